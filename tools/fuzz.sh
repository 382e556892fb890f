#!/usr/bin/env bash
# Runs the loader fuzzers (fuzz/, libFuzzer through cargo-fuzz).
#
#   tools/fuzz.sh TARGET SECONDS     one target (obj, mtl, load_mesh, gltf, lightmap, sensors, ies)
#   tools/fuzz.sh all SECONDS        every target in fuzz/Cargo.toml in turn
#   tools/fuzz.sh list               the targets
#
# Needs cargo-fuzz (`cargo install cargo-fuzz`). cargo fuzz passes
# nightly-only -Z flags (sanitizer and coverage instrumentation) to rustc;
# on a machine with only the stable toolchain, RUSTC_BOOTSTRAP=1 lets the
# stable compiler accept them (set below; verified with rustc 1.95.0 and
# cargo-fuzz 0.13.2). Builds are optimised with debug assertions (-O -a), so
# overflows and debug_assert!s fire too, and without AddressSanitizer
# (-s none): the loaders are safe Rust, where ASan finds nothing, and it
# cost a factor of 2 to 3 in executions per second here. libFuzzer's own
# timeout and memory limit stay on.
#
# The corpus grows in fuzz/corpus/TARGET (not committed), seeded from
# fuzz/seeds/TARGET (committed: small files for every reference form, line
# end, directive and face shape) and from the test scenes, assembled at
# each run into fuzz/generated-seeds/ (the built-in scenes of scenes/ and
# the measured Cornell box of shared/scenes, which is read from there, not
# copied into the project). For OBJ targets a seed is OBJ bytes, a NUL,
# then MTL bytes; for gltf a GLB, or glTF JSON, a NUL, then the one file
# its URIs name (no target reads or writes files); for sensors a points
# file (rtrace -I: x y z nx ny nz a line). A crash is saved in
# fuzz/artifacts/TARGET/; turn it into a regression test in
# tests/fuzz_regressions.rs and fix it. Each run's closing statistics go to
# fuzz/logs/TARGET.log (executions: the `stat::number_of_executed_units`
# line).
#
# Adding a target for a new loader: a file in fuzz/fuzz_targets/ (a few
# lines, see obj.rs), a [[bin]] entry in fuzz/Cargo.toml, seeds in
# fuzz/seeds/NAME/.
set -euo pipefail
cd "$(dirname "$0")/../fuzz"
export RUSTC_BOOTSTRAP=1

targets() { sed -n 's/^name = "\(.*\)"$/\1/p' Cargo.toml | grep -v '^radiosity-fuzz$'; }

if [ "${1:-}" = list ]; then
    targets
    exit 0
fi
target=${1:?usage: tools/fuzz.sh TARGET|all|list SECONDS}
seconds=${2:?usage: tools/fuzz.sh TARGET|all|list SECONDS}
if [ "$target" = all ]; then
    for t in $(targets); do "$0" "$t" "$seconds"; done
    exit 0
fi
targets | grep -qx "$target" || { echo "no fuzz target '$target' (tools/fuzz.sh list)" >&2; exit 1; }

mkdir -p "corpus/$target" "artifacts/$target" logs generated-seeds/obj generated-seeds/mtl \
    generated-seeds/gltf
# The test scenes as seeds: the built-in ones, and the shared measured
# Cornell box (beside a clone, or two levels up from a worktree).
for scene in ../crates/radiosity/scenes/cornell ../crates/radiosity/scenes/room \
    ../../shared/scenes/cornell_box/cornell_box ../../../shared/scenes/cornell_box/cornell_box; do
    if [ -f "$scene.obj" ] && [ -f "$scene.mtl" ]; then
        name=$(basename "$scene")
        { cat "$scene.obj"; printf '\0'; cat "$scene.mtl"; } > "generated-seeds/obj/$name"
        cp "$scene.mtl" "generated-seeds/mtl/$name.mtl"
    fi
done
# The glTF test files: a Blender export (GLB), and a .gltf with its
# external buffer (JSON, a NUL, the buffer, as the gltf target splits it).
cp ../tests/data/blender-cornell.glb generated-seeds/gltf/
{ cat ../tests/data/hierarchy.gltf; printf '\0'; cat ../tests/data/hierarchy.bin; } \
    > generated-seeds/gltf/hierarchy
case "$target" in
    # OBJ targets share the OBJ seeds.
    obj | load_mesh) seeds=(seeds/obj generated-seeds/obj) ;;
    mtl) seeds=(seeds/mtl generated-seeds/mtl) ;;
    # The lightmap rewrite reads glTF, as the loader does.
    gltf | lightmap) seeds=(seeds/gltf generated-seeds/gltf) ;;
    *) seeds=(); [ -d "seeds/$target" ] && seeds=("seeds/$target") ;;
esac
# -max_len: inputs up to 64 KiB (the load_mesh target itself skips inputs
# over 16 KiB); -timeout: a single input running 10 s is a hang; the RSS
# limit catches memory blow-ups.
cargo fuzz run -O -a -s none "$target" "corpus/$target" "${seeds[@]}" -- \
    -max_total_time="$seconds" -max_len=65536 -timeout=10 -rss_limit_mb=2048 \
    -print_final_stats=1 -artifact_prefix="artifacts/$target/" 2>&1 |
    tee "logs/$target.log" | grep -E '^(#[0-9]+ +(DONE|pulse)|stat::|==|SUMMARY|Test unit|artifact)' || true
test "${PIPESTATUS[0]}" -eq 0
