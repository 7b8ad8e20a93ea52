"""Benchmark the trajectory solver: SLSQP baseline, scaling over knots, multistart, Pareto.

Run ``python benchmarks/bench_trajopt.py [--quick] [--levers] [--workers N] [--json]``.
Everything is measured in one run, so the ratios compare like with like:

* **Base case** (study 1: beta = 0.5, 50 knots, trapezoidal, straight-line
  start): NLP build time with an empty kernel cache (compiles the dynamics
  kernels to C) and with the cache filled, and the solve's CPU time
  (``time.process_time``) and wall time (median of repeated solves).
* **SLSQP baseline**, the stand-in for the study's fmincon: SciPy's SLSQP on
  the *same* transcription (same variables, bounds, constraints ``g(x) = g0``,
  objective, straight-line start), with finite-difference derivatives (SciPy's
  default 2-point differences). It is capped at ``--slsqp-cap`` seconds; a
  capped run makes the printed ratio a lower bound (marked ``>=``).
* **Scaling** over 25 ... 1600 knots (``--quick``: 25 ... 200): build, solve
  CPU and wall time, iterations and the objective at ``tol = 1e-8`` (the
  default), compared with ``tol = 1e-6`` and ``tol = 1e-10`` from the same start,
  which shows that ``1e-8`` reaches the optimum; the largest grid is also
  solved from the 50-knot solution (mesh refinement).
* **Multistart** of 50 seeded random spline starts on ``--workers`` worker
  processes (wall time, including the pool) and the **19-point Pareto sweep**
  beta = 0.05 ... 0.95, each point warm-started from its neighbour.
* ``--levers``: the speed levers measured one by one on the base case and at
  400 knots -- derivative route (CasADi AD of the MX graph, of the graph
  expanded to SX, structured per-point kernels in CasADi's VM, the same
  kernels compiled to C) and IPOPT options (barrier-parameter oracle,
  limited-memory Hessian, looser tolerance).

Targets (issue 3, item 8, on 2 cores): base solve <= 0.05 s CPU, build <= 0.5 s
(cached), >= 300x faster than SLSQP, 1600 knots <= 2 s, 19-point Pareto <=
0.5 s, 50-start multistart <= 2 s wall. The machine's load average is printed:
on a shared machine, wall times are inflated by other processes, CPU times
much less so.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np
from scipy.optimize import minimize

from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.guess import resolve_guess
from youbot_opt.trajopt.multistart import run_multistart
from youbot_opt.trajopt.pareto import DEFAULT_BETAS, pareto_sweep
from youbot_opt.trajopt.solver import TrajOptSolver

TARGET_SOLVE_CPU = 0.05  # [s] base case, CPU
TARGET_BUILD = 0.5  # [s] base case NLP build (cached kernels)
TARGET_RATIO = 300.0  # SLSQP time / IPOPT time
TARGET_1600 = 2.0  # [s] 1600-knot solve
TARGET_PARETO = 0.5  # [s] wall, 19 warm-started points
TARGET_MULTISTART = 2.0  # [s] wall, 50 starts on 2 workers
BETA = 0.5


def _timed(fn: Callable[[], Any]) -> tuple[Any, float, float]:
    """``fn()``, its wall time and its CPU time in [s]."""
    wall, cpu = time.perf_counter(), time.process_time()
    value = fn()
    return value, time.perf_counter() - wall, time.process_time() - cpu


def _build(n_knots: int, **kwargs: Any) -> tuple[TrajOptSolver, float, float]:
    return _timed(lambda: TrajOptSolver(study1_problem(n_knots), **kwargs))


def _repeat_solve(solver: TrajOptSolver, repeats: int, **kwargs: Any) -> tuple[Any, float, float]:
    """Last result and the median wall and CPU time of ``repeats`` solves."""
    walls, cpus, result = [], [], None
    for _ in range(repeats):
        result, wall, cpu = _timed(lambda: solver.solve(beta=BETA, **kwargs))
        walls.append(wall)
        cpus.append(cpu)
    return result, statistics.median(walls), statistics.median(cpus)


def _nlp_data(solver: TrajOptSolver) -> dict[str, Any]:
    """Straight-line start and numeric bounds of ``solver``'s NLP (public pieces only)."""
    problem, nlp = solver.problem, solver.nlp
    guess = resolve_guess(problem, None)
    bounds = problem.bounds(1.0)
    lbx, ubx = nlp.variable_bounds(bounds, (problem.dt_min, problem.dt_max))
    lbg, ubg = nlp.constraint_bounds(problem.start, problem.goal, bounds)
    x0 = nlp.variables.pack(solver.method.knot_guess(guess, problem.n_knots))
    return {"x0": x0, "lbx": lbx, "ubx": ubx, "lbg": lbg, "ubg": ubg}


class _Capped(Exception):
    pass


