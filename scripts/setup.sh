#!/usr/bin/env bash
# Installs the Debian packages worldmodel needs (idempotent; runs apt-get only when something is missing).
set -euo pipefail
packages=(
  build-essential cmake ninja-build pkg-config clang-format
  libeigen3-dev libboost-dev libboost-system-dev nlohmann-json3-dev libsqlite3-dev sqlite3
  swi-prolog-core swi-prolog-core-packages
  libgtest-dev libgmock-dev googletest libbenchmark-dev
  zlib1g-dev libyaml-cpp-dev curl python3 python3-ezdxf python3-numpy gdal-bin
  libpq-dev postgresql-15 postgresql-15-postgis-3
)
# Extra packages for a purpose: `scripts/setup.sh bench` (benchmarks' baselines), `scripts/setup.sh web`
# (the browser test: Debian's Chromium and Node.js for playwright-core), `scripts/setup.sh sanitize` (clang for
# the ASan/UBSan build and the fuzzers), `scripts/setup.sh ros` (ROS 1 from Debian: the bridge in clients/ros and
# its tests).
for extra in "$@"; do
  case "$extra" in
    bench) packages+=(liboctomap-dev libopencv-dev libopencv-contrib-dev wrk nginx-light) ;;
    web) packages+=(chromium nodejs) ;;  # npm comes with nodejs (Debian or NodeSource)
    sanitize) packages+=(clang libclang-rt-14-dev llvm) ;;  # ASan/UBSan and libFuzzer run-times, llvm-symbolizer
    ros) packages+=(ros-core python3-rospy python3-rosbag python3-tf2-ros python3-tf2-msgs python3-sensor-msgs
                    python3-nav-msgs python3-visualization-msgs python3-geometry-msgs python3-std-msgs) ;;
    *) echo "setup: unknown extra '$extra' (bench, web, sanitize, ros)" >&2; exit 2 ;;
  esac
done
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  sudo_cmd=()
  [ "$(id -u)" -ne 0 ] && sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
