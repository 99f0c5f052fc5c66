#!/bin/bash
# Copies what the device machine needs into one folder DEST (e.g. .gpubench in the
# checkout the device tool sends, ignored through .git/info/exclude), which the run tool
# then carries:
#   gpu_preview_bench, ftable.bin, run_device.sh, bench_shaders/ (the stand-in's GLSL),
#   shaders/ (the add-on's GLSL: SHADER_DIR, default this checkout's shaders/),
#   shaders_<name>/ for each further NAME=DIR given (measured too, e.g. main=...),
#   gl/*.deb (glvnd's libEGL/libOpenGL/libGLdispatch, which that machine lacks; unpacked
#   there by run_device.sh).
# Usage: stage.sh DEST [--native-dir DIR] [--shaders DIR] [NAME=DIR ...]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
dest=${1:?usage: stage.sh DEST [--native-dir DIR] [--shaders DIR] [NAME=DIR ...]}
shift
native_dir=$repo/addon/airlight
shaders=$repo/shaders
extra=()
while [ $# -gt 0 ]; do
  case $1 in
    --native-dir) native_dir=$2; shift 2 ;;
    --shaders) shaders=$2; shift 2 ;;
    *=*) extra+=("$1"); shift ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
"$here/build.sh" >/dev/null
rm -rf "$dest"/shaders "$dest"/shaders_* "$dest/bench_shaders"
mkdir -p "$dest/gl" "$dest/shaders" "$dest/bench_shaders"
cp "$here/build/gpu_preview_bench" "$here/run_device.sh" "$dest/"
cp "$shaders"/*.glsl "$dest/shaders/"
for e in "${extra[@]+"${extra[@]}"}"; do
  mkdir -p "$dest/shaders_${e%%=*}"
  cp "${e#*=}"/*.glsl "$dest/shaders_${e%%=*}/"
done
cp "$here"/shaders/*.glsl "$dest/bench_shaders/"
/usr/bin/python3 "$here/make_ftable.py" "$dest/ftable.bin" --native-dir "$native_dir"
if ! ls "$dest"/gl/*.deb >/dev/null 2>&1; then
  (cd "$dest/gl" && apt-get download libegl1 libglvnd0 libopengl0 libgl1 libglx0)
fi
du -sh "$dest"
