#!/usr/bin/env bash
# Start Debian's PostgreSQL (installing it when missing) and create the service tests' database.
# Prints the URL for HRTLS_TEST_PG. Idempotent; run as root or a user with sudo.
set -euo pipefail
# Everything but the URL goes to stderr (pg_ctlcluster prints notices such as "Removed stale pid file.").
exec 3>&1 1>&2
if [ "$(id -u)" -eq 0 ]; then as_root=(); else as_root=(sudo); fi
if ! command -v pg_lsclusters >/dev/null 2>&1; then
  "${as_root[@]}" apt-get update -q
  DEBIAN_FRONTEND=noninteractive "${as_root[@]}" apt-get install -y -q postgresql >/dev/null
fi
read -r version cluster port status _ < <(pg_lsclusters --no-header | head -1)
if [ "$status" != "online" ]; then
  # The server must not inherit fd 3 (the caller's stdout): a reader of that pipe would wait for ever.
  "${as_root[@]}" pg_ctlcluster "$version" "$cluster" start 3>&- </dev/null
fi
as_pg() { if [ "$(id -u)" -eq 0 ]; then su postgres -c "$1"; else sudo -u postgres sh -c "$1"; fi; }
for _ in $(seq 1 30); do
  as_pg "pg_isready -q -p $port" && break
  sleep 1
done
psql_pg() { as_pg "psql -p $port -v ON_ERROR_STOP=1 -qtAc \"$1\""; }
if [ "$(psql_pg "SELECT 1 FROM pg_roles WHERE rolname='hrtls'")" != "1" ]; then
  psql_pg "CREATE ROLE hrtls LOGIN PASSWORD 'hrtls'"
fi
if [ "$(psql_pg "SELECT 1 FROM pg_database WHERE datname='hrtls_test'")" != "1" ]; then
  psql_pg "CREATE DATABASE hrtls_test OWNER hrtls"
fi
echo "postgresql://hrtls:hrtls@127.0.0.1:${port}/hrtls_test" >&3
