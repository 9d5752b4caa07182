#!/usr/bin/env bash
# A private PostgreSQL 15 server for one test process: `postgres.sh start DIR` makes a cluster in DIR (an empty
# directory), starts it on a free loopback port with its socket in DIR, creates the database `worldmodel` with
# PostGIS, and prints its URI; `postgres.sh stop DIR` stops it; `postgres.sh restart DIR` restarts it (a database
# that went away and came back). PostgreSQL refuses to run as root: as root, the
# cluster belongs to the `postgres` system user (the Debian package makes it). The test command installs the
# packages (scripts/setup.sh); a missing binary is an error here, never a skipped test.
set -euo pipefail
action=${1:?start|stop}
dir=${2:?directory}
bin=/usr/lib/postgresql/15/bin
[ -x "$bin/initdb" ] || { echo "postgres.sh: $bin/initdb missing (apt-get install postgresql-15 postgresql-15-postgis-3)" >&2; exit 1; }
as_owner=()
if [ "$(id -u)" -eq 0 ]; then
  chown postgres: "$dir"
  as_owner=(runuser -u postgres --)
fi
case "$action" in
  start)
    "${as_owner[@]}" "$bin/initdb" -D "$dir/data" -A trust -U wm -E UTF8 --no-sync >"$dir/initdb.log" 2>&1 ||
      { cat "$dir/initdb.log" >&2; exit 1; }
    for attempt in 1 2 3 4 5 6 7 8; do
      port=$(( 20000 + RANDOM % 40000 ))
      if "${as_owner[@]}" "$bin/pg_ctl" -D "$dir/data" -l "$dir/server.log" -w -t 60 start \
           -o "-p $port -k $dir -c listen_addresses=127.0.0.1 -c max_connections=200" >/dev/null 2>&1; then
        "$bin/psql" -q -h 127.0.0.1 -p "$port" -U wm -d postgres -v ON_ERROR_STOP=1 \
          -c "CREATE DATABASE worldmodel" >/dev/null
        "$bin/psql" -q -h 127.0.0.1 -p "$port" -U wm -d worldmodel -v ON_ERROR_STOP=1 \
          -c "CREATE EXTENSION postgis" >/dev/null
        echo "postgresql://wm@127.0.0.1:$port/worldmodel"
        exit 0
      fi
    done
    echo "postgres.sh: the server did not start; its log:" >&2
    cat "$dir/server.log" >&2
    exit 1
    ;;
  stop)
    "${as_owner[@]}" "$bin/pg_ctl" -D "$dir/data" -m immediate -w stop >/dev/null 2>&1 || true
    ;;
  restart)  # every connection is cut; the server comes back on the same port
    "${as_owner[@]}" "$bin/pg_ctl" -D "$dir/data" -l "$dir/server.log" -m fast -w -t 60 restart >/dev/null
    ;;
  *) echo "postgres.sh: start|stop|restart" >&2; exit 2 ;;
esac
