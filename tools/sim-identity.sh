#!/usr/bin/env bash
# Every output of a fixed set of simulator runs, for checking that a change to the simulator
# leaves its results byte-identical: run it with the build before and the build after, then
# `diff -r` the two directories.
#
#   tools/sim-identity.sh BINARY OUTDIR
#
# The set covers each law, loss and corruption, jitter, a silent slave, the lumped-only plan,
# free-running clocks, a sampling lead with the velocity observer, the disturbance observer,
# measured path delays, a broken and healed link, a double break, the arm, 16 axes, a pcapng
# capture and `reproduce`.
set -euo pipefail
bin="${1:?usage: tools/sim-identity.sh BINARY OUTDIR}"
out="${2:?usage: tools/sim-identity.sh BINARY OUTDIR}"
mkdir -p "$out"
short=(--set 'duration="1s"')
run() { # name, args...
  local name="$1"
  shift
  "$bin" sim "$@" --out "$out/$name" >"$out/$name.stdout" 2>"$out/$name.stderr" || echo "exit $?" >>"$out/$name.stdout"
}
run ref paper-2015 --seed 7 --pcap "$out/ref.pcapng"
run pd paper-2015 --set control.law=pd
run ring paper-2015 "${short[@]}" --set control.law=ring-coupled
run lossy paper-2015 "${short[@]}" --set faults.loss=0.05 --set faults.corruption=0.05 --pcap "$out/lossy.pcapng"
run jitter paper-2015 "${short[@]}" --set 'ring.jitter="200ns"'
run silent paper-2015 "${short[@]}" --set faults.silent_slave=3 --set 'faults.silent_from="400ms"'
run lumped paper-2015 "${short[@]}" --set 'ring.plan="lumped-only"'
run adjacent paper-2015 "${short[@]}" --set 'ring.plan="lumped-only"' --set control.law=adjacent
run freeclock paper-2015 "${short[@]}" --set clock.sync=false
run lead paper-2015 "${short[@]}" --set 'clock.sample_lead="50us"' --set control.velocity=observer --set control.observer_bandwidth=200
run dob paper-2015 "${short[@]}" --set control.dob_bandwidth=50 --set control.kh=0.003 --set control.kc=0.01
run measured paper-2015 "${short[@]}" --set 'clock.path_delays="measured"'
run broken paper-2015 --set 'duration="2s"' --set 'faults.break_link="2@500ms..1500ms"'
run split paper-2015 --set 'duration="2s"' --set 'faults.break_link=["2@500ms","4@800ms"]'
run arm arm-2link --set 'duration="1s"'
run wide paper-2015 "${short[@]}" --set ring.slaves=16 --set 'ring.cycle="2ms"'
"$bin" reproduce --seeds 2 --out "$out/reproduce" >"$out/reproduce.stdout" 2>"$out/reproduce.stderr" || echo "exit $?" >>"$out/reproduce.stdout"
# The output directory and the wall time in the messages differ from run to run: drop them.
find "$out" -name '*.stdout' -o -name '*.stderr' |
  xargs sed -i -E "s#$out#OUT#g; s/ in [0-9.]+ ?(µs|ms|s)(\.?)$/\2/"
