#!/usr/bin/env bash
# The fleet workflow on a real Slurm (docs/fleet.md): a single-node cluster on localhost
# (test/fleet/local_slurm.sh: munged, slurmctld, slurmd, 2 CPUs), a job array of
# tools/slurm_calibrate_array.sh over three short simulated logs of three vehicles (the third
# with a right tyre 1 % larger), a bounded wait, and autocal_fleet_report over the results.
# Needs root and Debian's packages (installed when missing); exits 77 (skipped) without root.
#
#   slurm_fleet_test.sh SOURCE_DIR TOOL_DIR WORK_DIR

set -u
source_dir=$1 tool_dir=$2 work=$3
here=$(cd "$(dirname "$0")" && pwd)
job_timeout_s=300

if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then
  echo "skipped: the Slurm fleet test needs root and apt-get (it installs and starts Slurm)"
  exit 77
fi
"$here/local_slurm.sh" install || exit 1
rm -rf "$work"
mkdir -p "$work/logs"
state=$work/cluster
rc=1
trap '"$here/local_slurm.sh" stop "$state" >/dev/null; exit $rc' EXIT
"$here/local_slurm.sh" start "$state" || exit 1
. "$state/env.sh"

# Three vehicles, one log each.
: > "$work/fleet.txt"
for i in 1 2 3; do
  change=0
  [ $i = 3 ] && change=1
  "$tool_dir/autocal_simulate" --scenario=urban --duration_s=25 --lidar=false --seed=$((50 + i)) \
    --right_wheel_radius_change_pct=$change --out="$work/logs/car_$i" >/dev/null || exit 1
  echo "car_$i $work/logs/car_$i" >> "$work/fleet.txt"
done

job=$(AUTOCAL_BIN=$tool_dir sbatch --parsable --array=0-2 --chdir="$work" \
  --output="$work/task_%a.log" "$source_dir/tools/slurm_calibrate_array.sh" "$work/fleet.txt" \
  "$source_dir/problems/imu_wheel_gnss.yaml" "$work/results") || exit 1
job=${job%%;*}
echo "submitted job array $job"
deadline=$(($(date +%s) + job_timeout_s))
while [ -n "$(squeue -h -j "$job" -o %i 2>/dev/null)" ]; do
  if [ "$(date +%s)" -ge "$deadline" ]; then
    echo "FAILED: the job array did not finish within $job_timeout_s s"
    squeue -j "$job"
    scancel "$job"
    tail -n 20 "$work"/task_*.log "$state/log/slurmctld.log" "$state/log/slurmd.log"
    exit 1
  fi
  sleep 1
done
echo "job array finished"

"$tool_dir/autocal_fleet_report" --output="$work/report" "$work"/results/car_* \
  > "$work/report.txt" 2>&1
report_rc=$?
cat "$work/report.txt"
fail() {
  echo "FAILED: $*"
  tail -n 20 "$work"/task_*.log
  exit 1
}
[ $report_rc = 0 ] || fail "autocal_fleet_report exited $report_rc, expected 0"
grep -q "^3 runs: 3 calibrated, 0 failed" "$work/report.txt" || fail "not three calibrations"
grep -q "^outlier: car_3: right rear wheel radius" "$work/report.txt" || fail "car_3 not flagged"
[ "$(grep -c '^outlier:' "$work/report.txt")" = 1 ] || fail "more than one outlier"
[ "$(grep -c ',0,' "$work/report/fleet.csv")" = 3 ] || fail "fleet.csv lacks three exit-0 rows"
for i in 1 2 3; do
  grep -q "^exit_status: 0$" "$work/results/car_$i/status.yaml" || fail "car_$i status"
done
echo "PASSED"
rc=0
