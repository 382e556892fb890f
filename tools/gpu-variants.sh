#!/usr/bin/env bash
# The GPU back end's kernels measured in variants on a borrowed GPU
# machine (DEVELOPERS.md, "Measuring on a GPU machine"), side by side in
# one run: the same solve, the same shots, with the walk split across
# threads at frontiers of 1 (never: RADIOSITY_GPU_FRONTIER=1 walks each
# receiver's whole tree on one thread) to 64 nodes, and cut into
# dispatches of 32,768 receivers (RADIOSITY_GPU_DISPATCH_RECEIVERS) or
# not; then the default solve of Sponza and the conference room. Expects
# what tools/gpu-bench.sh does.
#
# Usage: tools/gpu-variants.sh [SHOTS]   (default 400: the fixed-shot runs)
# Environment: GPU_LIMIT (the default solves' --time-limit, default 90).
set -u
OUT="${OUT:-./gpu-variants-out}"
SHOTS="${1:-400}"
# shellcheck source=tools/gpu-env.sh
. "$(dirname "$0")/gpu-env.sh"

# The fixed-shot variants on the base mesh (no coarse pass, whose share
# of --time-limit could cut it differently) and without the final pass:
# the same mesh and the same shots, the kernels alone compared.
FAST="--final-gather off --refine-levels 0"
# The frontier at which a walk splits, in one dispatch a shot (the
# default where the adapter holds it); then the default's frontier in
# dispatches of 32,768 receivers, as before 2026-11-28.
for f in 1 8 32 64; do
  RADIOSITY_GPU_FRONTIER=$f run sponza-f$f-s"$SHOTS" gpu 120 "$SPONZA" --max-shots "$SHOTS" $FAST
done
RADIOSITY_GPU_DISPATCH_RECEIVERS=32768 run sponza-f32-chunks-s"$SHOTS" gpu 120 "$SPONZA" \
  --max-shots "$SHOTS" $FAST
for f in 1 8 32; do
  RADIOSITY_GPU_FRONTIER=$f run conference-f$f-s100 gpu 90 "$CONFERENCE" --max-shots 100 $FAST
done
run sponza-default gpu "${GPU_LIMIT:-90}" "$SPONZA"
run conference-default gpu "${GPU_LIMIT:-90}" "$CONFERENCE"
table
pack
