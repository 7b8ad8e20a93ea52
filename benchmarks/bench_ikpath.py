"""Benchmark the IK-path solvers of study 2: both methods, four problems, multistart.

Run ``python benchmarks/bench_ikpath.py [--quick] [--repeats N] [--starts N] [--json]``.
Everything is measured in one run, so the ratios compare like with like.

Problems:

* **A**, **B**: the study's examples (3 links, 5 targets; B with
  ``|theta_i| <= pi/2``), :func:`youbot_opt.ikpath.example_problem`.
* **7-link**: lengths ``(1, .9, .8, .7, .6, .5, .4)`` through 12 targets, the
  tips of 12 configurations drawn uniformly in ``[-pi, pi]^7`` with
  ``numpy.random.default_rng(2026)`` (reachable by construction), no limits.
* **7-link lim**: the same arm with ``|theta_i| <= pi/2`` and targets drawn
  the same way inside the limits.

Measurements:

* **Single solve** from the study's start (the zero vector, clipped into the
  limits), repeated ``--repeats`` times: median wall and CPU time
  (``time.process_time``) of the solver alone, iterations (AL: outer and
  inner BFGS; IPOPT: its iterations), status, ``E`` and the largest residual.
  IPOPT is timed on a prebuilt :class:`~youbot_opt.ikpath.IpoptIKSolver` (as
  multistart uses it); its NLP build time is listed apart, and so is the
  exact reachability check that :func:`~youbot_opt.ikpath.solve` runs first.
  The two methods may stop in different local minima from this start (the
  ``E`` column says so); the ratio is the time ratio all the same.
* **Multistart** (:func:`~youbot_opt.ikpath.run_multistart`, seed 0,
  ``--starts`` feasible starts) with 1 worker (in process) and 2 worker
  processes (pool start-up included): wall time, starts per second, the
  median per-start solve time, how many starts succeeded and how many found
  the best ``E``.

Spatial problems (issue 14, ``--spatial-only`` / ``--planar-only``): ur5
(``tool0``) and panda (``panda_hand_tcp``) through 6, 9 and 12 targets, the
frame placements of configurations drawn uniformly in the joint limits
(clipped to ``[-pi, pi]``, ``default_rng(2026)``), even targets full poses,
odd ones positions. Per case: ms per solve of both methods from the greedy
start (median of ``--repeats``), starts/s of :func:`run_multistart`
on 1 and 2 workers, and the total joint motion ``E`` of the best minimum
against the greedy baseline (each target solved by damped least squares
from the previous configuration, :func:`greedy_path`): the ratio must be <= 1.

Memory (issue 15, ``--memory [--memory-sizes 1000,10000] [--keep-max N]``):
a planar IK multistart of a cheap problem (2 links ``(1, 0.8)`` m, 2 targets
``(1.2, 0.5)`` and ``(0.3, 1.1)`` m, no limits: 3 distinct minima; AL, feasible
starts, seed 0) on a pool of 2 workers into a fresh output folder, with
``keep_results=False`` at every size and ``keep_results=True`` up to
``--keep-max`` starts, in the same run: the driver's peak traced memory
(``tracemalloc``; the workers stop tracing in their initializer), the memory
the result still holds, starts/s, the time of the accessors (best,
status_counts, n_success, minima) and, for ``keep_results=False``, the time of
a resume of the finished folder.

The machine's load average is printed: on a shared machine wall times are
inflated by other processes, CPU times much less so.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from typing import Any

import numpy as np

from youbot_opt.ikpath import (
    CyclicIKProblem,
    IpoptIKSolver,
    PlanarChain,
    check_reachability,
    example_problem,
    run_multistart,
    solve_augmented_lagrangian,
)
from youbot_opt.ikpath.dls import greedy_path
from youbot_opt.ikpath.methods.ipopt import IpoptIKSolver3D
from youbot_opt.ikpath.solve import solve
from youbot_opt.ikpath.starts import make_starts_3d
from youbot_opt.ikpath.targets import Target
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.pool import WorkerPool

SEVEN_LINKS = (1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4)  # [m]
SEVEN_TARGETS = 12
SEVEN_SEED = 2026
E_TOL = 1e-6  # relative: starts whose E is within this of the best "found the best"


def seven_link_problem(limited: bool) -> CyclicIKProblem:
    """The 7-link chain through 12 reachable targets (tips of seeded configurations)."""
    limit = math.pi / 2.0 if limited else math.pi  # [rad]
    chain = PlanarChain(
        lengths=SEVEN_LINKS,
        q_lower=-limit if limited else None,
        q_upper=limit if limited else None,
        name="seven_link" + ("_limited" if limited else ""),
    )
    rng = np.random.default_rng(SEVEN_SEED)
    q = rng.uniform(-limit, limit, (SEVEN_TARGETS, chain.n))
    return CyclicIKProblem(robot=chain, targets=[chain.tip_position(qj) for qj in q])


def problems() -> dict[str, CyclicIKProblem]:
    """The benchmark problems by name."""
    return {
        "A": example_problem("A"),
        "B": example_problem("B"),
        "7-link": seven_link_problem(limited=False),
        "7-link lim": seven_link_problem(limited=True),
    }


def _timed(fn: Callable[[], Any]) -> tuple[Any, float, float]:
    """``fn()``, its wall time and its CPU time in [s]."""
    wall, cpu = time.perf_counter(), time.process_time()
    value = fn()
    return value, time.perf_counter() - wall, time.process_time() - cpu


def _repeat(fn: Callable[[], Any], repeats: int) -> tuple[Any, float, float]:
    """Last value of ``fn()`` and the median wall and CPU time in [s] of ``repeats`` calls."""
    walls, cpus, value = [], [], None
    for _ in range(repeats):
        value, wall, cpu = _timed(fn)
        walls.append(wall)
        cpus.append(cpu)
    return value, statistics.median(walls), statistics.median(cpus)


def _row(result: Any, wall: float, cpu: float) -> dict[str, Any]:
    return {
        "status": result.status.value,
        "E": result.objective,
        "max_residual": result.max_position_error(),
        "limit_violation": result.limit_violation,
        "iterations": result.iterations,
        "inner_iterations": result.inner_iterations,
        "wall": wall,
        "cpu": cpu,
    }


def bench_single(problem: CyclicIKProblem, repeats: int) -> dict[str, Any]:
    """Both methods from the study's start: medians over ``repeats`` solves."""
    _, reach_wall, _ = _repeat(lambda: check_reachability(problem), repeats)
    al, al_wall, al_cpu = _repeat(lambda: solve_augmented_lagrangian(problem), repeats)
    solver, build_wall, build_cpu = _repeat(lambda: IpoptIKSolver(problem), min(repeats, 3))
    ip, ip_wall, ip_cpu = _repeat(lambda: solver.solve(problem), repeats)
    return {
        "reachability_wall": reach_wall,
        "ipopt_build_wall": build_wall,
        "ipopt_build_cpu": build_cpu,
        "al": _row(al, al_wall, al_cpu),
        "ipopt": _row(ip, ip_wall, ip_cpu),
        "wall_ratio_al_over_ipopt": al_wall / ip_wall,
        "cpu_ratio_al_over_ipopt": al_cpu / max(ip_cpu, 1e-9),
    }


