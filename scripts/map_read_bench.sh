#!/usr/bin/env bash
# Map reads over HTTP, side by side in one run with nginx serving the very same bytes as a static file:
#   bash scripts/map_read_bench.sh [SECONDS]        (default 10 s per measurement)
# Builds the demo's map (the GDC1 plan and the whole Intel log), then measures with wrk (32 connections, 2 threads):
#   - the full map (GET /api/v1/map) and nginx, idle and while 4 robots replay the Intel log at full rate;
#   - a delta poll (GET /api/v1/map?since=V, V one version back) idle, and the 304 of a client that has the map.
# Prints requests/s, p50 and p99 per row and the ratios the README reports. Installs wrk and nginx-light when missing
# (scripts/setup.sh bench).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-10}
max_stale=${WM_MAX_STALE:-1}  # seconds a polling client accepts in the last row
bash scripts/setup.sh bench
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
[ -f build/CMakeCache.txt ] || cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "${launcher[@]}" >/dev/null
cmake --build build -j"$(nproc)" --target wmd wmctl >/dev/null

work=$(mktemp -d)
pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT INT TERM

free_port() { /usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
wmd_port=$(free_port)
nginx_port=$(free_port)
url="http://127.0.0.1:$wmd_port"
log=tests/data/carmen/intel-corrected.log.gz

python3 clients/demo/make_demo_plan.py clients/demo/data/GDC1.vectormap.json > "$work/plan.json"
build/bin/wmd --db "$work/wm.db" --port "$wmd_port" --floorplan "$work/plan.json" --sync full >"$work/wmd.log" 2>&1 &
pids+=($!)
for _ in $(seq 100); do curl -sf "$url/api/v1/health" >/dev/null && break; sleep 0.1; done
echo "building the map: the Intel log (910 scans) ..." >&2
build/bin/wmctl --server "$url" replay "$log" --offset 100,0 --source intel-lab >/dev/null

mkdir -p "$work/www"
chmod a+rx "$work" "$work/www"  # nginx's workers may run as another user (www-data when started as root)
curl -sf "$url/api/v1/map" -o "$work/www/map.json"
version=$(/usr/bin/python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["version"])' "$work/www/map.json")
etag=$(curl -sfI "$url/api/v1/map" | tr -d '\r' | sed -n 's/^[Ee][Tt]ag: //p')
cat >"$work/nginx.conf" <<CONF
worker_processes 2;
pid $work/nginx.pid;
error_log $work/nginx-error.log;
events { worker_connections 1024; }
http {
  access_log off;
  sendfile on;
  default_type application/json;
  client_body_temp_path $work/tmp; proxy_temp_path $work/tmp; fastcgi_temp_path $work/tmp;
  uwsgi_temp_path $work/tmp; scgi_temp_path $work/tmp;
  server { listen 127.0.0.1:$nginx_port; root $work/www; }
}
CONF
mkdir -p "$work/tmp"
nginx -c "$work/nginx.conf" -g 'daemon off;' &
pids+=($!)
for _ in $(seq 50); do curl -sf "http://127.0.0.1:$nginx_port/map.json" >/dev/null && break; sleep 0.1; done
cmp -s <(curl -sf "http://127.0.0.1:$nginx_port/map.json") "$work/www/map.json" || { echo "nginx serves other bytes" >&2; exit 1; }

# One wrk run: prints "requests/s p50_ms p99_ms".
measure() {
  local out
  out=$(wrk -t2 -c32 -d"${seconds}s" --latency "$@" 2>&1)
  /usr/bin/python3 - "$out" <<'PY'
import re, sys
text = sys.argv[1]
def ms(pattern):
    found = re.search(pattern + r"\s+([\d.]+)(us|ms|s|m)\b", text)
    if not found:
        return float("nan")
    return float(found.group(1)) * {"us": 1e-3, "ms": 1.0, "s": 1e3, "m": 6e4}[found.group(2)]
found = re.search(r"Requests/sec:\s+([\d.]+)", text)
rps = float(found.group(1)) if found else 0.0
p50 = ms("50%")
p99 = ms("99%")
if not found:
    sys.stderr.write(text + "\n")
errors = re.search(r"Non-2xx or 3xx responses: (\d+)", text)
print(f"{rps:.0f} {p50:.2f} {p99:.2f} {errors.group(1) if errors else 0}")
PY
}

row() { printf '%-44s %10s %9s %9s %8s\n' "$@"; }
bytes=$(stat -c %s "$work/www/map.json")
echo "map: $bytes bytes, version $version; wrk -t2 -c32 -d${seconds}s on $(nproc) cores"
row "what" "req/s" "p50 ms" "p99 ms" "non-2xx"
read -r n_rps n_p50 n_p99 n_err <<<"$(measure "http://127.0.0.1:$nginx_port/map.json")"
row "nginx, the same bytes (idle)" "$n_rps" "$n_p50" "$n_p99" "$n_err"
read -r m_rps m_p50 m_p99 m_err <<<"$(measure "$url/api/v1/map")"
row "GET /api/v1/map (idle)" "$m_rps" "$m_p50" "$m_p99" "$m_err"
read -r d_rps d_p50 d_p99 d_err <<<"$(measure "$url/api/v1/map?since=$((version - 1))")"
row "GET /api/v1/map?since=V-1 (idle)" "$d_rps" "$d_p50" "$d_p99" "$d_err"
read -r c_rps c_p50 c_p99 c_err <<<"$(measure -H "If-None-Match: $etag" "$url/api/v1/map")"
row "GET /api/v1/map, If-None-Match: 304 (idle)" "$c_rps" "$c_p50" "$c_p99" "$c_err"

# Full-rate ingest: four robots replaying the log as fast as the server takes it, for the whole measurement.
for robot in 1 2 3 4; do
  (while :; do build/bin/wmctl --server "$url" replay "$log" --offset $((100 * robot)),0 --source "robot-$robot" \
     >/dev/null 2>&1 || true; done) &
  pids+=($!)
done
sleep 2
before=$(curl -sf "$url/api/v1/health" | /usr/bin/python3 -c 'import json,sys; print(json.load(sys.stdin).get("version", 0))' || echo 0)
read -r ni_rps ni_p50 ni_p99 ni_err <<<"$(measure "http://127.0.0.1:$nginx_port/map.json")"
row "nginx, the same bytes (during ingest)" "$ni_rps" "$ni_p50" "$ni_p99" "$ni_err"
read -r mi_rps mi_p50 mi_p99 mi_err <<<"$(measure "$url/api/v1/map")"
row "GET /api/v1/map, newest (during ingest)" "$mi_rps" "$mi_p50" "$mi_p99" "$mi_err"
read -r ms_rps ms_p50 ms_p99 ms_err <<<"$(measure -H "Cache-Control: max-stale=$max_stale" "$url/api/v1/map")"
row "GET /api/v1/map, max-stale=$max_stale (during ingest)" "$ms_rps" "$ms_p50" "$ms_p99" "$ms_err"
after=$(curl -sf "$url/api/v1/health" | /usr/bin/python3 -c 'import json,sys; print(json.load(sys.stdin).get("version", 0))' || echo 0)
echo "ingest meanwhile: $(( (after - before) / (3 * seconds) )) requests/s applied (the map version's growth)"
/usr/bin/python3 - "$m_rps" "$n_rps" "$d_rps" "$mi_rps" "$ni_rps" "$ms_rps" <<'PY'
import sys
m, n, d, mi, ni, ms = map(float, sys.argv[1:])
print(f"ratios: map/nginx idle {m / n:.2f}x; during ingest: newest {mi / ni:.2f}x, max-stale {ms / ni:.2f}x; "
      f"delta poll / full read (idle) {d / m:.1f}x")
PY
