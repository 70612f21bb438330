#!/usr/bin/env bash
# A throw-away PostgreSQL server on 127.0.0.1 for the distributed-tuning tests.
#
#   eval "$(bash .ci/postgres.sh)"        # start (or reuse) it; exports FUZZYSERVO_TEST_POSTGRES_URL
#   bash .ci/postgres.sh stop             # stop the server started above (uses the exported variables)
#
# Start prints, on stdout and nothing else:
#   export FUZZYSERVO_TEST_POSTGRES_URL=postgresql://postgres@127.0.0.1:<port>/fuzzyservo_test
#   export FUZZYSERVO_TEST_POSTGRES_DATA=<data directory>
# It installs the Debian package `postgresql` when no initdb/pg_ctl is found (root only),
# creates a fresh cluster under a temp dir (trust auth, listening on 127.0.0.1 only, its
# socket in that dir), starts it on the first free port from 55432 and creates the database.
# Called again while that server runs, it reuses it. On any failure it explains on stderr
# and exits 0 printing no export line: the tests that need the server then skip.
set -uo pipefail

PORT_FIRST=${FUZZYSERVO_TEST_POSTGRES_PORT:-55432}
DB=fuzzyservo_test
STATE_ROOT=${TMPDIR:-/tmp}

say() { echo ".ci/postgres.sh: $*" >&2; }
give_up() {
    say "$*"
    say "no PostgreSQL server: the tests that need one will be skipped"
    exit 0
}

find_bin() {
    local p
    for p in "$(command -v pg_ctl 2>/dev/null)" "$(command -v initdb 2>/dev/null)"; do
        if [ -n "$p" ]; then
            p=$(dirname "$(readlink -f "$p")")
            if [ -x "$p/initdb" ] && [ -x "$p/pg_ctl" ]; then
                echo "$p"
                return 0
            fi
        fi
    done
    # Debian keeps the server binaries off PATH, one folder per major version: take the newest
    p=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n 1)
    if [ -n "$p" ] && [ -x "$p/initdb" ] && [ -x "$p/pg_ctl" ]; then
        echo "$p"
        return 0
    fi
    return 1
}

# run a command as the cluster's owner: `postgres` when we are root (initdb and the
# server refuse to run as root), ourselves otherwise
as_owner() {
    if [ "$(id -u)" -ne 0 ]; then
        "$@"
    elif command -v runuser >/dev/null 2>&1; then
        runuser -u postgres -- "$@"
    else
        su postgres -s /bin/sh -c "$(printf '%q ' "$@")"
    fi
}

port_in_use() { (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }

stop() {
    local data=${FUZZYSERVO_TEST_POSTGRES_DATA:-}
    if [ -z "$data" ] || [ ! -f "$data/PG_VERSION" ]; then
        say "stop: FUZZYSERVO_TEST_POSTGRES_DATA names no cluster; nothing to stop"
        return 0
    fi
    local bin
    bin=$(find_bin) || { say "stop: pg_ctl not found"; return 0; }
    (cd "$data/.." && as_owner "$bin/pg_ctl" -D "$data" -m fast -w stop >/dev/null 2>&1) || true
    case "$(basename "$(dirname "$data")")" in
    fuzzyservo-pg-*) rm -rf "$(dirname "$data")" ;;
    esac
    say "stopped the PostgreSQL server in $data"
}

if [ "${1:-start}" = stop ]; then
    stop
    exit 0
fi

bin=$(find_bin)
if [ -z "$bin" ]; then
    if [ "$(id -u)" -ne 0 ]; then
        give_up "initdb/pg_ctl not found and not root, so cannot apt-get install postgresql"
    fi
    if ! command -v apt-get >/dev/null 2>&1; then
        give_up "initdb/pg_ctl not found and no apt-get to install them"
    fi
    say "installing postgresql with apt-get (this takes a minute)"
    export DEBIAN_FRONTEND=noninteractive
    if ! { apt-get update -qq && apt-get install -y -qq --no-install-recommends postgresql; } \
        >/tmp/fuzzyservo-pg-apt.log 2>&1 </dev/null; then
        tail -n 20 /tmp/fuzzyservo-pg-apt.log >&2
        give_up "apt-get install postgresql failed (log: /tmp/fuzzyservo-pg-apt.log)"
    fi
    bin=$(find_bin) || give_up "postgresql installed but no initdb/pg_ctl found under /usr/lib/postgresql"
fi

if [ "$(id -u)" -eq 0 ] && ! id postgres >/dev/null 2>&1; then
    useradd --system --home-dir /var/lib/postgresql --shell /bin/sh postgres >/dev/null 2>&1 ||
        give_up "running as root and no 'postgres' user could be created to own the cluster"
fi

url() { echo "postgresql://postgres@127.0.0.1:$1/$DB"; }
emit() {
    echo "export FUZZYSERVO_TEST_POSTGRES_URL=$(url "$1")"
    echo "export FUZZYSERVO_TEST_POSTGRES_DATA=$2"
}

# reuse a server this script started earlier and that still runs
for state in "$STATE_ROOT"/fuzzyservo-pg-*/; do
    data="${state}data"
    [ -f "$data/postmaster.pid" ] || continue
    port=$(sed -n 4p "$data/postmaster.pid" 2>/dev/null)
    [ -n "$port" ] || continue
    if as_owner "$bin/pg_ctl" -D "$data" status >/dev/null 2>&1 &&
        "$bin/pg_isready" -q -h 127.0.0.1 -p "$port" -t 3 2>/dev/null; then
        say "reusing the PostgreSQL server on 127.0.0.1:$port ($data)"
        emit "$port" "$data"
        exit 0
    fi
done

port=$PORT_FIRST
while port_in_use "$port"; do
    port=$((port + 1))
    [ "$port" -lt $((PORT_FIRST + 20)) ] || give_up "ports $PORT_FIRST..$port are all in use"
done

dir=$(mktemp -d "$STATE_ROOT/fuzzyservo-pg-XXXXXX") || give_up "cannot create a temp dir in $STATE_ROOT"
chmod 755 "$dir"
[ "$(id -u)" -ne 0 ] || chown postgres: "$dir" || give_up "cannot chown $dir to postgres"
data="$dir/data"
cd "$dir" || give_up "cannot enter $dir"

if ! as_owner "$bin/initdb" -D "$data" -U postgres --auth=trust --no-locale -E UTF8 \
    >"$dir/initdb.log" 2>&1; then
    cat "$dir/initdb.log" >&2
    give_up "initdb failed in $data"
fi
# listen on 127.0.0.1 only, socket in our own dir (/var/run/postgresql may not exist)
if ! as_owner "$bin/pg_ctl" -D "$data" -l "$dir/server.log" -w -t 60 \
    -o "-c listen_addresses=127.0.0.1 -p $port -c unix_socket_directories=$dir -c fsync=off" \
    start >/dev/null 2>&1; then
    cat "$dir/server.log" >&2 2>/dev/null
    give_up "the server did not start on 127.0.0.1:$port (log above)"
fi
if ! "$bin/psql" -q -h 127.0.0.1 -p "$port" -U postgres -d postgres -v ON_ERROR_STOP=1 \
    -c "CREATE DATABASE $DB" >/dev/null 2>"$dir/createdb.log"; then
    cat "$dir/createdb.log" >&2
    FUZZYSERVO_TEST_POSTGRES_DATA=$data stop
    give_up "could not create the database $DB"
fi
say "PostgreSQL $("$bin/pg_ctl" --version | awk '{print $3}') on 127.0.0.1:$port, data in $data"
emit "$port" "$data"