def bench_multistart(problem: CyclicIKProblem, method: str, n_starts: int) -> dict[str, Any]:
    """Multistart with 1 and 2 workers: throughput and how often the best E is found."""
    out: dict[str, Any] = {}
    for workers in (1, 2):
        ms, wall, cpu = _timed(
            lambda w=workers: run_multistart(
                problem, method=method, n_starts=n_starts, seed=0, sweep=SweepOptions(workers=w)
            )
        )
        ok = [r for r in ms.results if r.success]
        best = min((r.objective for r in ok), default=math.inf)
        found = sum(1 for r in ok if r.objective <= best + E_TOL * max(1.0, abs(best)))
        out[str(workers)] = {
            "wall": wall,
            "parent_cpu": cpu,
            "starts_per_second": n_starts / wall,
            "median_start_wall": statistics.median(r.wall_time for r in ms.results),
            "n_success": len(ok),
            "best_E": best,
            "found_best": found,
            "distinct_minima": len(ms.minima),
        }
    out["speedup_2_over_1"] = out["1"]["wall"] / out["2"]["wall"]
    return out


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:9.1f}"


def print_report(report: dict[str, Any]) -> None:
    """Print the tables of :func:`main`'s report."""
    load = report["load_average"]
    print(
        f"bench_ikpath: {report['cpu_count']} CPUs, load average "
        f"{load[0]:.2f} {load[1]:.2f} {load[2]:.2f}; repeats {report['repeats']}, "
        f"multistart starts {report['starts']}"
    )
    print("\nSingle solve from the zero start (medians; IPOPT solve on a prebuilt NLP)")
    head = (
        f"{'problem':<11}{'method':<7}{'status':<15}{'E [rad^2]':>14}{'max res [m]':>12}"
        f"{'iters':>7}{'inner':>7}{'wall [ms]':>10}{'CPU [ms]':>10}"
    )
    print(head)
    print("-" * len(head))
    for name, case in report["single"].items():
        for method in ("al", "ipopt"):
            r = case[method]
            print(
                f"{name:<11}{method:<7}{r['status']:<15}{r['E']:>14.8f}{r['max_residual']:>12.1e}"
                f"{r['iterations']:>7d}{r['inner_iterations']:>7d}{_ms(r['wall'])} "
                f"{_ms(r['cpu'])}"
            )
        print(
            f"{'':<11}AL/IPOPT time ratio: wall {case['wall_ratio_al_over_ipopt']:.1f}x, "
            f"CPU {case['cpu_ratio_al_over_ipopt']:.1f}x; IPOPT build "
            f"{case['ipopt_build_wall'] * 1e3:.1f} ms; reachability check "
            f"{case['reachability_wall'] * 1e3:.1f} ms"
        )
    print(f"\nMultistart, {report['starts']} seeded feasible starts (seed 0)")
    head = (
        f"{'problem':<11}{'method':<7}{'workers':>8}{'wall [s]':>10}{'starts/s':>10}"
        f"{'per start [ms]':>15}{'success':>9}{'best E':>14}{'found best':>11}{'minima':>7}"
    )
    print(head)
    print("-" * len(head))
    for name, methods in report["multistart"].items():
        for method, runs in methods.items():
            for workers in ("1", "2"):
                r = runs[workers]
                print(
                    f"{name:<11}{method:<7}{workers:>8}{r['wall']:>10.2f}"
                    f"{r['starts_per_second']:>10.1f}{r['median_start_wall'] * 1e3:>15.1f}"
                    f"{r['n_success']:>9d}{r['best_E']:>14.8f}{r['found_best']:>11d}"
                    f"{r['distinct_minima']:>7d}"
                )
            print(f"{'':<18}2 workers / 1 worker speed-up: {runs['speedup_2_over_1']:.2f}x")
        al, ip = methods["al"], methods["ipopt"]
        print(
            f"{'':<18}throughput IPOPT/AL: 1 worker "
            f"{ip['1']['starts_per_second'] / al['1']['starts_per_second']:.1f}x, 2 workers "
            f"{ip['2']['starts_per_second'] / al['2']['starts_per_second']:.1f}x"
        )
    print(f"\ntotal benchmark time {report['elapsed']:.1f} s")


