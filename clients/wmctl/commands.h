#pragma once

// The wmctl commands, one function each; main.cpp's command table names them with their usage.
#include "clients/wmctl/cli.h"

namespace wm::wmctl {

// The map and the floor plan (map_commands.cpp).
int health(const Invocation& in);
int network(const Invocation& in);
int network_subtask(const Invocation& in);  // PUT /api/v1/network/subtasks/{name}
int network_set(const Invocation& in);      // PUT /api/v1/network/components/{name}/params
int maps_list(const Invocation& in);
int cluster(const Invocation& in);  // GET /api/v1/cluster
int maps_create(const Invocation& in);
int maps_delete(const Invocation& in);
int maps_import(const Invocation& in);
int floorplan_load(const Invocation& in);
int floorplan_show(const Invocation& in);
int floorplan_align(const Invocation& in);
int floorplan_place(const Invocation& in);
int floorplan_pairs(const Invocation& in);
int floorplan_undo(const Invocation& in);
int floorplan_redecide(const Invocation& in);
int floorplan_georeference(const Invocation& in);
int primitives_post(const Invocation& in);
int map(const Invocation& in);
int map_quality(const Invocation& in);
int report(const Invocation& in);
int changes(const Invocation& in);
int changes_accept(const Invocation& in);
int changes_reject(const Invocation& in);
int changes_undo(const Invocation& in);
int grid(const Invocation& in);
int grid_extract(const Invocation& in);
int robots(const Invocation& in);

// The decision log, the rules and queries (rules_commands.cpp).
int decisions(const Invocation& in);
int explain(const Invocation& in);
int rules(const Invocation& in);
int rules_reload(const Invocation& in);
int rules_dry_run(const Invocation& in);
int query(const Invocation& in);

// The shared-memory export (shm_command.cpp).
int shm_check(const Invocation& in);

// Laser logs (replay_command.cpp).
int replay(const Invocation& in);

}  // namespace wm::wmctl
