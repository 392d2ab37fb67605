#!/usr/bin/env bash
# Instructions per axis and cycle of the simulation alone, against the number of axes n:
# the difference between a 120-cycle and a 20-cycle run of n axes (start-up and outputs
# cancel), divided by 100·n, counted by callgrind (independent of the host's load).
#
#   tools/sim-cost-per-axis.sh [BINARY]      # default target/release/ringsync; needs valgrind
#
# The rings use small gains and a slow, small trajectory (stable at the long cycles a long
# ring needs); it is a cost measurement, not a control experiment.
set -euo pipefail
bin="${1:-target/release/ringsync}"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
common=(--set 'trajectory.period="400s"' --set trajectory.peak_speed=0.01
  --set faults.following_error_limit=1000 --set faults.brake_gain=0.001
  --set control.kp=0.01 --set control.kd=0.001 --set control.ke=0.001 --outputs summary)
count() { # n, cycle [ms], cycles
  valgrind --tool=callgrind --callgrind-out-file=/dev/null "$bin" sim paper-2015 \
    --set "ring.slaves=$1" --set "ring.cycle=\"$2ms\"" --set "duration=\"$(($2 * $3))ms\"" \
    "${common[@]}" --out "$out/run" 2>&1 | sed -n 's/.*Collected : //p' | tr -d ,
}
echo "n instructions_per_axis_cycle"
for spec in "4 1" "16 5" "64 40" "256 140" "1024 2100"; do
  set -- $spec
  a=$(count "$1" "$2" 20)
  b=$(count "$1" "$2" 120)
  echo "$1 $(((b - a) / (100 * $1)))"
done
