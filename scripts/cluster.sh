#!/usr/bin/env bash
# A local cluster to try: its own PostgreSQL (in build/cluster/, on a free loopback port) and three wmd nodes on
# ports 8181-8183 sharing it, with two maps made on the first node. Installs what is missing and builds wmd and
# wmctl first. Any node answers for any map (it passes the request on to the node serving it); kill a node
# (kill -9 its pid, printed below) and within 5 s its maps are served by the others. Ctrl-C stops everything.
#   WM_CLUSTER_NODES=N (default 3), WM_CLUSTER_PORT=P (the first node's port, default 8181)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build -j"$(nproc)" --target wmd wmctl
nodes=${WM_CLUSTER_NODES:-3}
first_port=${WM_CLUSTER_PORT:-8181}
dir=$(realpath -m build/cluster)
rm -rf "$dir" && mkdir -p "$dir/pg"
uri=$(bash tests/support/postgres.sh start "$dir/pg")
# The node-to-node token: in a file only its owner reads, never on a command line.
token_file="$dir/token"
(umask 077 && head -c 24 /dev/urandom | base64 > "$token_file")
pids=()
stop_all() {
  for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
  bash tests/support/postgres.sh stop "$dir/pg"
}
trap stop_all EXIT INT TERM
for n in $(seq 1 "$nodes"); do
  port=$((first_port + n - 1))
  build/bin/wmd --store "$uri" --cluster-id local --node-id "node-$n" --cluster-token-file "$token_file" \
    --port "$port" --maps-dir "$dir/maps-$n" --no-shm >"$dir/node-$n.log" 2>&1 &
  pids+=($!)
done
for n in $(seq 1 "$nodes"); do
  url="http://127.0.0.1:$((first_port + n - 1))"
  for _ in $(seq 100); do curl -sf "$url/api/v1/health" >/dev/null && break; sleep 0.1; done
done
first="http://127.0.0.1:$first_port"
for map in floor1 floor2; do curl -sf -X POST "$first/api/v1/maps" -H 'Content-Type: application/json' \
  -d "{\"id\":\"$map\"}" >/dev/null; done
cat <<TXT

worldmodel cluster '$(basename "$dir")': PostgreSQL at $uri, $nodes nodes:
$(for n in $(seq 1 "$nodes"); do echo "  node-$n  http://127.0.0.1:$((first_port + n - 1))  pid ${pids[$((n - 1))]}  log $dir/node-$n.log"; done)
Try:
  build/bin/wmctl --server $first cluster                  # nodes, heartbeats, leases and epochs
  build/bin/wmctl --server http://127.0.0.1:$((first_port + 1)) --map floor1 replay tests/data/carmen/intel-corrected.log.gz
  kill -9 ${pids[0]}                                            # a node dies: its maps move within 5 s
  ogrinfo PG:"$(echo "$uri" | sed -E 's|postgresql://([^@]+)@([^:]+):([0-9]+)/(.*)|host=\2 port=\3 user=\1 dbname=\4|') schemas=map_floor1" elements
Ctrl-C stops the cluster and its database.
TXT
wait
