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
# the first took under 30 s), SKIP_RAYS=1, SKIP_CPU=1.
set -u
OUT="${OUT:-./gpu-bench-out}"
mkdir -p "$OUT"
CPU_LIMIT="${1:-60}"
GPU_LIMIT="${GPU_LIMIT:-90}"
REPEAT="${REPEAT:-3}"
BIN=target/release/radiosity
log() { echo "== $*" | tee -a "$OUT/bench.log"; }
TIMEV=""
[ -x /usr/bin/time ] && TIMEV="/usr/bin/time -v"

# Vulkan's loader from Debian's package, unpacked over /.
for f in .gl/*.deb; do [ -e "$f" ] && dpkg -x "$f" /; done
ldconfig

# The adapter: try NVIDIA's driver through its EGL library first (its
# stock ICD names libGLX_nvidia, which fails without a display), then the
# stock ICD files, then whatever the loader finds; keep the first with
# which a short GPU solve of the Cornell box runs.
cat >/tmp/nvidia_headless_icd.json <<'JSON'
{ "file_format_version": "1.0.0",
  "ICD": { "library_path": "libEGL_nvidia.so.0", "api_version": "1.3.0" } }
JSON
probe() {
  timeout 60 "$BIN" render cornell --device gpu --max-shots 20 --final-gather off \
    --output /tmp/probe.png --stats /tmp/probe.json >>"$OUT/probe.log" 2>&1 \
    && grep -q '"device_shots": [1-9]' /tmp/probe.json
}
found=""
for icd in /tmp/nvidia_headless_icd.json /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json \
    /usr/share/vulkan/icd.d/nvidia_icd.json /etc/vulkan/icd.d/nvidia_icd.json ""; do
  if [ -n "$icd" ]; then
    [ -e "$icd" ] || continue
    export VK_ICD_FILENAMES="$icd" VK_DRIVER_FILES="$icd"
  else
    unset VK_ICD_FILENAMES VK_DRIVER_FILES
  fi
  echo "-- probe with ICD '${icd:-loader default}'" >>"$OUT/probe.log"
  if probe; then found="${icd:-loader default}"; break; fi
done
nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.sm,clocks.max.sm --format=csv 2>&1 \
  | tee -a "$OUT/bench.log"
log "machine: $(nproc) cores, $(free -g | awk '/Mem:/ {print $2}') GiB; ICD: ${found:-none worked}"
if [ -z "$found" ]; then
  tail -30 "$OUT/probe.log"
  exit 1
fi
grep '"device"' /tmp/probe.json | tee -a "$OUT/bench.log"

# GPU memory in use, sampled every 50 ms while a run goes.
sample_start() {
  nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits -lms 50 >"$OUT/$1.gpumem" 2>/dev/null &
  SAMPLER=$!
}
sample_stop() { kill "$SAMPLER" 2>/dev/null; wait "$SAMPLER" 2>/dev/null; }
run() { # name device limit scene
  local name=$1 device=$2 limit=$3 scene=$4
  log "$name: $device, --time-limit $limit"
  sample_start "$name"
  local start end
  start=$(date +%s.%N)
  timeout $((limit + 120)) $TIMEV "$BIN" render ".scenes/$scene" --device "$device" \
    --time-limit "$limit" --output "$OUT/$name.png" --stats "$OUT/$name.json" \
    >"$OUT/$name.txt" 2>"$OUT/$name.err"
  echo "exit $?" >>"$OUT/$name.txt"
  end=$(date +%s.%N)
  sample_stop
  echo "wall $(awk "BEGIN {print $end - $start}")" >>"$OUT/$name.txt"
  tail -3 "$OUT/$name.txt"
}

SPONZA=sponza_dabrovic/sponza_dabrovic.obj
CONFERENCE=conference/conference.obj
idle=$(nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits 2>/dev/null | head -1)
echo "${idle:-0}" >"$OUT/idle.gpumem"
run sponza-gpu-1 gpu "$GPU_LIMIT" "$SPONZA"
run conference-gpu-1 gpu "$GPU_LIMIT" "$CONFERENCE"
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

# One line a run: its parts' seconds, shots, memory.
python3 - "$OUT" <<'PY' | tee "$OUT/table.txt"
import json, glob, os, sys
out = sys.argv[1]
idle = float(open(os.path.join(out, "idle.gpumem")).read().strip() or 0)
keys = ["total_seconds", "load_seconds", "mesh_seconds", "solve_seconds", "accel_build_seconds",
        "write_seconds", "final_gather_seconds", "device_upload_seconds",
        "device_kernel_seconds", "device_readback_seconds"]
print("run | device | stop | unshot | shots: coarse+all (coarse stop) | dev shots | " + " | ".join(k.replace("_seconds", "") for k in keys)
      + " | peak host MiB | peak GPU MiB (over idle)")
for path in sorted(glob.glob(os.path.join(out, "*.json"))):
    name = os.path.basename(path)[:-5]
    try:
        s = json.load(open(path))
    except Exception as e:
        print(name, "unreadable", e); continue
    mem = [float(x) for x in open(os.path.join(out, name + ".gpumem")).read().split() if x.strip()] \
        if os.path.exists(os.path.join(out, name + ".gpumem")) else []
    peak_gpu = (max(mem) - idle) if mem else float("nan")
    host = (s.get("peak_memory_bytes") or 0) / 2**20
    print(f"{name} | {s.get('device')} | {s.get('stop_reason')} | {s.get('unshot_fraction'):.4f} | "
          f"{s.get('coarse_shots')}+{s.get('shots')} ({s.get('coarse_stop_reason')}) | {s.get('device_shots')} | "
          + " | ".join(f"{s.get(k, float('nan')):.2f}" for k in keys)
          + f" | {host:.0f} | {peak_gpu:.0f}")
PY
# A borrowed machine returns a few files only: everything in one archive,
# the table beside it.
tar czf /tmp/gpu-bench.tgz -C "$OUT" . && cp "$OUT/table.txt" /tmp/gpu-bench-table.txt \
  && find "$OUT" -mindepth 1 -delete && mv /tmp/gpu-bench.tgz /tmp/gpu-bench-table.txt "$OUT/"
