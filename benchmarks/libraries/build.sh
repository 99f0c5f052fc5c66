#!/usr/bin/env bash
# Builds library_bench (needs libsleef-dev and libboost-math-dev, which tools/install_deps.sh installs).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
mkdir -p "$repo/build-libraries"
g++ -O3 -fno-trapping-math -std=c++17 -march=x86-64-v3 -fno-math-errno -I"$repo/native" -I/usr/include/x86_64-linux-gnu \
  "$repo/benchmarks/libraries/library_bench.cpp" "$repo/native/core/quadrature.cpp" \
  -lsleef -o "$repo/build-libraries/library_bench"
echo "built $repo/build-libraries/library_bench"
