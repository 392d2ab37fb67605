"""Benchmarks of the Python package (docs/benchmarks.md, "Python package").

(a) ``ringsync.simulate("paper-2015")`` (the whole ring: frames, clocks, four servo axes,
    the sync controller; 4 s at 1 ms) beside python-control's ``input_output_response`` of
    the same four axes under PD with viscous friction and no network at all (a nonlinear
    I/O system, 4 s, output every 1 ms): the median of several runs each.
(b) A 1,000-run sweep of ``paper-2015`` (4 s runs, metrics only) in-process (threads in
    Rust) and on a 2-worker ``LocalCluster(processes=True, threads_per_worker=1)``: wall
    time, throughput, and whether the rows are identical.

Run it on a quiet machine with the package built as a plain ``pip install .`` builds it
(the optimised ``wheel`` profile), e.g.::

    python -m venv target/py-bench
    target/py-bench/bin/python -m pip install maturin numpy pandas 'dask[distributed]' control
    target/py-bench/bin/python -m pip install --no-build-isolation .
    target/py-bench/bin/python python/bench/bench_python.py

``--quick`` runs fewer repetitions and a 200-run sweep (a smoke test).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from typing import Any

import numpy as np


def median_time(fn: Any, repeat: int) -> tuple[float, list[float]]:
    """Median wall time of ``fn()`` over ``repeat`` calls [s], and every time."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times


def pd_loop_python_control(friction: str = "viscous") -> tuple[Any, np.ndarray]:
    """The four reference axes under PD, no network, as a python-control nonlinear I/O
    system, and the output times (4 s at 1 ms).

    ``friction``: ``"viscous"`` (b·v only: the loop of docs/python.md), or with the axes'
    Coulomb friction T_c = 0.02 × rated torque as well, ``"sign"`` (T_c·sgn(v), as
    ringsync's exact model) or ``"tanh"`` (T_c·tanh(v / 1 mrad/s), ringsync's smooth one).
    """
    import control

    import ringsync

    s = ringsync.load("paper-2015")
    axes = s["axis"]
    n = len(axes)
    k_a = np.array([a["rated_torque"] / 10.0 for a in axes])
    J = np.array([a["j_over_ka"] for a in axes]) * k_a
    b = np.array([a["viscous"] for a in axes])
    t_c = np.array([a["rated_torque"] * a.get("coulomb_fraction", 0.02) for a in axes])
    coulomb = {
        "viscous": lambda v: 0.0,
        "sign": lambda v: t_c * np.sign(v),
        "tanh": lambda v: t_c * np.tanh(v / 1e-3),
    }[friction]
    k_p, k_d, u_max = s["control.kp"], s["control.kd"], axes[0]["u_max"]
    P = 2.0
    A = s["trajectory.peak_speed"] * P / (2 * np.pi)
    w = 2 * np.pi / P

    def update(t: float, x: np.ndarray, u: np.ndarray, params: Any) -> np.ndarray:
        pos, vel = x[:n], x[n:]
        x_d, v_d = A * (1 - np.cos(w * t)), A * w * np.sin(w * t)
        cmd = np.clip(k_p * (x_d - pos) + k_d * (v_d - vel), -u_max, u_max)
        return np.concatenate([vel, (k_a * cmd - b * vel - coulomb(vel)) / J])

    def output(t: float, x: np.ndarray, u: np.ndarray, params: Any) -> np.ndarray:
        return A * (1 - np.cos(w * t)) - x[:n]

    loop = control.nlsys(update, output, states=2 * n, inputs=0, outputs=n, name="pd")
    return loop, np.arange(4000) * 1e-3


