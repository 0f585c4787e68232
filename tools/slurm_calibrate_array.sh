#!/usr/bin/env bash
#SBATCH --job-name=autocal
#SBATCH --cpus-per-task=1
#SBATCH --output=autocal_%A_%a.log
#
# One task of a fleet calibration as a Slurm job array (docs/fleet.md). Task i takes line i
# (from 0; blank lines and lines starting with # do not count) of LIST:
#
#   VEHICLE DATASET_DIR [DATASET_DIR ...]     (several directories: one shared calibration)
#
# and runs a stateless autocal_calibrate into RESULTS/VEHICLE, which then holds status.yaml
# whether the run succeeded or not; a failed run keeps a previous result found there as it
# was (docs/fleet.md), so give each array run a RESULTS of its own. Gather with
# autocal_fleet_report RESULTS/*.
#
#   n=$(grep -cv '^\s*\(#\|$\)' LIST)
#   sbatch --array=0-$((n - 1)) tools/slurm_calibrate_array.sh LIST PROBLEM RESULTS [FLAGS...]
#
# FLAGS go to autocal_calibrate. autocal_calibrate is taken from $AUTOCAL_BIN (a directory)
# when set, else from PATH. Names and paths must not contain white space.

set -u
if [ $# -lt 3 ]; then
  echo "usage: sbatch --array=0-N $0 LIST PROBLEM RESULTS [autocal_calibrate flags]" >&2
  exit 1
fi
list=$1 problem=$2 results=$3
shift 3
task=${SLURM_ARRAY_TASK_ID:?"not a Slurm array task (SLURM_ARRAY_TASK_ID unset)"}
line=$(grep -v '^[[:space:]]*\(#\|$\)' "$list" | sed -n "$((task + 1))p")
if [ -z "$line" ]; then
  echo "task $task: $list has no line $((task + 1))" >&2
  exit 1
fi
read -r vehicle datasets <<<"$line"
if [ -z "${datasets}" ]; then
  echo "task $task: line '$line' of $list names no dataset" >&2
  exit 1
fi
args=()
for dataset in $datasets; do args+=("--dataset=$dataset"); done
mkdir -p "$results"
exec "${AUTOCAL_BIN:+$AUTOCAL_BIN/}autocal_calibrate" "${args[@]}" --vehicle="$vehicle" \
  --problem="$problem" --output="$results/$vehicle" --threads="${SLURM_CPUS_PER_TASK:-1}" \
  --progress=false "$@"
