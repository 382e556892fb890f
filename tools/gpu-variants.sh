#!/usr/bin/env bash
# The GPU back end's kernels measured in variants on a borrowed GPU
# machine (DEVELOPERS.md, "Measuring on a GPU machine"), side by side in
# one run: the same solve, the same shots, with the walk split across
# threads or not (RADIOSITY_GPU_FRONTIER=1 walks each receiver's whole tree
# on one thread) and cut into dispatches of fewer or more receivers
# (RADIOSITY_GPU_DISPATCH_RECEIVERS); then the default solve of Sponza and
# the conference room to the end. Expects what tools/gpu-bench.sh does.
#
# Usage: tools/gpu-variants.sh [SHOTS]   (default 400: the fixed-shot runs)
set -u
OUT="${OUT:-./gpu-variants-out}"
SHOTS="${1:-400}"
# shellcheck source=tools/gpu-env.sh
. "$(dirname "$0")/gpu-env.sh"

# The fixed-shot variants on the base mesh (no coarse pass, whose share
# of --time-limit could cut it differently) and without the final pass:
# the same mesh and the same shots, the kernels alone compared.
FAST="--final-gather off --refine-levels 0"
RADIOSITY_GPU_FRONTIER=1 run sponza-f1-s"$SHOTS" gpu 120 "$SPONZA" --max-shots "$SHOTS" $FAST
run sponza-f32-s"$SHOTS" gpu 120 "$SPONZA" --max-shots "$SHOTS" $FAST
run sponza-default gpu 90 "$SPONZA"
run conference-default gpu 90 "$CONFERENCE"
RADIOSITY_GPU_FRONTIER=1 run conference-f1-s100 gpu 90 "$CONFERENCE" --max-shots 100 $FAST
run conference-f32-s100 gpu 90 "$CONFERENCE" --max-shots 100 $FAST
RADIOSITY_GPU_DISPATCH_RECEIVERS=4194304 run sponza-f32-one-dispatch-s"$SHOTS" gpu 120 "$SPONZA" \
  --max-shots "$SHOTS" $FAST
table
pack