def bench_simulate(repeat: int) -> None:
    import control

    import ringsync

    ringsync.simulate("paper-2015")  # warm up (page faults, first allocation)
    t_rs, all_rs = median_time(lambda: ringsync.simulate("paper-2015"), repeat)
    t_pd, _ = median_time(lambda: ringsync.simulate("paper-2015", **{"control.law": "pd"}), repeat)
    loop, T = pd_loop_python_control()
    n = loop.nstates // 2
    run = lambda: control.input_output_response(loop, T, 0, X0=np.zeros(2 * n))  # noqa: E731
    run()
    t_pc, all_pc = median_time(run, max(3, repeat // 2))
    track_pc = float(np.sqrt(np.sum(run().outputs ** 2) / len(T)))
    print("(a) one 4 s run of the four axes, output every 1 ms")
    print(f"    ringsync.simulate('paper-2015') (ring, sync law):   median {t_rs * 1e3:8.2f} ms "
          f"(min {min(all_rs) * 1e3:.2f}, max {max(all_rs) * 1e3:.2f}, {repeat} runs)")
    print(f"    ringsync.simulate(..., control.law='pd'):           median {t_pd * 1e3:8.2f} ms")
    print(f"    control.input_output_response (PD, no network):     median {t_pc * 1e3:8.2f} ms "
          f"(min {min(all_pc) * 1e3:.2f}, max {max(all_pc) * 1e3:.2f}, {len(all_pc)} runs); "
          f"Track-RMSE {track_pc:.5f} rad")
    print(f"    ratio python-control / ringsync: {t_pc / t_rs:.1f}× (PD vs PD: {t_pc / t_pd:.1f}×)")
    for friction in ("tanh", "sign"):
        loop_f, _ = pd_loop_python_control(friction)
        run_f = lambda: control.input_output_response(loop_f, T, 0, X0=np.zeros(2 * n))  # noqa: E731
        t_f, all_f = median_time(run_f, 3)
        print(f"    the same with the axes' Coulomb friction ({friction}): median {t_f * 1e3:8.2f} ms "
              f"(min {min(all_f) * 1e3:.2f}, max {max(all_f) * 1e3:.2f}, 3 runs); "
              f"ratio {t_f / t_rs:.1f}×")


def bench_sweep(runs: int, repeat: int) -> None:
    from dask.distributed import Client, LocalCluster

    import ringsync

    alphas = [round(0.1 * (i + 1), 1) for i in range(10)]
    seeds = runs // len(alphas)
    grid = {"control.alpha": alphas}
    ringsync.sweep("paper-2015", grid, seeds=1, jobs=2)  # warm up
    t_local, all_local = median_time(lambda: ringsync.sweep("paper-2015", grid, seeds=seeds, jobs=2), repeat)
    local = ringsync.sweep("paper-2015", grid, seeds=seeds, jobs=2)
    n = len(local.rows)
    t0 = time.perf_counter()
    with LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        start = time.perf_counter() - t0
        ringsync.sweep("paper-2015", grid, seeds=1, executor=client)  # warm the workers' imports
        results = []

        def on_dask() -> None:
            results.append(ringsync.sweep("paper-2015", grid, seeds=seeds, executor=client))

        t_dask, all_dask = median_time(on_dask, repeat)
    same = all(r.rows == local.rows and r.mean_rows == local.mean_rows for r in results)
    print(f"(b) a {n}-run sweep of paper-2015 (4 s runs, metrics only), 10 values × {seeds} seeds")
    print(f"    in-process, 2 threads:                median {t_local:6.2f} s "
          f"({n / t_local:6.1f} runs/s; all {', '.join(f'{t:.2f}' for t in all_local)})")
    print(f"    LocalCluster, 2 worker processes:     median {t_dask:6.2f} s "
          f"({n / t_dask:6.1f} runs/s; all {', '.join(f'{t:.2f}' for t in all_dask)}); "
          f"cluster start {start:.1f} s, not counted")
    print(f"    tasks (runs per task): {results[-1].tasks}")
    print(f"    Dask throughput / in-process: {t_local / t_dask * 100:.0f} %; rows identical: {same}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer repetitions, a 200-run sweep")
    ap.add_argument("--no-sweep", action="store_true", help="(a) only")
    args = ap.parse_args()
    import control
    import dask

    import ringsync

    print(f"ringsync {ringsync.__version__}, python-control {control.__version__}, dask {dask.__version__}, "
          f"numpy {np.__version__}, Python {platform.python_version()}, {os.cpu_count()} CPUs, "
          f"load {os.getloadavg()[0]:.2f}")
    bench_simulate(5 if args.quick else 21)
    if not args.no_sweep:
        bench_sweep(200 if args.quick else 1000, 1 if args.quick else 3)


if __name__ == "__main__":
    main()
