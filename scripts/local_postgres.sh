#!/usr/bin/env bash
# A throwaway PostgreSQL server of its own on 127.0.0.1, for the tests and for trying docs/scaling.md on one machine.
#
#   scripts/local_postgres.sh start DIR   initdb into DIR, start the server on a free port, create the database `optuna`,
#                                         print its URL (postgresql://sb3:PASSWORD@127.0.0.1:PORT/optuna) on stdout
#   scripts/local_postgres.sh stop DIR    stop the server of DIR (nothing to do when it is not running)
#
# It needs PostgreSQL's server binaries (Debian: apt-get install -y postgresql). PostgreSQL refuses to run as root, so
# as root the server runs as the `postgres` system user (created by the Debian package) and DIR is handed to it.
set -euo pipefail

usage() {
    echo "usage: $0 start|stop DIR" >&2
    exit 2
}
[ $# -eq 2 ] || usage
action="$1"
dir="$2"

bindir="$(command -v pg_ctl >/dev/null 2>&1 && dirname "$(readlink -f "$(command -v pg_ctl)")" || true)"
if [ -z "$bindir" ] || [ ! -x "$bindir/initdb" ]; then
    bindir="$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n 1 || true)"
fi
if [ -z "$bindir" ] || [ ! -x "$bindir/initdb" ]; then
    echo "$0: PostgreSQL's server binaries (initdb, pg_ctl) not found; install them, e.g. apt-get install -y postgresql" >&2
    exit 1
fi

# Run a PostgreSQL binary as a user it accepts
as_server_user() {
    if [ "$(id -u)" -eq 0 ]; then
        runuser -u postgres -- "$@"
    else
        "$@"
    fi
}

case "$action" in
start)
    if [ "$(id -u)" -eq 0 ] && ! id postgres >/dev/null 2>&1; then
        useradd --system --no-create-home --shell /usr/sbin/nologin postgres
    fi
    mkdir -p "$dir"
    [ "$(id -u)" -ne 0 ] || chown postgres "$dir"
    password="$(python3 -c 'import secrets; print(secrets.token_hex(12))')"
    port="$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
    pwfile="$dir/password"
    printf '%s\n' "$password" >"$pwfile"
    [ "$(id -u)" -ne 0 ] || chown postgres "$pwfile"
    as_server_user "$bindir/initdb" -D "$dir/data" -U sb3 --pwfile="$pwfile" --auth=scram-sha-256 -E UTF8 >"$dir/initdb.log"
    as_server_user "$bindir/pg_ctl" -D "$dir/data" -l "$dir/data/server.log" -w \
        -o "-k /tmp -h 127.0.0.1 -p $port -c max_connections=200" start >/dev/null
    PGPASSWORD="$password" "$bindir/createdb" -h 127.0.0.1 -p "$port" -U sb3 optuna
    echo "postgresql://sb3:$password@127.0.0.1:$port/optuna"
    ;;
stop)
    if [ -f "$dir/data/postmaster.pid" ]; then
        as_server_user "$bindir/pg_ctl" -D "$dir/data" -m fast -w stop >/dev/null
    fi
    ;;
*)
    usage
    ;;
esac
