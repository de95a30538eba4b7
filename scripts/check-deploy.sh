#!/usr/bin/env bash
# The deploy/ checks of .ci/run, all offline once installed: the Dockerfile linted (hadolint),
# the Kubernetes and Knative manifests validated against the Kubernetes schemas
# (kubernetes-validate, scripts/check_manifests.py), the compose file parsed
# (docker-compose config, Debian's, no engine needed), then the container smoke test
# (scripts/smoke-image.sh). The Python tools live in a venv under target/, so nothing leaks.
set -euo pipefail
cd "$(dirname "$0")/.."

venv=target/deploy-venv
requirements=deploy/check-requirements.txt
if ! cmp -s "$requirements" "$venv/requirements.txt" 2>/dev/null; then
  rm -rf "$venv"
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet --disable-pip-version-check -r "$requirements"
  cp "$requirements" "$venv/requirements.txt"
fi
if ! command -v docker-compose >/dev/null 2>&1; then
  apt-get install -y -qq --no-install-recommends docker-compose >/dev/null
fi

echo "== hadolint deploy/Dockerfile"
"$venv/bin/hadolint" deploy/Dockerfile
echo "== manifests"
"$venv/bin/python" scripts/check_manifests.py
echo "== compose file"
docker-compose -f deploy/compose.yaml config --quiet
echo "== container smoke test"
scripts/smoke-image.sh
# And as the Kubernetes and Knative manifests run it: on PostgreSQL (a database of its own).
pg_url=${PENMESH_TEST_POSTGRES_URL:-}
if [ -n "$pg_url" ]; then
  if ! command -v psql >/dev/null 2>&1; then
    apt-get install -y -qq --no-install-recommends postgresql-client >/dev/null
  fi
  db="penmesh_smoke_$$"
  psql "$pg_url" -qc "create database $db"
  trap 'psql "$pg_url" -qc "drop database if exists $db" >/dev/null 2>&1 || true' EXIT
  echo "== container smoke test on PostgreSQL"
  scripts/smoke-image.sh "${pg_url%/*}/$db"
fi
