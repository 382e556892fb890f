# Sourced by tools/gpu-bench.sh and tools/gpu-variants.sh on a borrowed GPU
# machine: Vulkan's loader unpacked from Debian's package, the first ICD
# with which a short GPU solve runs, and `run NAME DEVICE LIMIT SCENE
# [ARGS...]`, one render with its --stats, summary and the GPU's memory
# sampled while it goes; SPONZA and CONFERENCE, the scenes under .scenes;
# the GPU's memory in use before any run (idle.gpumem). Expects OUT set.
mkdir -p "$OUT"
BIN=target/release/radiosity
log() { echo "== $*" | tee -a "$OUT/bench.log"; }
SPONZA=sponza_dabrovic/sponza_dabrovic.obj
CONFERENCE=conference/conference.obj
# Each run's peak memory and times from GNU time, where there is one.
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

idle=$(nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits 2>/dev/null | head -1)
echo "${idle:-0}" >"$OUT/idle.gpumem"

# GPU memory in use, sampled every 50 ms while a run goes.
sample_start() {
  nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits -lms 50 >"$OUT/$1.gpumem" 2>/dev/null &
  SAMPLER=$!
}
sample_stop() { kill "$SAMPLER" 2>/dev/null; wait "$SAMPLER" 2>/dev/null; }
run() { # name device limit scene [more render arguments]
  local name=$1 device=$2 limit=$3 scene=$4
  shift 4
  log "$name: $device, --time-limit $limit"
  sample_start "$name"
  local start end
  start=$(date +%s.%N)
  timeout $((limit + 120)) $TIMEV "$BIN" render ".scenes/$scene" --device "$device" \
    --time-limit "$limit" --output "$OUT/$name.png" --stats "$OUT/$name.json" "$@" \
    >"$OUT/$name.txt" 2>"$OUT/$name.err"
  echo "exit $?" >>"$OUT/$name.txt"
  end=$(date +%s.%N)
  sample_stop
  echo "wall $(awk "BEGIN {print $end - $start}")" >>"$OUT/$name.txt"
  tail -3 "$OUT/$name.txt"
}


# One line a run: its parts' seconds, shots, memory (table.txt).
table() {
python3 - "$OUT" <<'PY' | tee "$OUT/table.txt"
import json, glob, os, sys
out = sys.argv[1]
idle = float(open(os.path.join(out, "idle.gpumem")).read().strip() or 0)
keys = ["total_seconds", "load_seconds", "mesh_seconds", "solve_seconds", "accel_build_seconds",
        "write_seconds", "final_gather_seconds", "device_upload_seconds",
        "device_kernel_seconds", "device_readback_seconds", "device_pipeline_seconds"]
print("run | device | stop | unshot | shots: coarse+all (coarse stop) | rounds | dev shots | " + " | ".join(k.replace("_seconds", "") for k in keys)
      + " | kernel ms/shot | rest of solve ms/shot | device walk/items/join/book s | passes | host waits | checkpoints"
      + " | submissions | MB read | critical/mean visits | objects made | kernel cache | peak host MiB | peak GPU MiB (over idle)")
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
    shots = max(s.get("shots") or 0, 1)
    st = s.get("device_stage_seconds") or {}
    stages = "/".join(f"{st[k]:.2f}" for k in ("walk", "items", "join", "book") if k in st) or "-"
    kernel = 1000 * s.get("device_kernel_seconds", 0) / max(s.get("device_shots") or 0, 1)
    rest = 1000 * (s.get("solve_seconds", 0) - s.get("device_kernel_seconds", 0)
                   - s.get("device_upload_seconds", 0) - s.get("device_readback_seconds", 0)) / shots
    print(f"{name} | {s.get('device')} | {s.get('stop_reason')} | {s.get('unshot_fraction'):.4f} | "
          f"{s.get('coarse_shots')}+{s.get('shots')} ({s.get('coarse_stop_reason')}) | {s.get('rounds', '-')} | {s.get('device_shots')} | "
          + " | ".join(f"{s.get(k, float('nan')):.2f}" for k in keys)
          + f" | {kernel:.2f} | {rest:.2f} | {stages} | {s.get('device_passes', '-')} | {s.get('device_host_waits', '-')}"
          + f" | {s.get('device_checkpoints', '-')} | {s.get('device_submissions', '-')}"
          + f" | {(s.get('device_bytes_read') or 0) / 1e6:.1f}"
          + f" | {s.get('device_longest_visits', 0)}/{s.get('device_mean_visits', 0):.0f}"
          + f" | {s.get('device_objects_made', '-')} | {s.get('device_pipeline_cache', '-')}"
          + f" | {host:.0f} | {peak_gpu:.0f}")
PY

}

# A borrowed machine returns a few files only: everything in one archive,
# the table beside it.
pack() {
  tar czf /tmp/gpu-bench.tgz -C "$OUT" . && cp "$OUT/table.txt" /tmp/gpu-bench-table.txt \
  && find "$OUT" -mindepth 1 -delete && mv /tmp/gpu-bench.tgz /tmp/gpu-bench-table.txt "$OUT/"
}
