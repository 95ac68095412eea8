# shellcheck shell=bash
# Sourced by .ci/run (as root, under `set -euo pipefail`, on a fresh Debian 12 machine):
# install PostgreSQL from the system's packages, start a cluster, create a role and a database for the
# recipe-database tests, and export DOORLOC_TEST_POSTGRES_URL so they run on PostgreSQL as well as SQLite.
# Safe to source again: every step checks before it acts. Variables are prefixed _pg_ to stay out of the way.
echo "postgres.sh: installing PostgreSQL (apt)"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq >/dev/null
# C.UTF-8 always exists on Debian: a LANG naming an ungenerated locale would make initdb fail
LANG=C.UTF-8 LC_ALL=C.UTF-8 apt-get install -y -qq --no-install-recommends postgresql >/dev/null

# newest installed server version (Debian 12: 15)
_pg_ver=$(find /usr/lib/postgresql -mindepth 1 -maxdepth 1 -type d -printf '%f\n' | sort -V | tail -n 1)
if [ -z "$_pg_ver" ] || [ ! -x "/usr/lib/postgresql/$_pg_ver/bin/postgres" ]; then
  echo "postgres.sh: no PostgreSQL server under /usr/lib/postgresql after installing" >&2
  return 1
fi
# the package creates cluster "main" unless the machine's policy stopped it; make sure it exists
if ! pg_lsclusters --no-header | awk '{print $1 "/" $2}' | grep -qx "$_pg_ver/main"; then
  LANG=C.UTF-8 LC_ALL=C.UTF-8 pg_createcluster --locale C.UTF-8 "$_pg_ver" main >/dev/null
fi
if ! pg_ctlcluster "$_pg_ver" main status >/dev/null 2>&1; then
  pg_ctlcluster "$_pg_ver" main start
fi
_pg_port=$(pg_lsclusters --no-header | awk -v v="$_pg_ver" '$1 == v && $2 == "main" {print $3}')
for _pg_i in $(seq 1 30); do
  pg_isready -q -h 127.0.0.1 -p "$_pg_port" && break
  sleep 1
done
pg_isready -h 127.0.0.1 -p "$_pg_port"

_pg_psql() { runuser -u postgres -- psql -X -q -v ON_ERROR_STOP=1 -p "$_pg_port" -d postgres -tA "$@"; }
if [ "$(_pg_psql -c "SELECT 1 FROM pg_roles WHERE rolname = 'doorloc'")" != "1" ]; then
  _pg_psql -c "CREATE ROLE doorloc LOGIN PASSWORD 'doorloc'"
fi
if [ "$(_pg_psql -c "SELECT 1 FROM pg_database WHERE datname = 'doorloc_test'")" != "1" ]; then
  _pg_psql -c "CREATE DATABASE doorloc_test OWNER doorloc"
fi
unset -f _pg_psql

export DOORLOC_TEST_POSTGRES_URL="postgresql+psycopg://doorloc:doorloc@127.0.0.1:${_pg_port}/doorloc_test"
echo "postgres.sh: PostgreSQL $_pg_ver on port $_pg_port; DOORLOC_TEST_POSTGRES_URL=postgresql+psycopg://doorloc:***@127.0.0.1:${_pg_port}/doorloc_test"
unset _pg_ver _pg_port _pg_i
