"""Ctrl-C (a Jupyter kernel's interrupt) stops long work in Rust: KeyboardInterrupt is
raised promptly, and the interpreter goes on working."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

# The child announces the call, makes it, and says how it ended; then one short run shows
# the interpreter (and the extension) still works.
CHILD = """
import sys, time
import ringsync
print("calling", flush=True)
t0 = time.perf_counter()
try:
    {call}
    print("finished", flush=True)
except KeyboardInterrupt:
    print(f"interrupted after {{time.perf_counter() - t0:.2f}} s", flush=True)
run = ringsync.simulate("paper-2015", duration="0.1s")
print("then simulate:", len(run.time), "cycles", flush=True)
"""

CALLS = {
    # 10 000 runs: minutes if the interrupt were not taken.
    "sweep": 'ringsync.sweep("paper-2015", {"control.alpha": [0.1 * k for k in range(1, 11)]}, seeds=1000)',
    # One hour of simulated time: minutes as well.
    "simulate": 'ringsync.simulate("paper-2015", duration="3600s")',
    "reproduce": "ringsync.reproduce(seeds=10000)",
}


@pytest.mark.parametrize("what", sorted(CALLS))
def test_ctrl_c_interrupts_long_work_and_the_interpreter_goes_on(what: str) -> None:
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD.format(call=CALLS[what])],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # SIGINT at its default in the child, whatever the suite's (a background job
        # ignores it, and Python then installs no KeyboardInterrupt handler).
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert child.stdout is not None
    assert child.stdout.readline().strip() == "calling"
    time.sleep(0.5)  # well inside the call, which takes minutes
    child.send_signal(signal.SIGINT)
    try:
        out, err = child.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        child.kill()
        out, err = child.communicate()
        pytest.fail(f"{what}: still running 120 s after Ctrl-C: {out!r} {err!r}")
    lines = out.splitlines()
    assert lines and lines[0].startswith("interrupted after "), (out, err)
    # Taken within a cycle or a run, not when the work ended by itself (tens of seconds at
    # least: a late KeyboardInterrupt would land in the same `try`).
    after = float(lines[0].removeprefix("interrupted after ").removesuffix(" s"))
    assert after < 10, (what, after)
    assert lines[1:] == ["then simulate: 100 cycles"], (out, err)
    assert child.returncode == 0, err
