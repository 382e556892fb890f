#!/usr/bin/env bash
# Checks that the suite holds on a busy or slow machine: runs .ci/run on a
# fresh clone of this repository's HEAD (with ../shared copied read-only
# beside it, as CI has it) RUNS times in a row, either beside four busy
# loops or pinned to one core.
#
#   tools/ci-under-load.sh busy [RUNS]      beside 4 busy loops (default 3 runs)
#   tools/ci-under-load.sh one-core [RUNS]  under taskset -c 0
#
# The clone goes to $TMPDIR (or /tmp)/radiosity-ci-MODE, the logs beside
# it; the first run builds, the others reuse the build. PREBUILD=1 builds
# everything first on every core, unloaded, so that the runs time only the
# tests (the build is not what they check). Exits non-zero on the first
# failing run. Takes a while: 10 to 40 minutes a run beside busy loops on
# two cores, the first with the build.
set -euo pipefail
mode=${1:-}
runs=${2:-3}
case "$mode" in
  busy | one-core) ;;
  *) sed -n '2,14p' "$0"; exit 2 ;;
esac
repo=$(cd "$(dirname "$0")/.." && pwd)
shared=$(cd "$repo/../shared" && pwd)
root=${TMPDIR:-/tmp}/radiosity-ci-$mode
rm -rf "$root"
mkdir -p "$root"
cp -r "$shared" "$root/shared"
chmod -R a-w "$root/shared"
git clone -q "$repo" "$root/main"
cd "$root/main"
if [ "${PREBUILD:-0}" = 1 ]; then
  cargo build --release --all-targets --quiet
  cargo test --release --no-run --quiet 2>/dev/null
fi
loops=()
stop_loops() { if [ ${#loops[@]} -gt 0 ]; then kill "${loops[@]}" 2>/dev/null || true; fi; loops=(); }
trap stop_loops EXIT
for i in $(seq 1 "$runs"); do
  log=$root/run-$i.log
  if [ "$mode" = busy ]; then
    for _ in 1 2 3 4; do (while :; do :; done) & loops+=($!); done
  fi
  start=$(date +%s)
  status=0
  if [ "$mode" = busy ]; then
    CI=true bash .ci/run >"$log" 2>&1 || status=$?
  else
    CI=true taskset -c 0 bash .ci/run >"$log" 2>&1 || status=$?
  fi
  stop_loops
  echo "$mode run $i of $runs at $(git rev-parse --short HEAD): exit $status after $(($(date +%s) - start)) s ($log)"
  if [ "$status" -ne 0 ]; then
    tail -40 "$log"
    exit "$status"
  fi
done
