#!/usr/bin/env bash
# blender.sh: run Blender with an isolated user environment and the Airlight add-on enabled.
#
#   tools/blender.sh [blender args...]        e.g. tools/blender.sh -b file.blend -f 1
#
# User scripts and config live in <repo>/build/blender_user (override with
# AIRLIGHT_BLENDER_USER), so nothing in ~/.config/blender is read or written. The add-on
# is linked from addon/airlight (including the built _native module) into
# .../scripts/addons/airlight. Blender runs with --factory-startup and --addons airlight
# (which enables add-ons in 3.4 even with factory settings); its exit code is passed
# through. Set BLENDER to choose the binary.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
user_root="${AIRLIGHT_BLENDER_USER:-$repo/build/blender_user}"
scripts="$user_root/scripts"
addons="$scripts/addons"
mkdir -p "$addons" "$user_root/config"

# Link the package; replace a stale link or copy left by an older checkout.
target="$repo/addon/airlight"
link="$addons/airlight"
if [ "$(readlink "$link" 2>/dev/null || true)" != "$target" ]; then
  rm -rf "$link.tmp.$$"
  ln -s "$target" "$link.tmp.$$"
  mv -Tf "$link.tmp.$$" "$link"
fi

export BLENDER_USER_SCRIPTS="$scripts"
export BLENDER_USER_CONFIG="$user_root/config"
# The models' tables across processes (addon/airlight/native.py), beside the user folder.
export AIRLIGHT_TABLE_CACHE="${AIRLIGHT_TABLE_CACHE-$user_root/table_cache}"
exec "${BLENDER:-blender}" --factory-startup --addons airlight "$@"
