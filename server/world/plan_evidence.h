#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "server/world/spatial_hash.h"
#include "server/world/world_state.h"

namespace wm::world {

/// What the occupancy grid says of one point of a drawn edge, looking across the edge.
enum class EdgeSample {
  backed,        // an occupied cell within one cell of the point: the surface is where it is drawn
  displaced,     // no occupied cell within one cell, but one a little further across: a surface near the drawing
  seen_through,  // the cells on and around the point were seen and are free, and nothing occupied is near
  unknown,       // too little seen there to say
};

/// Classifies a point of an edge; `normal` is the edge's unit normal (the probe looks along it).
using EdgeProbe = std::function<EdgeSample(const Eigen::Vector2d& point, const Eigen::Vector2d& normal)>;

/// Laser beams counted at a stretch of an edge: passed through it, returned on it.
struct BeamTally {
  std::int64_t through = 0, ended = 0;
};
/// The beams counted at [s0_m, s1_m) of edge `edge` of object `object` (WorldState::objects index), from the edge's
/// first end as placed now; zeros when none were counted.
using EdgeCrossings = std::function<BeamTally(std::size_t object, std::size_t edge, double s0_m, double s1_m)>;

struct PlanEvidenceOptions {
  double step_m = 0.05;             // sample spacing along an edge (the grid's cell size) [m], > 0
  double min_stretch_m = 0.30;      // a seen-through run shorter than this is not reported as a stretch [m]
  std::size_t max_unknown_gap = 2;  // unknown samples bridged inside a seen-through run
  /// Samples within this many steps of another drawn edge that meets or crosses the edge (30° or more) take the
  /// verdict of the samples beside them: the other wall's cells are there whether this wall stands or not, so a
  /// demolished wall would otherwise end a few cells short of its corners. 0: off.
  double junction_cells = 2.5;
  /// A sample the probe left unknown (nothing occupied near, but some cells crossed by fewer beams than make them
  /// free) is seen through when at least this many counted beams crossed the edge there, five for each that
  /// returned on it. Far from a well-placed robot the beams of its scans fall on the same cells and leave every
  /// other cell of a line with one or two misses; the beams crossing the line itself were many. 0: off.
  std::int64_t min_beams_crossing = 3;
};

/// A stretch of an edge, from its first end (p0 of the edge as placed now) [m].
struct Stretch {
  double s0_m = 0, s1_m = 0;
  /// Beams counted passing through this stretch, and returning on it (0 when not counted).
  std::int64_t beams_through = 0, beams_ended = 0;
};

/// The grid's evidence on one edge of a plan object, as the object is placed now.
struct EdgeEvidence {
  std::size_t object = 0;  // index in WorldState::objects
  std::size_t edge = 0;    // edge index in the object
  double length_m = 0;
  /// Shares of the edge's samples, in [0, 1]: backed + displaced + seen_through + unknown = 1; observed is
  /// 1 − unknown.
  double backed = 0, displaced = 0, seen_through = 0, observed = 0;
  std::vector<Stretch> seen_through_stretches;  // runs of seen-through samples of at least min_stretch_m
  /// Laser beams counted at the edge where it stands now (filled by the server, which counts them as scans come):
  /// passed through it, and returned on it.
  std::int64_t beams_through = 0, beams_ended = 0;
};

/// The evidence of every edge of every object that has an edge crossing `region`, in (object, edge) order, sampled
/// at options.step_m with `probe`, and with `crossings` where the probe says unknown (none: the probe alone). Edges
/// shorter than two samples are left out.
std::vector<EdgeEvidence> plan_evidence(const WorldState& state, const Box& region, const EdgeProbe& probe,
                                        const PlanEvidenceOptions& options, const EdgeCrossings& crossings = {});
/// The same for every edge of the plan.
std::vector<EdgeEvidence> plan_evidence(const WorldState& state, const EdgeProbe& probe,
                                        const PlanEvidenceOptions& options, const EdgeCrossings& crossings = {});

/// What the rules concluded about an edge or an object from the evidence (wm_kb verdict hooks).
struct Verdict {
  std::string object_id;
  std::optional<std::size_t> edge;  // nullopt: about the whole object (e.g. "gone")
  std::string verdict;              // missing | partly_missing | gone | (rule sets may add others)
  Stretch stretch;                  // for edges: the part concerned (the whole edge for "missing")
  std::string rule, explanation;
};

/// The evidence and the verdicts over the whole plan, as last computed by the writer.
struct PlanReport {
  std::int64_t map_version = 0;     // the map version the edges were placed from
  std::int64_t grid_revision = 0;   // the last scan the grid held
  std::vector<EdgeEvidence> edges;  // every edge with any sample observed, (object, edge) order
  std::vector<Verdict> verdicts;    // in (object, edge, s0) order
  /// The evidence of an edge, or nullptr when it has none.
  const EdgeEvidence* find(std::size_t object, std::size_t edge) const;
};

}  // namespace wm::world
