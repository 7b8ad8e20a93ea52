"""Time the study sweeps: a 50-start multistart and a 19-point warm-started Pareto sweep.

Run ``python benchmarks/bench_studies.py [--quick] [--workers N] [--json]``. On the
study-1 base case (beta = 0.5, 50 knots, trapezoidal, symbolic backend) it measures,
in one run so the ratios compare like with like:

* the NLP build and the per-solve time of the base case from the straight line
  (median of 5 solves);
* the 50-start multistart (seeded random spline guesses) on a process pool with
  ``--workers`` workers (default 2), against the same multistart run serially
  in this process (baseline); target <= 2 s wall on 2 cores;
* the 19-point Pareto sweep beta = 0.05 .. 0.95, each point warm-started from
  the previous one, against the same sweep with every point cold-started from
  the straight line (baseline); target <= 0.5 s.

``--quick`` uses 10 starts and 5 weights. Wall times on a shared machine are
noisy (other processes compete for the cores): expect 20-50 % variation.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.multistart import run_multistart
from youbot_opt.trajopt.pareto import DEFAULT_BETAS, pareto_sweep
from youbot_opt.trajopt.solver import TrajOptSolver

TARGET_MULTISTART = 2.0  # [s] wall, 50 starts on 2 cores
TARGET_PARETO = 0.5  # [s] wall, 19 warm-started points


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10 starts, 5 weights")
    parser.add_argument("--workers", type=int, default=2, help="pool size (default 2)")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON too")
    args = parser.parse_args()
    n_starts = 10 if args.quick else 50
    betas = DEFAULT_BETAS[::4] if args.quick else DEFAULT_BETAS

    tic = time.perf_counter()
    solver = TrajOptSolver(study1_problem(50))
    build = time.perf_counter() - tic
    solves = [solver.solve(beta=0.5) for _ in range(5)]
    per_solve = statistics.median(r.wall_time for r in solves)
    base = solves[0]

    tic = time.perf_counter()
    par = run_multistart(
        solver, n_starts, beta=0.5, seed=0,
        sweep=SweepOptions(executor="process", workers=args.workers),
    )  # fmt: skip
    t_par = time.perf_counter() - tic
    tic = time.perf_counter()
    ser = run_multistart(solver, n_starts, beta=0.5, seed=0, sweep=SweepOptions(executor="serial"))
    t_ser = time.perf_counter() - tic
    same = all(
        (a.status, a.iterations) == (b.status, b.iterations)
        and (a.objective == b.objective or np.isnan(a.objective) and np.isnan(b.objective))
        for a, b in zip(par.starts, ser.starts, strict=True)
    )
    solve_sum = sum(s.solve_time for s in ser.starts)
    guess_sum = sum(s.guess_time for s in ser.starts)

    tic = time.perf_counter()
    warm = pareto_sweep(solver, betas)
    t_warm = time.perf_counter() - tic
    tic = time.perf_counter()
    cold = pareto_sweep(solver, betas, warm_start=False)
    t_cold = time.perf_counter() - tic
    gap = max(abs(a.objective - b.objective) for a, b in zip(warm.points, cold.points, strict=True))

    optima = par.distinct_optima()
    rows = [
        ("NLP build (50 knots)", build, None, None),
        ("base-case solve (straight line, median of 5)", per_solve, None, None),
        (f"multistart {n_starts} starts, serial (baseline)", t_ser, None, None),
        (
            f"multistart {n_starts} starts, {args.workers} workers",
            t_par,
            t_ser / t_par,
            TARGET_MULTISTART if n_starts == 50 else None,
        ),
        (f"pareto {len(betas)} points, cold (baseline)", t_cold, None, None),
        (
            f"pareto {len(betas)} points, warm-started",
            t_warm,
            t_cold / t_warm,
            TARGET_PARETO if len(betas) == 19 else None,
        ),
    ]
    print(f"{'case':<48} {'wall [s]':>9} {'speed-up':>9} {'target [s]':>10}")
    for name, t, ratio, target in rows:
        r = f"{ratio:.2f}x" if ratio is not None else ""
        tg = f"{target:.2f}" if target is not None else ""
        print(f"{name:<48} {t:>9.3f} {r:>9} {tg:>10}")
    print(
        f"\nbase case: f = {base.objective:.6f}, T = {base.duration:.4f} s, W = {base.work:.4f}, "
        f"{base.iterations} iterations\n"
        f"multistart: success rate {100 * par.success_rate:.0f} %, "
        f"{len(optima)} distinct optima "
        + ", ".join(f"f = {o.objective:.6f} x{o.count}" for o in optima)
        + f"; parallel == serial: {same}\n"
        f"serial multistart: {solve_sum:.2f} s in IPOPT, {guess_sum:.2f} s building guesses, "
        f"{t_ser / n_starts * 1e3:.1f} ms per start\n"
        f"pareto: max |f_warm - f_cold| = {gap:.2e}; iterations warm "
        f"{sum(p.iterations for p in warm.points)} vs cold {sum(p.iterations for p in cold.points)}"
    )
    if args.json:
        print(
            json.dumps(
                {
                    "build_s": build,
                    "per_solve_s": per_solve,
                    "multistart_serial_s": t_ser,
                    "multistart_parallel_s": t_par,
                    "workers": args.workers,
                    "n_starts": n_starts,
                    "pareto_cold_s": t_cold,
                    "pareto_warm_s": t_warm,
                    "n_betas": len(betas),
                    "success_rate": par.success_rate,
                    "optima": [[o.objective, o.count] for o in optima],
                }
            )
        )


if __name__ == "__main__":
    main()
