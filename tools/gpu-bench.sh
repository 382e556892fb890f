#!/usr/bin/env bash
# The GPU measurements of DEVELOPERS.md ("Measuring on a GPU machine"), as
# one script for a borrowed machine: the default solve of Sponza and of the
# conference room on the GPU and on the CPU, side by side, on the same
# machine, each with its --stats (the adapter named, every part's time) and
# its summary; then the rays experiment's GPU table. Everything it writes
# goes to $OUT (default ./gpu-bench-out).
#
# It expects, relative to the repository's root (carry them):
#   target/release/radiosity   built here (cargo build --release)
#   .gl/*.deb                  Debian's libvulkan1 (apt-get download libvulkan1)
#   .scenes/                   sponza_dabrovic/ and conference/ from ../shared/scenes
#
# Usage: tools/gpu-bench.sh [CPU_TIME_LIMIT_SECONDS]   (default 120)
set -u
OUT="${OUT:-./gpu-bench-out}"
mkdir -p "$OUT"
CPU_LIMIT="${1:-120}"
BIN=target/release/radiosity
log() { echo "== $*" | tee -a "$OUT/bench.log"; }

# Vulkan's loader from Debian's package, unpacked over /.
for f in .gl/*.deb; do [ -e "$f" ] && dpkg -x "$f" /; done
ldconfig
# NVIDIA's stock ICD names libGLX_nvidia, which fails without a display:
# the same driver through its EGL library works headless.
if [ -z "${VK_ICD_FILENAMES:-}" ] && ls /usr/lib/x86_64-linux-gnu/libEGL_nvidia.so.0 \
    /usr/local/nvidia/lib64/libEGL_nvidia.so.0 >/dev/null 2>&1; then
  cat >/tmp/nvidia_headless_icd.json <<'JSON'
{ "file_format_version": "1.0.0",
  "ICD": { "library_path": "libEGL_nvidia.so.0", "api_version": "1.3.0" } }
JSON
  export VK_ICD_FILENAMES=/tmp/nvidia_headless_icd.json
fi
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv 2>&1 | tee -a "$OUT/bench.log"
log "machine: $(nproc) cores, $(free -g | awk '/Mem:/ {print $2}') GiB"

# Each scene: GPU first (the whole job, every part timed in --stats), then
# the CPU at its time limit, from the same binary on the same machine.
for scene in sponza_dabrovic/sponza_dabrovic.obj conference/conference.obj; do
  name=$(basename "$scene" .obj)
  log "$name on the GPU"
  /usr/bin/time -v "$BIN" render ".scenes/$scene" --device gpu \
    --output "$OUT/$name-gpu.png" --stats "$OUT/$name-gpu.json" \
    >"$OUT/$name-gpu.txt" 2>"$OUT/$name-gpu.err"
  echo "exit $?" >>"$OUT/$name-gpu.txt"
  log "$name on the CPU (--time-limit $CPU_LIMIT)"
  /usr/bin/time -v "$BIN" render ".scenes/$scene" --device cpu --time-limit "$CPU_LIMIT" \
    --output "$OUT/$name-cpu.png" --stats "$OUT/$name-cpu.json" \
    >"$OUT/$name-cpu.txt" 2>"$OUT/$name-cpu.err"
  echo "exit $?" >>"$OUT/$name-cpu.txt"
done
cat "$OUT"/*-gpu.txt "$OUT"/*-cpu.txt
log "rays --quick --device gpu"
"$BIN" experiment rays --quick --device gpu --scenes .scenes --out "$OUT/rays" \
  >"$OUT/rays.txt" 2>&1
echo "exit $?" >>"$OUT/rays.txt"
cp "$OUT/rays/rays.md" "$OUT/rays.md" 2>/dev/null
tail -40 "$OUT/rays.txt"
# A borrowed machine returns a few files only: everything in one archive.
tar czf /tmp/gpu-bench.tgz -C "$OUT" . && find "$OUT" -mindepth 1 -delete \
  && mv /tmp/gpu-bench.tgz "$OUT/"
