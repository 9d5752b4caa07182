#!/usr/bin/env bash
# Installs what is missing, builds wmd and wmctl, and starts the server on http://127.0.0.1:8080 with a
# demo floor plan: the real walls of UT Austin's GDC floor 1 (AMRL vector map, BSD) plus two tables.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build -j"$(nproc)" --target wmd wmctl
port=${WM_PORT:-8080}
db=build/demo.db
rm -f "$db" "$db-wal" "$db-shm"
python3 clients/demo/make_demo_plan.py clients/demo/data/GDC1.vectormap.json > build/demo-plan.json
cat <<TXT

worldmodel demo — open or try, while it runs (Ctrl-C stops it):
  curl http://127.0.0.1:$port/api/v1/health
  build/bin/wmctl primitives post clients/demo/primitives.json     # one decision of each kind
  build/bin/wmctl map
  build/bin/wmctl decisions
  curl http://127.0.0.1:$port/api/v1/map

TXT
exec build/bin/wmd --db "$db" --port "$port" --floorplan build/demo-plan.json
