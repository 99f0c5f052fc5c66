#!/usr/bin/env bash
# Installs the Debian 12 packages Airlight needs to build, run and test.
# Idempotent: asks apt only for what is missing. Needs root (or sudo).
set -euo pipefail

PKGS=(
  build-essential cmake pkg-config
  pybind11-dev python3-dev libglm-dev
  libopenimageio-dev openimageio-tools python3-openimageio
  libembree-dev libtbb-dev libsleef-dev libboost-math-dev
  libgtest-dev googletest
  python3-numpy python3-scipy python3-mpmath python3-pytest python3-matplotlib
  blender xvfb xauth
  slurm-wlm munge nodejs
)

missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#PKGS[@]} Debian packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install_deps: need root to install: ${missing[*]}" >&2; exit 1; }
  SUDO=sudo
fi
echo "install_deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq "${missing[@]}"
