#!/usr/bin/env bash
# Makes this machine behave like a busy CI host for the real-time runs: two SCHED_FIFO hogs
# above the ring's loop (priority 90 > 80) that take its CPU for a few ms at a time, as a
# virtual machine's host does when it runs other guests. Calibrated against a loaded CI
# host's runs of the reference (4 s, UDP): there 3-34 % of the cycles were stalled into
# overruns, stalls p50 20-180 µs, longest 4-11 ms; here 20 %, p50 23 µs, longest 12 ms.
# `stress-ng --cpu 2` alone does not do this: the loop's SCHED_FIFO wins over it.
# Usage: tools/busy-host.sh SECONDS   (then run the suite or `ringsync rt` beside it)
set -euo pipefail
exec stress-ng --cpu 2 --cpu-load 15 --cpu-load-slice 2 --sched fifo --sched-prio 90 \
  --timeout "${1:?usage: tools/busy-host.sh SECONDS}s"
