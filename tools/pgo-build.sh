#!/usr/bin/env bash
# A profile-guided (PGO) build of the ringsync command, for long sweeps: the same code and
# the same results to the last bit (no flag changes floating point), laid out by the
# compiler from a profile of the simulator at work. Measured on a 200-run sweep: 6.5 % less
# time than the plain release build at its opt-level 2 (10-13 % when the release profile
# was at level 3; docs/benchmarks.md, "A profile-guided build" and "opt-level 2").
#
#   tools/pgo-build.sh [OUTDIR]     # default target/pgo; prints the binary's path last
#
# RUSTFLAGS set by the caller are kept in both builds, e.g. RUSTFLAGS="-C target-cpu=native"
# for a binary that only this machine's kind of CPU runs.
#
# Needs LLVM's profile tools for the toolchain in use: `rustup component add llvm-tools`.
# Builds twice (instrumented, then optimised): about twice a release build's time.
set -euo pipefail
extra="${RUSTFLAGS:-}"
root="$(cd "$(dirname "$0")/.." && pwd)"
out="${1:-$root/target/pgo}"
profdata="$(find "$(rustc --print sysroot)/lib/rustlib" -name llvm-profdata -type f 2>/dev/null | head -n 1)"
if [ -z "$profdata" ]; then
  echo "pgo-build: llvm-profdata not found; install it with: rustup component add llvm-tools" >&2
  exit 2
fi
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$root"

echo "pgo-build: 1/3 instrumented build" >&2
CARGO_TARGET_DIR="$out/instrumented" RUSTFLAGS="$extra -Cprofile-generate=$work/raw" \
  cargo build --release --locked -p ringsync-cli
bin="$out/instrumented/release/ringsync"

echo "pgo-build: 2/3 training runs" >&2
# The reference run with every output, a sweep (metrics only), and the paths the simulator
# takes besides (PD, the lumped-only plan, loss and corruption, jitter, a long ring, the arm).
short=(--set 'duration="1s"' --outputs summary)
"$bin" sim paper-2015 --out "$work/ref" >/dev/null
"$bin" sweep paper-2015 --set control.alpha=0.3,0.5 --seeds 20 --out "$work/sweep" >/dev/null
"$bin" sim paper-2015 --set control.law=pd --outputs summary --out "$work/pd" >/dev/null
"$bin" sim paper-2015 "${short[@]}" --set 'ring.plan="lumped-only"' --out "$work/lumped" >/dev/null
"$bin" sim paper-2015 "${short[@]}" --set faults.loss=0.01 --set faults.corruption=0.01 --out "$work/loss" >/dev/null
"$bin" sim paper-2015 "${short[@]}" --set 'ring.jitter="200ns"' --out "$work/jitter" >/dev/null
"$bin" sim paper-2015 "${short[@]}" --set ring.slaves=16 --set 'ring.cycle="2ms"' --out "$work/wide" >/dev/null
"$bin" sim arm-2link "${short[@]}" --out "$work/arm" >/dev/null
"$profdata" merge -o "$work/merged.profdata" "$work/raw"

echo "pgo-build: 3/3 optimised build" >&2
CARGO_TARGET_DIR="$out" RUSTFLAGS="$extra -Cprofile-use=$work/merged.profdata" \
  cargo build --release --locked -p ringsync-cli
echo "$out/release/ringsync"
