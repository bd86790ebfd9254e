#!/usr/bin/env bash
# A throw-away PostgreSQL server for tests and benchmarks: its own data directory, a local port, trust
# authentication for local connections, nothing shared with a system cluster. Debian's server binaries
# (/usr/lib/postgresql/<major>/bin, package postgresql; scripts/setup.sh installs it).
#
#   bash scripts/throwaway_postgres.sh start DIR [PORT]   # prints the database URL on stdout
#   bash scripts/throwaway_postgres.sh stop DIR
#
# start: creates DIR (must not hold a running server), initialises a cluster in DIR/data (or, if DIR holds
# the data of a server this script stopped, keeps it: a restart), starts it on
# PORT (default: a free port from 54320 up) listening on 127.0.0.1 only, creates database
# textile_handling and prints postgresql://postgres@127.0.0.1:PORT/textile_handling. As root the
# server runs as the system user postgres (initdb refuses root). stop: fast shutdown; DIR can then be
# removed. Exit status: 0 done, 1 failure (the server log's tail on stderr), 2 usage.
set -euo pipefail
usage() { echo "usage: $0 start DIR [PORT] | stop DIR" >&2; exit 2; }
[ $# -ge 2 ] || usage
CMD=$1
DIR=$2
BIN=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n 1)
[ -n "$BIN" ] && [ -x "$BIN/pg_ctl" ] || { echo "throwaway_postgres: no PostgreSQL server binaries under /usr/lib/postgresql (install package postgresql)" >&2; exit 1; }
as_owner() {
  if [ "$(id -u)" -eq 0 ]; then runuser -u postgres -- "$@"; else "$@"; fi
}
case "$CMD" in
  start)
    PORT=${3:-}
    if [ -z "$PORT" ]; then
      PORT=54320
      while (exec 3<>"/dev/tcp/127.0.0.1/$PORT") 2>/dev/null; do PORT=$((PORT + 1)); done
    fi
    mkdir -p "$DIR"
    DIR=$(cd "$DIR" && pwd)
    if [ -f "$DIR/data/postmaster.pid" ]; then echo "throwaway_postgres: $DIR already has a server" >&2; exit 1; fi
    [ "$(id -u)" -eq 0 ] && chown postgres: "$DIR"
    fresh=1
    if [ -d "$DIR/data" ]; then
      fresh=0  # a stopped server of this script: start it again with its data (a restart)
    else
      as_owner "$BIN/initdb" -D "$DIR/data" -U postgres --auth=trust -E UTF8 --locale=C.UTF-8 > "$DIR/initdb.log" 2>&1 || {
        tail -n 20 "$DIR/initdb.log" >&2; exit 1; }
    fi
    as_owner "$BIN/pg_ctl" -D "$DIR/data" -l "$DIR/server.log" -w -t 60 \
      -o "-p $PORT -c listen_addresses=127.0.0.1 -k $DIR -c fsync=on" start > /dev/null || {
      tail -n 20 "$DIR/server.log" >&2; exit 1; }
    [ $fresh = 1 ] && as_owner "$BIN/createdb" -h 127.0.0.1 -p "$PORT" -U postgres textile_handling
    echo "postgresql://postgres@127.0.0.1:$PORT/textile_handling"
    ;;
  stop)
    [ -d "$DIR/data" ] || { echo "throwaway_postgres: no cluster in $DIR" >&2; exit 1; }
    as_owner "$BIN/pg_ctl" -D "$DIR/data" -m fast -w stop > /dev/null
    ;;
  *) usage ;;
esac
