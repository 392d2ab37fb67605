#!/usr/bin/env bash
# What the reference run's model arithmetic costs on its own: the instructions (callgrind,
# inclusive) of the functions whose results are the output's numbers, and which any run
# giving the same bytes must therefore evaluate as often as today (the plant's exact steps do
# not compose to the bit, so none can be merged; the desired motion is asked at distinct
# instants). Everything else in the run (event queue, links, frames, the nodes' frame
# handling and counters) is what a faster driver could remove. Compare the sum with the
# targets of issue 12 (40 M for the run, 2 500 per axis and cycle).
#
#   tools/sim-floor.sh [BINARY]      # default target/release/ringsync; needs valgrind
#
# Left out, so the sum is a lower bound: the slaves' clock servo and the oscillator's
# forward reading (both inlined into their callers), the master's sample decoding.
set -euo pipefail
bin="${1:-target/release/ringsync}"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
valgrind --tool=callgrind --callgrind-out-file="$out/cg" "$bin" sim paper-2015 --seed 7 \
  --outputs summary --out "$out/run" >/dev/null 2>"$out/log"
total="$(sed -n 's/.*Collected : //p' "$out/log" | tr -d ,)"
cycles="$(sed -n 's/.*"cycles": *\([0-9]*\).*/\1/p' "$out/run/summary.json" | head -n 1)"
axes=4 # the reference ring (paper-2015) has four
callgrind_annotate --tree=calling --inclusive=yes --threshold=100 "$out/cg" >"$out/calls" 2>/dev/null
# The cost of every call into one function (callgrind's "=>" lines: all the instructions
# run from the call to its return, wherever the code came from).
cost() {
  awk -v sym="$1" '
    / => / {
      n = $1; gsub(",", "", n)
      line = $0; sub(/^.* => /, "", line)
      sub(/ \([0-9,]+x\)$/, "", line); sub(/ \[[^]]*\]$/, "", line)
      f = substr(line, index(line, ":") + 1)
      if (f == sym) sum += n
    }
    END { print sum + 0 }' "$out/calls"
}
printf '%-62s %13s %10s\n' "part (function, inclusive)" instructions per_ax_cyc
sum=0
row() { # label, symbol
  local c
  c="$(cost "$2")"
  if [ "$c" -eq 0 ]; then
    echo "sim-floor: no callgrind entry for $2 (renamed or inlined?)" >&2
    exit 1
  fi
  sum=$((sum + c))
  printf '%-62s %13d %10d\n' "$1" "$c" $((c / (cycles * axes)))
}
row "law, estimator, monitors, desired motion (Motion::compute)" \
  '<ringsync_model::motion::ControlMotion as ringsync_proto::node::motion::Motion>::compute'
row "plant's exact steps, 4 per axis and cycle (Axes::advance)" \
  '<ringsync_model::axes::ServoAxes as ringsync_model::axes::Axes>::advance'
row "encoder counts at each latch (Axes::counts)" \
  '<ringsync_model::axes::ServoAxes as ringsync_model::axes::Axes>::counts'
row "slave clocks' true instants (Oscillator::true_at)" \
  'ringsync_model::oscillator::Oscillator::true_at'
row "desired motion at each cycle start (Motion::desired)" \
  '<ringsync_model::motion::ControlMotion as ringsync_proto::node::motion::Motion>::desired'
row "metrics at each cycle start (Recorder::cycle)" \
  '<ringsync_model::record::Recorder as ringsync_model::observer::Observer>::cycle'
printf '%-62s %13d %10d\n' "model arithmetic, sum (a lower bound)" "$sum" $((sum / (cycles * axes)))
printf '%-62s %13d %10d\n' "the whole run (start-up included)" "$total" $((total / (cycles * axes)))
printf '%-62s %13d %10d\n' "issue 12's target for the whole run" 40000000 2500
