#!/bin/bash
# Builds the harness into benchmarks/gpu_preview/build/ (ignored by git).
# Needs: cmake, a C++17 compiler, libegl-dev libgl-dev libopengl-dev libglm-dev.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
cmake -S "$here" -B "$here/build" -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" >/dev/null
cmake --build "$here/build" -j2
echo "$here/build/gpu_preview_bench"