def slsqp_baseline(solver: TrajOptSolver, cap: float) -> dict[str, Any]:
    """SciPy SLSQP with finite differences on ``solver``'s transcription, capped at ``cap`` s."""
    data = _nlp_data(solver)
    nlp_fn = ca.Function(
        "nlp_ref", [solver.nlp.x, solver.nlp.p], [solver.nlp.f, solver.nlp.g]
    ).expand()
    lbg = data["lbg"]
    if np.any(data["ubg"] != lbg):
        raise ValueError("the SLSQP baseline expects equality constraints only (trapezoidal)")
    best = {"x": data["x0"]}
    start = time.process_time()

    def fg(x: np.ndarray) -> tuple[float, np.ndarray]:
        if time.process_time() - start > cap:
            raise _Capped
        f, g = nlp_fn(x, BETA)
        return float(f), np.asarray(g).ravel() - lbg

    iterations = [0]

    def count(x: np.ndarray) -> None:  # SLSQP calls it once per iteration
        iterations[0] += 1
        best["x"] = x.copy()

    wall, cpu = time.perf_counter(), time.process_time()
    capped, message = False, ""
    try:
        res = minimize(
            lambda x: fg(x)[0],
            data["x0"],
            method="SLSQP",
            bounds=list(zip(data["lbx"], data["ubx"], strict=True)),
            constraints=[{"type": "eq", "fun": lambda x: fg(x)[1]}],
            options={"maxiter": 5000, "ftol": 1e-10},
            callback=count,
        )
        x, message = res.x, str(res.message)
    except _Capped:
        x, capped, message = best["x"], True, f"capped at {cap:.0f} s CPU"
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    f, g = nlp_fn(x, BETA)
    return {
        "objective": float(f),
        "violation": float(np.max(np.abs(np.asarray(g).ravel() - lbg))),
        "iterations": iterations[0],
        "wall": wall,
        "cpu": cpu,
        "capped": capped,
        "message": message,
    }


def _raw_ipopt(
    solver: TrajOptSolver, route: str, options: IpoptOptions
) -> tuple[float, float, int]:
    """Build and solve the base NLP by a CasADi-AD route; (build, solve CPU) [s], iterations."""
    nlp = solver.nlp

    def build() -> Any:
        fn = ca.Function("nlp", [nlp.x, nlp.p], [nlp.f, nlp.g], ["x", "p"], ["f", "g"])
        fn = fn.expand() if route == "expand" else fn
        return ca.nlpsol("raw", "ipopt", fn, options.to_casadi(True))

    ipopt, build_wall, _ = _timed(build)
    data = _nlp_data(solver)
    _, _, cpu = _timed(lambda: ipopt(p=BETA, **data))
    _, _, cpu2 = _timed(lambda: ipopt(p=BETA, **data))
    return build_wall, min(cpu, cpu2), int(ipopt.stats()["iter_count"])


def _levers(rows: list[str]) -> None:
    """Measure the speed levers one at a time (base case and 400 knots)."""
    rows.append(
        f"{'lever':<44} {'knots':>5} {'build [s]':>9} {'solve CPU [s]':>13} {'iter':>5} {'f':>10}"
    )
    for n in (50, 400):
        ref, _, _ = _build(n)
        for route in ("mx", "expand"):
            b, cpu, it = _raw_ipopt(ref, route, IpoptOptions())
            name = (
                "CasADi AD, MX graph, F.map over knots"
                if route == "mx"
                else ("CasADi AD, MX graph expanded to SX")
            )
            rows.append(f"{name:<44} {n:>5} {b:>9.3f} {cpu:>13.4f} {it:>5} {'':>10}")
        for label, kwargs in (
            ("structured kernels, CasADi VM", {"compile": False}),
            ("structured kernels, compiled C (default)", {}),
            ("  + mu_oracle=probing", {"options": IpoptOptions(extra={"mu_oracle": "probing"})}),
            ("  + hessian=limited-memory", {"options": IpoptOptions(hessian="limited-memory")}),
            ("  + tol=1e-6", {"options": IpoptOptions(tol=1e-6)}),
        ):
            solver, build, _ = _build(n, **kwargs)
            res, _, cpu = _repeat_solve(solver, 3 if n <= 50 else 1)
            rows.append(
                f"{label:<44} {n:>5} {build:>9.3f} {cpu:>13.4f} {res.iterations:>5} "
                f"{res.objective:>10.6f}"
            )