def spatial_problem(robot_name: str, n_targets: int, seed: int = 2026) -> CyclicIKProblem:
    """Targets at the frame placements of random in-limit configurations (poses on even ones)."""
    from youbot_opt.robot.load import load_model

    robot = load_model(robot_name)
    model, data = robot.model, robot.model.createData()
    base = CyclicIKProblem(
        robot=model,
        frame=robot.tip_frame,
        targets=(Target(position=(0, 0, 0)), Target(position=(0, 0, 0))),
    )
    rng = np.random.default_rng(seed)
    lo = np.maximum(base.q_lower, -np.pi)
    hi = np.minimum(base.q_upper, np.pi)
    targets = []
    for k in range(n_targets):
        theta = rng.uniform(lo, hi)
        placement = base.placement(theta, data)
        rot = placement.rotation if k % 2 == 0 else None
        targets.append(Target(position=placement.translation, rotation=rot))
    return base.with_targets(targets)


def bench_spatial(robot: str, n_targets: int, repeats: int, n_starts: int) -> dict[str, Any]:
    """One spatial case: both methods' ms per solve, starts/s on 1 and 2 workers, motion ratio."""
    problem = spatial_problem(robot, n_targets)
    greedy, greedy_ok = greedy_path(problem)
    e_greedy = problem.objective(greedy)
    x0 = make_starts_3d(problem, 1, 0)[0]
    row: dict[str, Any] = {"robot": robot, "targets": n_targets, "greedy_E": e_greedy}
    row["greedy_ok"] = greedy_ok
    al, wall_al, _ = _repeat(lambda: solve(problem, method="al", x0=x0), repeats)
    ipopt_solver = IpoptIKSolver3D(problem)
    ip, wall_ip, _ = _repeat(lambda: ipopt_solver.solve(x0), repeats)
    row.update(
        al_ms=wall_al * 1e3,
        al_status=al.status.value,
        al_E=al.objective,
        ipopt_ms=wall_ip * 1e3,
        ipopt_status=ip.status.value,
        ipopt_E=ip.objective,
    )
    best = math.inf
    for method in ("al", "ipopt"):
        ms = run_multistart(problem, method=method, n_starts=n_starts, seed=0, workers=2)
        row[f"{method}_starts_per_s_2w"] = ms.starts_per_second()
        row[f"{method}_best_E"] = ms.best.objective if ms.best.success else math.nan
        row[f"{method}_n_success"] = sum(r.success for r in ms.results)
        row[f"{method}_n_minima"] = len(ms.minima)
        if ms.best.success:
            best = min(best, ms.best.objective)
    row["best_E"] = best if math.isfinite(best) else math.nan
    row["motion_ratio"] = row["best_E"] / e_greedy if greedy_ok else math.nan
    return row


