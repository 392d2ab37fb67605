"""Instruction counts of one ``ringsync.simulate("paper-2015")`` and one python-control
``input_output_response`` of the PD loop (bench_python.py's), independent of the host's load.

Each count is the difference of two runs under callgrind that make the call once and twice
(imports, set-up and first-call costs cancel)::

    python python/bench/instructions.py        # runs valgrind four times, prints the counts

Needs valgrind (Debian package ``valgrind``); takes a few minutes.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def call(what: str, times: int) -> None:
    """Sets up both, then makes the call ``times`` times (run under valgrind)."""
    sys.path.insert(0, str(HERE))
    import numpy as np

    import control
    import ringsync
    from bench_python import pd_loop_python_control

    loop, T = pd_loop_python_control()
    x0 = np.zeros(loop.nstates)
    ringsync.load("paper-2015")
    for _ in range(times):
        if what == "ringsync":
            ringsync.simulate("paper-2015")
        else:
            control.input_output_response(loop, T, 0, X0=x0)


def collected(what: str, times: int) -> int:
    p = subprocess.run(
        ["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null",
         sys.executable, __file__, what, str(times)],
        capture_output=True, text=True, check=True,
    )
    m = re.search(r"Collected : (\d+)", p.stderr)
    if m is None:
        raise RuntimeError(p.stderr[-2000:])
    return int(m.group(1))


def main() -> None:
    if len(sys.argv) == 3:
        call(sys.argv[1], int(sys.argv[2]))
        return
    counts = {}
    for what in ("ringsync", "control"):
        once, twice = collected(what, 1), collected(what, 2)
        counts[what] = twice - once
        print(f"{what:9s} one call: {counts[what] / 1e6:8.1f} M instructions "
              f"(runs: {once / 1e6:.1f} M once, {twice / 1e6:.1f} M twice)", flush=True)
    print(f"ratio python-control / ringsync: {counts['control'] / counts['ringsync']:.1f}×")


if __name__ == "__main__":
    main()
