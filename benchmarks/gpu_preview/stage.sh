#!/bin/bash
# Copies what the device machine needs into one folder DEST (default: .gpubench in the
# checkout the device tool sends), which the run tool then carries:
#   gpu_preview_bench, ftable.bin, shaders/ (the add-on's GLSL), bench_shaders/ (the
#   harness's stand-ins), run_device.sh, gl/*.deb (glvnd's libEGL/libOpenGL, which that
#   machine lacks: unpacked there by run_device.sh).
# Usage: stage.sh DEST [NATIVE_DIR]   (NATIVE_DIR holds the built _native module)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
dest=${1:?usage: stage.sh DEST [NATIVE_DIR]}
native_dir=${2:-$repo/addon/airlight}
"$here/build.sh" >/dev/null
mkdir -p "$dest/gl" "$dest/shaders" "$dest/bench_shaders"
cp "$here/build/gpu_preview_bench" "$here/run_device.sh" "$dest/"
cp "$repo"/shaders/*.glsl "$dest/shaders/"
cp "$here"/shaders/*.glsl "$dest/bench_shaders/"
/usr/bin/python3 "$here/make_ftable.py" "$dest/ftable.bin" --native-dir "$native_dir"
if ! ls "$dest"/gl/*.deb >/dev/null 2>&1; then
  (cd "$dest/gl" && apt-get download libegl1 libglvnd0 libopengl0 libgl1 libglx0)
fi
du -sh "$dest"