def print_spatial(rows: list[dict[str, Any]]) -> None:
    """Print the spatial table."""
    print("\nspatial cyclic IK paths (issue 14): solve from the greedy start, multistart")
    head = (
        f"{'robot':6} {'s':>3} {'AL ms':>8} {'AL status':>11} {'IPOPT ms':>9} {'IPOPT st':>11} "
        f"{'AL st/s':>8} {'AL ok':>6} {'IP st/s':>8} {'IP ok':>6} {'best E':>10} "
        f"{'greedy E':>10} {'ratio':>6}"
    )
    print(head)
    for r in rows:
        print(
            f"{r['robot']:6} {r['targets']:>3} {r['al_ms']:8.1f} {r['al_status']:>11} "
            f"{r['ipopt_ms']:9.1f} {r['ipopt_status']:>11} {r['al_starts_per_s_2w']:8.2f} "
            f"{r['al_n_success']:>6} {r['ipopt_starts_per_s_2w']:8.2f} {r['ipopt_n_success']:>6} "
            f"{r['best_E']:10.4f} {r['greedy_E']:10.4f}{'' if r['greedy_ok'] else '*'} "
            f"{r['motion_ratio']:6.3f}"
        )
    print("(st/s: starts per second on 2 workers; ok: successful starts; * greedy missed a target)")
    worse = [(r["robot"], r["targets"]) for r in rows if r["motion_ratio"] > 1.0]
    undecided = [(r["robot"], r["targets"]) for r in rows if math.isnan(r["motion_ratio"])]
    print("ours worse than greedy DLS:", worse or "never", "; no ratio:", undecided or "none")


def memory_problem() -> CyclicIKProblem:
    """The cheap planar problem of the memory section (3 distinct minima)."""
    return CyclicIKProblem(robot=PlanarChain(lengths=[1.0, 0.8]), targets=[(1.2, 0.5), (0.3, 1.1)])


def bench_memory_case(n_starts: int, keep: bool) -> dict[str, Any]:
    """One multistart of :func:`memory_problem`: driver peak memory, throughput, resume."""
    problem = memory_problem()
    with tempfile.TemporaryDirectory() as tmp, WorkerPool(2, initializer=tracemalloc.stop) as pool:
        sweep = SweepOptions(executor=pool, out=tmp, keep_results=keep)
        tracemalloc.start()
        tic = time.perf_counter()
        ms = run_multistart(problem, n_starts=n_starts, seed=0, sweep=sweep)
        wall = time.perf_counter() - tic
        held, peak = tracemalloc.get_traced_memory()  # the result is still alive: held
        tracemalloc.stop()
        tic = time.perf_counter()
        best, counts, n_success, minima = ms.best, ms.status_counts(), ms.n_converged, ms.minima
        accessors = time.perf_counter() - tic
        row: dict[str, Any] = {
            "starts": n_starts,
            "keep_results": keep,
            "wall_s": wall,
            "starts_per_s": n_starts / wall,
            "peak_mb": peak / 1e6,
            "held_mb": held / 1e6,
            "accessors_ms": 1e3 * accessors,
            "best_E": best.objective,
            "n_success": n_success,
            "status_counts": counts,
            "minima": [m.count for m in minima],
            "resume_s": None,
        }
        del ms, best, minima
        if not keep:
            tic = time.perf_counter()
            again = run_multistart(problem, n_starts=n_starts, seed=0, sweep=sweep)
            row["resume_s"] = time.perf_counter() - tic
            assert again.resumed == n_starts and again.best.objective == row["best_E"]
    return row


