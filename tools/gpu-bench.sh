#!/usr/bin/env bash
# The GPU measurements of DEVELOPERS.md ("Measuring on a GPU machine"), as
# one script for a borrowed machine: the default solve of Sponza and of the
# conference room on the GPU and on the CPU, side by side, on the same
# machine, each with its --stats (the adapter named, every part's time) and
# its summary, the GPU's memory sampled by nvidia-smi while it runs; then
# the rays experiment's GPU table. Everything it writes goes to $OUT
# (default ./gpu-bench-out); a short table of every run is printed last.
#
# It expects, relative to the repository's root (carry them):
#   target/release/radiosity   built here (cargo build --release)
#   .gl/*.deb                  Debian's libvulkan1 (apt-get download libvulkan1)
#   .scenes/                   sponza_dabrovic/ and conference/ from ../shared/scenes
#
# Usage: tools/gpu-bench.sh [CPU_TIME_LIMIT_SECONDS]   (default 60)
# Environment: GPU_LIMIT (the GPU runs' --time-limit, default 90),
# REPEAT (GPU runs of each scene, default 3, the later ones only where
# the first took under 30 s), SKIP_RAYS=1, SKIP_CPU=1, SKIP_ROUND1=1 (the
# Sponza run of one shooter a round, --round 1).
set -u
OUT="${OUT:-./gpu-bench-out}"
CPU_LIMIT="${1:-60}"
GPU_LIMIT="${GPU_LIMIT:-90}"
REPEAT="${REPEAT:-3}"
# shellcheck source=tools/gpu-env.sh
. "$(dirname "$0")/gpu-env.sh"
# A cache of compiled kernels of its own: the first run compiles them,
# the ones after load them (the table's kernel cache and pipeline columns).
export RADIOSITY_CACHE_DIR="${RADIOSITY_CACHE_DIR:-$(mktemp -d)}"

run sponza-gpu-1 gpu "$GPU_LIMIT" "$SPONZA"
run conference-gpu-1 gpu "$GPU_LIMIT" "$CONFERENCE"
# One shooter a round, as before rounds: what rounds save on this GPU.
[ "${SKIP_ROUND1:-0}" != 1 ] && run sponza-gpu-round1 gpu "$GPU_LIMIT" "$SPONZA" --round 1
if [ "${SKIP_CPU:-0}" != 1 ]; then
  run sponza-cpu cpu "$CPU_LIMIT" "$SPONZA"
  run conference-cpu cpu "$CPU_LIMIT" "$CONFERENCE"
fi
for i in $(seq 2 "$REPEAT"); do
  for pair in "sponza:$SPONZA" "conference:$CONFERENCE"; do
    name=${pair%%:*}
    took=$(python3 -c "import json;print(int(json.load(open('$OUT/$name-gpu-1.json'))['total_seconds']))" 2>/dev/null || echo 999)
    [ "$took" -lt 30 ] && run "$name-gpu-$i" gpu "$GPU_LIMIT" "${pair#*:}"
  done
done
if [ "${SKIP_RAYS:-0}" != 1 ]; then
  log "rays --quick --device gpu"
  timeout 150 "$BIN" experiment rays --quick --device gpu --scenes .scenes --out "$OUT/rays" \
    >"$OUT/rays.txt" 2>&1
  echo "exit $?" >>"$OUT/rays.txt"
  cp "$OUT/rays/rays.md" "$OUT/rays.md" 2>/dev/null
  tail -25 "$OUT/rays.txt"
fi

table
pack
