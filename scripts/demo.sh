#!/usr/bin/env bash
# Installs what is missing, builds wmd and wmctl, and starts the server on http://127.0.0.1:8080 with a
# demo floor plan (the real walls of UT Austin's GDC floor 1, AMRL vector map, BSD, plus three tables). First a
# simulated robot drives GDC1's corridors through the building as built, which differs from its plan: one wall
# demolished, a partition added, a table moved (clients/demo/make_demo_building.py; a ray-cast laser, 720 beams,
# σ 1 cm). Then a real laser log replays live beside it (the Intel Research Lab, CARMEN, placed 100 m east: there
# is no public log of the GDC building). Open the URL it prints: the web viewer follows the map as it grows, and
# `wmctl changes` lists what the drive found.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build -j"$(nproc)" --target wmd wmctl wm-raycast-log
port=${WM_PORT:-8080}
url="http://127.0.0.1:$port"
db=build/demo.db
rm -f "$db" "$db-wal" "$db-shm"
python3 clients/demo/make_demo_plan.py clients/demo/data/GDC1.vectormap.json > build/demo-plan.json
python3 clients/demo/make_demo_building.py build/demo-plan.json > build/demo-building.json
build/bin/wm-raycast-log build/demo-building.json build/demo-drive.log --step 0.5 2>/dev/null
log=tests/data/carmen/intel-corrected.log.gz  # the whole Intel lab log, shipped for the tests

# Loopback only and no token, like a developer's machine: dry runs are allowed explicitly so that the
# README's rule-writing walk-through works (a shared server runs with --token instead).
build/bin/wmd --db "$db" --port "$port" --floorplan build/demo-plan.json --sync normal --allow-dry-run-without-token &
wmd_pid=$!
trap 'kill $wmd_pid 2>/dev/null; wait $wmd_pid 2>/dev/null' EXIT INT TERM
for _ in $(seq 100); do curl -sf "$url/api/v1/health" >/dev/null && break; sleep 0.1; done
build/bin/wmctl --server "$url" primitives post clients/demo/primitives.json >/dev/null
cat <<TXT

worldmodel demo — open $url/ in a browser (the live viewer). While it runs (Ctrl-C stops it):
  build/bin/wmctl decisions                      # the decision log, one rule and explanation each
  build/bin/wmctl changes                        # what the drive found: a wall gone, a partition, a table moved
  build/bin/wmctl explain wall-178               # the evidence on the demolished wall: seen through, by how many beams
  build/bin/wmctl explain table-3                # the history of the table that was moved
  build/bin/wmctl changes accept ID              # take a change into the plan (wmctl changes undo takes it back)
  build/bin/wmctl query "attribute(O, not_deformable)"
  build/bin/wmctl grid --out /tmp/map.pgm        # the occupancy grid as a ROS map_server pair
  curl $url/api/v1/map

driving a simulated robot through GDC1 as built at 25 scans/s ...
TXT
build/bin/wmctl --server "$url" replay build/demo-drive.log --rate 25 --source gdc1-robot || true
build/bin/wmctl --server "$url" changes || true
echo "replaying $log at 25 scans/s ..."
build/bin/wmctl --server "$url" replay "$log" --rate 25 --offset 100,0 --source intel-lab || true
echo "replay finished; the server keeps running (Ctrl-C stops it)"
wait $wmd_pid
