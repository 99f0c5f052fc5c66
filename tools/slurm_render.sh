#!/usr/bin/env bash
# slurm_render.sh: render an animation with fog on a Slurm cluster, as a job array.
#
#   tools/slurm_render.sh FILE.blend START END [--chunk K] [--package ZIP] [--output PATH]
#                         [--blender EXE] [-- SBATCH_ARGS...]
#
# Submits one array task per chunk of K frames (default 1) of START..END. Each task:
#   1. installs the add-on from ZIP (default build/airlight.zip, `make package`) into a
#      task-local Blender user folder (under $TMPDIR, removed when the task ends);
#   2. checks that the add-on and its native module load; if not, the task FAILS with the
#      reason (never renders an unfogged frame);
#   3. renders its frames: blender -b FILE -o PATH -s A -e B -a (PATH default: the file's own
#      output path), the fog baked per frame into FILE's cache folder (shared storage).
# FILE, ZIP and PATH should be on storage every node sees; relative paths are made absolute
# here, at submission. Prints the job id (sbatch --parsable). SBATCH_ARGS go to sbatch as
# they are (partition, time limit, --output for the task logs, ...).
set -euo pipefail

if [ "${AIRLIGHT_SLURM_TASK:-}" != "1" ]; then
  # ---- submission --------------------------------------------------------------------
  repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
  usage() { echo "usage: $0 FILE.blend START END [--chunk K] [--package ZIP] [--output PATH] [--blender EXE] [-- SBATCH_ARGS...]" >&2; exit 2; }
  [ $# -ge 3 ] || usage
  file="$1" start="$2" end="$3"
  shift 3
  chunk=1 package="$repo/build/airlight.zip" output="" blender="${BLENDER:-blender}"
  while [ $# -gt 0 ]; do
    case "$1" in
      --chunk) chunk="$2"; shift 2 ;;
      --package) package="$2"; shift 2 ;;
      --output) output="$2"; shift 2 ;;
      --blender) blender="$2"; shift 2 ;;
      --) shift; break ;;
      *) usage ;;
    esac
  done
  [[ "$start" =~ ^-?[0-9]+$ && "$end" =~ ^-?[0-9]+$ && "$chunk" =~ ^[1-9][0-9]*$ ]] || {
    echo "slurm_render: START and END must be integers and K a positive integer" >&2; exit 2; }
  [ "$end" -ge "$start" ] || { echo "slurm_render: END ($end) is before START ($start)" >&2; exit 2; }
  [ -f "$file" ] || { echo "slurm_render: no such .blend file: $file" >&2; exit 2; }
  [ -f "$package" ] || { echo "slurm_render: no add-on package at $package (run \`make package\`)" >&2; exit 2; }
  command -v sbatch >/dev/null || { echo "slurm_render: sbatch not found (Slurm's client tools)" >&2; exit 2; }
  file="$(realpath "$file")"
  package="$(realpath "$package")"
  if [ -n "$output" ] && [[ "$output" != /* ]]; then output="$(pwd)/$output"; fi
  case "$file$package$output$blender" in
    *,*) echo "slurm_render: paths must not hold a comma (sbatch --export splits at them)" >&2; exit 2 ;;
  esac
  tasks=$(( (end - start) / chunk ))
  exec sbatch --parsable --job-name="airlight:$(basename "$file")" --array="0-$tasks" \
    --export=ALL,AIRLIGHT_SLURM_TASK=1,AIRLIGHT_FILE="$file",AIRLIGHT_START="$start",AIRLIGHT_END="$end",AIRLIGHT_CHUNK="$chunk",AIRLIGHT_PACKAGE="$package",AIRLIGHT_OUTPUT="$output",AIRLIGHT_BLENDER="$blender" \
    "$@" "$(realpath "${BASH_SOURCE[0]}")"
fi

# ---- one array task ------------------------------------------------------------------
task="${SLURM_ARRAY_TASK_ID:?slurm_render: not inside a Slurm array task}"
first=$(( AIRLIGHT_START + task * AIRLIGHT_CHUNK ))
last=$(( first + AIRLIGHT_CHUNK - 1 ))
[ "$last" -le "$AIRLIGHT_END" ] || last="$AIRLIGHT_END"
user="$(mktemp -d "${TMPDIR:-/tmp}/airlight_task_${SLURM_ARRAY_JOB_ID:-0}_${task}_XXXXXX")"
trap 'rm -rf "$user"' EXIT
mkdir -p "$user/scripts/addons" "$user/config"
python3 -c "import sys, zipfile; zipfile.ZipFile(sys.argv[1]).extractall(sys.argv[2])" \
  "$AIRLIGHT_PACKAGE" "$user/scripts/addons" || {
  echo "slurm_render: task $task: cannot unpack the add-on package $AIRLIGHT_PACKAGE" >&2; exit 1; }
export BLENDER_USER_SCRIPTS="$user/scripts" BLENDER_USER_CONFIG="$user/config"
blender=("$AIRLIGHT_BLENDER" -b --factory-startup --addons airlight)

# The add-on and its compiled module must load here, or the frames would render unfogged.
check='import sys
try:
    import airlight
    from airlight import native
except Exception as ex:
    sys.exit(f"Airlight add-on not installed: {ex}")
if not native.available():
    sys.exit(f"Airlight native module not loaded: {native.error()}")'
if ! "${blender[@]}" --python-exit-code 1 --python-expr "$check"; then
  echo "slurm_render: task $task (frames $first-$last): the Airlight add-on did not load on $(hostname); not rendering" >&2
  exit 1
fi
args=("$AIRLIGHT_FILE")
[ -z "$AIRLIGHT_OUTPUT" ] || args+=(-o "$AIRLIGHT_OUTPUT")
echo "slurm_render: task $task renders frames $first-$last of $AIRLIGHT_FILE on $(hostname)"
# A frame whose bake failed renders unfogged and says so: fail the task then, too.
log="$user/render.log"
set -o pipefail
"${blender[@]}" "${args[@]}" -s "$first" -e "$last" -a 2>&1 | tee "$log"
if grep -q "rendered without fog" "$log"; then
  echo "slurm_render: task $task: $(grep -c "rendered without fog" "$log") frame(s) rendered without fog (see above); failing" >&2
  exit 1
fi