def _verdict(value: float, target: float, *, larger_is_better: bool = False) -> str:
    ok = value >= target if larger_is_better else value <= target
    return "PASS" if ok else "MISS"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="knots <= 200, 10 starts, 5 weights")
    parser.add_argument("--levers", action="store_true", help="also measure each speed lever")
    parser.add_argument("--workers", type=int, default=2, help="multistart pool size (default 2)")
    parser.add_argument(
        "--slsqp-cap", type=float, default=None, help="SLSQP CPU cap in [s] (default 300, quick 30)"
    )
    parser.add_argument("--json", action="store_true", help="print the figures as JSON too")
    args = parser.parse_args()
    quick = args.quick
    cap = args.slsqp_cap if args.slsqp_cap is not None else (30.0 if quick else 300.0)
    knots = (25, 50, 100, 200) if quick else (25, 50, 100, 200, 400, 800, 1600)
    n_starts = 10 if quick else 50
    betas = DEFAULT_BETAS[::4] if quick else DEFAULT_BETAS
    load0 = os.getloadavg()
    out: dict[str, Any] = {"quick": quick, "loadavg_start": load0}

    # -- base case: cold build (empty kernel cache), cached build, solve
    with tempfile.TemporaryDirectory() as cache:
        old = os.environ.get("YOUBOT_OPT_CACHE")
        os.environ["YOUBOT_OPT_CACHE"] = cache
        try:
            _, cold_build, _ = _build(50)
            solver, cached_build, _ = _build(50)
        finally:
            if old is None:
                del os.environ["YOUBOT_OPT_CACHE"]
            else:
                os.environ["YOUBOT_OPT_CACHE"] = old
    base, base_wall, base_cpu = _repeat_solve(solver, 20)
    out["base"] = {
        "build_cold_s": cold_build, "build_cached_s": cached_build, "solve_wall_s": base_wall,
        "solve_cpu_s": base_cpu, "objective": base.objective, "iterations": base.iterations,
        "compiled": solver.compiled,
    }  # fmt: skip

    slsqp = slsqp_baseline(solver, cap)
    ratio_cpu = slsqp["cpu"] / base_cpu
    ratio_wall = slsqp["wall"] / base_wall
    out["slsqp"] = {**slsqp, "ratio_cpu": ratio_cpu, "ratio_wall": ratio_wall}

    # -- scaling over knots
    scaling = []
    for n in knots:
        s, build, build_cpu = _build(n)
        res, wall, cpu = _repeat_solve(s, 3 if n <= 200 else 1)
        loose = TrajOptSolver(s.problem, options=IpoptOptions(tol=1e-6)).solve(beta=BETA)
        tight = TrajOptSolver(s.problem, options=IpoptOptions(tol=1e-10)).solve(beta=BETA)
        scaling.append({
            "n_knots": n, "build_s": build, "build_cpu_s": build_cpu, "solve_wall_s": wall,
            "solve_cpu_s": cpu, "iterations": res.iterations, "objective": res.objective,
            "status": res.status.value, "objective_tol_1e-6": loose.objective,
            "iterations_tol_1e-6": loose.iterations, "objective_tol_1e-10": tight.objective,
        })  # fmt: skip
    out["scaling"] = scaling
    # Mesh refinement: the largest grid started from the 50-knot solution (resampled).
    refined, refined_wall, refined_cpu = _timed(lambda: s.solve(beta=BETA, guess=base))
    out["refined"] = {
        "n_knots": knots[-1], "solve_wall_s": refined_wall, "solve_cpu_s": refined_cpu,
        "iterations": refined.iterations, "objective": refined.objective,
    }  # fmt: skip

    # -- multistart and Pareto sweep on the base-case solver
    ms, ms_wall, _ = _timed(
        lambda: run_multistart(
            solver,
            n_starts,
            beta=BETA,
            seed=0,
            sweep=SweepOptions(executor="process", workers=args.workers),
        )  # fmt: skip
    )
    # default: the points run one after another in one crash-isolated worker process
    front, pareto_wall, _ = _timed(lambda: pareto_sweep(solver, betas))
    # in-process (no isolation): its CPU time is the solver work itself
    _, pareto_serial_wall, pareto_cpu = _timed(
        lambda: pareto_sweep(solver, betas, sweep=SweepOptions(executor="serial"))
    )
    optima = ms.distinct_optima()
    out["multistart"] = {
        "n_starts": n_starts, "workers": args.workers, "wall_s": ms_wall,
        "success_rate": ms.success_rate, "optima": [[o.objective, o.count] for o in optima],
    }  # fmt: skip
    out["pareto"] = {
        "n_points": len(betas), "wall_s": pareto_wall,
        "serial_wall_s": pareto_serial_wall, "serial_cpu_s": pareto_cpu,
        "iterations": sum(p.iterations for p in front.points),
    }  # fmt: skip
    out["loadavg_end"] = os.getloadavg()

    # -- report
    bound = ">=" if slsqp["capped"] else ""
    print(f"load average at start {load0[0]:.2f}, at end {out['loadavg_end'][0]:.2f} (2 cores)")
    print(f"\n{'case':<52} {'measured':>12} {'target':>10} {'':>5}")
    # fmt: off
    rows: list[tuple[str, str, str, str]] = []

    def row(name: str, value: str, target: str = "", verdict: str = "") -> None:
        rows.append((name, value, target, verdict))

    row("base case solve, CPU [s] (median of 20)", f"{base_cpu:.4f}", f"<= {TARGET_SOLVE_CPU}",
        _verdict(base_cpu, TARGET_SOLVE_CPU))
    row("base case solve, wall [s]", f"{base_wall:.4f}")
    row("NLP build, empty kernel cache [s]", f"{cold_build:.3f}")
    row("NLP build, cached kernels [s]", f"{cached_build:.3f}", f"<= {TARGET_BUILD}",
        _verdict(cached_build, TARGET_BUILD))
    row("SLSQP (finite differences) / IPOPT, CPU", f"{bound}{ratio_cpu:.0f}x",
        f">= {TARGET_RATIO:.0f}x", _verdict(ratio_cpu, TARGET_RATIO, larger_is_better=True))
    row("SLSQP / IPOPT, wall", f"{bound}{ratio_wall:.0f}x")
    for r in scaling:
        if r["n_knots"] == 1600:
            row("1600 knots solve, CPU [s]", f"{r['solve_cpu_s']:.3f}", f"<= {TARGET_1600}",
                _verdict(r["solve_cpu_s"], TARGET_1600))
            row("1600 knots solve, wall [s]", f"{r['solve_wall_s']:.3f}", f"<= {TARGET_1600}",
                _verdict(r["solve_wall_s"], TARGET_1600))
    row(f"{knots[-1]} knots from the 50-knot solution, CPU [s]", f"{refined_cpu:.3f}")
    row(f"{knots[-1]} knots from the 50-knot solution, wall [s]", f"{refined_wall:.3f}")
    full = len(betas) == 19 and n_starts == 50
    row(f"Pareto {len(betas)} points warm-started, one worker, wall [s]", f"{pareto_wall:.3f}",
        f"<= {TARGET_PARETO}" if full else "", _verdict(pareto_wall, TARGET_PARETO) if full else "")
    row("  same, in-process (executor='serial'), wall [s]", f"{pareto_serial_wall:.3f}")
    row("  same, in-process (executor='serial'), CPU [s]", f"{pareto_cpu:.3f}")
    row(f"multistart {n_starts} starts, {args.workers} workers, wall [s]", f"{ms_wall:.3f}",
        f"<= {TARGET_MULTISTART}" if full else "",
        _verdict(ms_wall, TARGET_MULTISTART) if full else "")
    # fmt: on
    for name, value, target, verdict in rows:
        print(f"{name:<52} {value:>12} {target:>10} {verdict:>5}")

    print(
        f"\nbase case: IPOPT f = {base.objective:.6f} ({base.iterations} iterations, kernels "
        f"{'compiled' if solver.compiled else 'in the CasADi VM'}); SLSQP f = "
        f"{slsqp['objective']:.6f}, max |g| = {slsqp['violation']:.1e}, "
        f"{slsqp['iterations']} iterations, {slsqp['cpu']:.1f} s CPU ({slsqp['message']})"
    )
    print(
        f"multistart: success rate {100 * ms.success_rate:.0f} %, {len(optima)} distinct optima "
        + ", ".join(f"f = {o.objective:.6f} x{o.count}" for o in optima)
    )
    print(f"pareto: {out['pareto']['iterations']} IPOPT iterations in total")
    print(
        f"{knots[-1]} knots from the 50-knot solution: f = {refined.objective:.7f}, "
        f"{refined.iterations} iterations (from the straight line: f = "
        f"{scaling[-1]['objective']:.7f}, {scaling[-1]['iterations']} iterations)"
    )
    print(
        f"\n{'knots':>5} {'build [s]':>9} {'build CPU':>9} {'solve [s]':>9} {'solve CPU':>9} "
        f"{'iter':>5} {'f (tol 1e-8)':>13} {'f (tol 1e-6)':>13} {'iter':>5} {'f (tol 1e-10)':>13}"
    )
    for r in scaling:
        print(
            f"{r['n_knots']:>5} {r['build_s']:>9.3f} {r['build_cpu_s']:>9.3f} "
            f"{r['solve_wall_s']:>9.3f} {r['solve_cpu_s']:>9.3f} {r['iterations']:>5} "
            f"{r['objective']:>13.7f} {r['objective_tol_1e-6']:>13.7f} "
            f"{r['iterations_tol_1e-6']:>5} {r['objective_tol_1e-10']:>13.7f}"
        )
    if args.levers:
        lever_rows: list[str] = []
        _levers(lever_rows)
        print("\n" + "\n".join(lever_rows))
    if args.json:
        print(json.dumps(out))


if __name__ == "__main__":
    main()
