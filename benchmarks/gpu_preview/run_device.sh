#!/bin/bash
# Runs the benchmark on the device machine from a staged folder (stage.sh), writing
# logs and images under $OUT (the device tool's output folder; default ./out):
#   nvidia_smi.txt, log_1080.txt (1920x1080, all configurations, 3000 Gaussians),
#   log_small.txt (240x135, 300 Gaussians: the size the llvmpipe cross-check uses),
#   images_1080.npz, images_small.npz (the fog images, every 4th / every pixel).
set -u
here=$(cd "$(dirname "$0")" && pwd)
OUT=${OUT:-$here/out}
mkdir -p "$OUT"
for f in "$here"/gl/*.deb; do dpkg -x "$f" /; done
ldconfig
vendor=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
[ -f "$vendor" ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$vendor
{ nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,clocks.sm,power.limit --format=csv; nvidia-smi; } > "$OUT/nvidia_smi.txt" 2>&1
bench=("$here/gpu_preview_bench" --ftable "$here/ftable.bin" --shaders "$here/shaders"
       --bench-shaders "$here/bench_shaders" --platform "${PLATFORM:-device}")
mkdir -p /tmp/gpb_1080 /tmp/gpb_small
timeout "${T1080:-420}" "${bench[@]}" --size 1920x1080 --frames "${FRAMES:-200}" --warmup 20 \
  --budget-s "${BUDGET:-25}" --gaussians 3000 --out /tmp/gpb_1080 --npy-step 4 \
  ${CONFIGS:+--configs $CONFIGS} 2>&1 | tee "$OUT/log_1080.txt"
timeout "${TSMALL:-90}" "${bench[@]}" --size 240x135 --frames 20 --warmup 5 --budget-s 10 \
  --gaussians 300 --out /tmp/gpb_small --npy-step 1 ${CONFIGS:+--configs $CONFIGS} 2>&1 | tee "$OUT/log_small.txt"
python3 - "$OUT" <<'PY'
import glob, os, sys
import numpy as np
out = sys.argv[1]
for tag in ("1080", "small"):
    files = sorted(glob.glob(f"/tmp/gpb_{tag}/*.npy"))
    if files:
        np.savez(os.path.join(out, f"images_{tag}.npz"),
                 **{os.path.basename(f)[:-4]: np.load(f) for f in files})
PY
ls -la "$OUT"