def bench_memory(sizes: list[int], keep_max: int) -> list[dict[str, Any]]:
    """Both modes at each size (``keep_results=True`` only up to ``keep_max`` starts)."""
    rows = []
    for n in sizes:
        for keep in (True, False):
            if keep and n > keep_max:
                continue
            rows.append(bench_memory_case(n, keep))
            print(_memory_line(rows[-1]), flush=True)
    return rows


def _memory_line(r: dict[str, Any]) -> str:
    resume = "-" if r["resume_s"] is None else f"{r['resume_s']:.2f}"
    return (
        f"{r['starts']:>7d} {'True' if r['keep_results'] else 'False':>5s} "
        f"{r['wall_s']:>8.1f} {r['starts_per_s']:>8.1f} {r['peak_mb']:>9.2f} "
        f"{r['held_mb']:>9.2f} {r['accessors_ms']:>9.1f} {resume:>8s}  {r['minima']}"
    )


def print_memory(rows: list[dict[str, Any]]) -> None:
    """Print the memory table, with the peak ratio of the two modes at each size."""
    print("\nplanar IK multistart memory (2 links, 2 targets, AL, pool of 2, driver traced)")
    print("  starts  keep   wall s  starts/s   peak MB   held MB  access ms  resume s  minima")
    for r in rows:
        print(_memory_line(r))
    by = {(r["starts"], r["keep_results"]): r for r in rows}
    for (n, keep), r in by.items():
        lean = by.get((n, False))
        if keep and lean is not None:
            print(
                f"  {n} starts: keep_results=False peak {lean['peak_mb']:.2f} MB vs "
                f"{r['peak_mb']:.2f} MB (x{r['peak_mb'] / lean['peak_mb']:.1f} less), starts/s "
                f"ratio {lean['starts_per_s'] / r['starts_per_s']:.2f}, same best E: "
                f"{lean['best_E'] == r['best_E']}"
            )


def main(argv: list[str] | None = None) -> dict[str, Any]:
    """Run the benchmark and print (or dump as JSON) its report."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 repeats, 8 starts")
    parser.add_argument("--repeats", type=int, default=None, help="single-solve repeats (5)")
    parser.add_argument("--starts", type=int, default=None, help="multistart starts (24)")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    parser.add_argument("--spatial-only", action="store_true", help="only the ur5/panda cases")
    parser.add_argument("--planar-only", action="store_true", help="only the planar cases")
    parser.add_argument(
        "--memory", action="store_true", help="only the keep_results memory section"
    )
    parser.add_argument(
        "--memory-sizes", default="1000,10000", help="starts of the memory section (1000,10000)"
    )
    parser.add_argument(
        "--keep-max",
        type=int,
        default=10000,
        help="largest size also run with keep_results=True (10000)",
    )
    args = parser.parse_args(argv)
    if args.memory:
        sizes = [int(x) for x in args.memory_sizes.split(",")]
        mem: dict[str, Any] = {"cpu_count": os.cpu_count(), "load_average": list(os.getloadavg())}
        mem["memory"] = bench_memory(sizes, args.keep_max)
        mem["load_average_after"] = list(os.getloadavg())
        if args.json:
            print(json.dumps(mem, indent=1))
        else:
            print_memory(mem["memory"])
            print(f"load average before {mem['load_average']}, after {mem['load_average_after']}")
        return mem
    repeats = args.repeats or (3 if args.quick else 5)
    n_starts = args.starts or (8 if args.quick else 24)
    if repeats < 1 or n_starts < 2:
        parser.error("--repeats must be >= 1 and --starts >= 2")
    t0 = time.perf_counter()
    report: dict[str, Any] = {
        "cpu_count": os.cpu_count(),
        "load_average": list(os.getloadavg()),
        "repeats": repeats,
        "starts": n_starts,
    }
    if not args.spatial_only:
        cases = problems()
        report["single"] = {name: bench_single(p, repeats) for name, p in cases.items()}
        report["multistart"] = {
            name: {m: bench_multistart(p, m, n_starts) for m in ("al", "ipopt")}
            for name, p in cases.items()
        }
    if not args.planar_only:
        sizes = (6, 12) if args.quick else (6, 9, 12)
        report["spatial"] = [
            bench_spatial(robot, s, repeats, n_starts) for robot in ("ur5", "panda") for s in sizes
        ]
    report["elapsed"] = time.perf_counter() - t0
    if args.json:
        print(json.dumps(report, indent=1))
    else:
        if "single" in report:
            print_report(report)
        if "spatial" in report:
            print_spatial(report["spatial"])
    return report


if __name__ == "__main__":
    main()
