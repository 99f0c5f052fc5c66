#!/bin/bash
# Runs the benchmark on the device machine from a folder made by stage.sh, writing under
# $OUT (the device tool's output folder; default ./out):
#   nvidia_smi.txt        GPU, driver, clocks
#   log_1080_<set>.txt    1920x1080 for each shader set (shaders/, shaders_*/):
#                         $CONFIGS_1080, $GAUSSIANS Gaussians (default 3000)
#   log_small.txt         240x135 with shaders/, 300 Gaussians: the size the llvmpipe
#                         cross-check runs at (bench_gpu_preview.py --compare)
#   images_1080.npz       the fog images of the shaders/ 1080 run (every 4th pixel)
#   images_small.npz      the fog images of the small run (every pixel)
# Environment: PLATFORM (EGL platform, default device), FRAMES, BUDGET (s per
# configuration), CONFIGS_1080, CONFIGS_SMALL, GAUSSIANS, PYTHON (one with numpy),
# EXTRA (further runs, see below).
set -u
here=$(cd "$(dirname "$0")" && pwd)
OUT=${OUT:-$here/out}
mkdir -p "$OUT"
for f in "$here"/gl/*.deb; do dpkg -x "$f" /; done
ldconfig
vendor=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
[ -f "$vendor" ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$vendor
{ nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,clocks.sm,power.limit --format=csv; nvidia-smi; } > "$OUT/nvidia_smi.txt" 2>&1
rm -rf /tmp/gpb_1080_* /tmp/gpb_small  # images of an earlier run on this machine
all=homog_full,homog_half,homog_quarter,compute_full,gauss_full,gauss_half,gauss_quarter,tiles_full,tiles_half,tiles_quarter,tiles_eighth,tilesexact_half,tilesexact_quarter,tilesexact_eighth
bench=("$here/gpu_preview_bench" --ftable "$here/ftable.bin" --bench-shaders "$here/bench_shaders"
       --platform "${PLATFORM:-device}")
for d in "$here"/shaders "$here"/shaders_*; do
  [ -d "$d" ] || continue
  set_name=$(basename "$d")
  mkdir -p "/tmp/gpb_1080_$set_name"
  timeout "${T1080:-300}" "${bench[@]}" --shaders "$d" --size 1920x1080 --frames "${FRAMES:-200}" \
    --warmup 20 --budget-s "${BUDGET:-20}" --gaussians "${GAUSSIANS:-3000}" \
    --configs "${CONFIGS_1080:-$all}" --out "/tmp/gpb_1080_$set_name" --npy-step 4 2>&1 |
    tee "$OUT/log_1080_$set_name.txt"
done
# Optional further 1920x1080 runs with shaders/, one per ';'-separated argument list in
# $EXTRA (e.g. EXTRA='--cull-eps 1e-3 --configs gauss_half;--gaussians 300'), into
# log_extra.txt; each after the defaults --gaussians 3000 --frames 50 --warmup 3.
IFS=';' read -r -a extra_runs <<< "${EXTRA:-}"
for args in "${extra_runs[@]+"${extra_runs[@]}"}"; do
  echo "== extra run: $args" | tee -a "$OUT/log_extra.txt"
  # shellcheck disable=SC2086  # word splitting of the argument list is intended
  timeout 150 "${bench[@]}" --shaders "$here/shaders" --size 1920x1080 --frames 50 --warmup 3 \
    --budget-s 15 --gaussians 3000 $args 2>&1 | tee -a "$OUT/log_extra.txt"
done
mkdir -p /tmp/gpb_small
timeout "${TSMALL:-90}" "${bench[@]}" --shaders "$here/shaders" --size 240x135 --frames 20 --warmup 5 \
  --budget-s 10 --gaussians 300 --configs "${CONFIGS_SMALL:-$all}" --out /tmp/gpb_small \
  --npy-step 1 2>&1 | tee "$OUT/log_small.txt"
"${PYTHON:-python3}" - "$OUT" <<'PY'
import glob, os, sys
import numpy as np
out = sys.argv[1]
for tag, folder in (("1080", "/tmp/gpb_1080_shaders"), ("small", "/tmp/gpb_small")):
    files = sorted(glob.glob(f"{folder}/*.npy"))
    if files:
        np.savez(os.path.join(out, f"images_{tag}.npz"),
                 **{os.path.basename(f)[:-4]: np.load(f) for f in files})
PY
ls -la "$OUT"
