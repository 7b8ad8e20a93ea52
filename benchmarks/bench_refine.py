"""Mesh refinement (issue 13): histories per robot, and refined against uniform grids.

Run ``python benchmarks/bench_refine.py [--quick] [--robots base,ur5,panda,kinova]
[--figures DIR] [--json FILE]``. Everything is measured in one run:

* **Histories**: :func:`youbot_opt.trajopt.refine.refine` from a coarse uniform
  grid, per round: knots, f, T, the largest relative interval error, the
  certificate's feedback figures and verdict, and the time (build + solve,
  error estimate + certificate). Robots: the study-1 base case (50 knots,
  trapezoidal and Hermite-Simpson), ur5 (the notebook-05 motion), panda and
  kinova (a motion from a quarter of each joint's range below its middle to a
  quarter above, at most 1 rad; kinova's continuous joints are angles), 40
  trapezoidal knots each. kinova's 40-knot grid is exploited (T ~ 28 s).
* **Refined against uniform** (base case, trapezoidal, error tolerance 1e-4):
  the refined plan's knots, time and objective error against the converged
  optimum f* = 8.074944 (Hermite-Simpson, 800 knots, README), and the uniform
  grids' f and time against knots, and the smallest uniform grid reaching the
  refined plan's objective accuracy.

``--figures DIR`` writes the refinement figure of each history
(:func:`youbot_opt.viz.plots.trajopt.plot_refinement`) and the f-against-knots plot.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np

from youbot_opt.dynamics.coordinates import angle_robot
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.robot.model import load_model
from youbot_opt.trajopt.certify import certify
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.refine import RefinementBudget, refine
from youbot_opt.trajopt.solver import TrajOptSolver

F_STAR = 8.074944  # study-1 base case, Hermite-Simpson, 800 knots (README)
UR5 = (np.array([0.0, -1.2, 1.0, -0.5, 0.3, 0.0]), np.array([0.8, -0.6, 0.4, -1.2, -0.3, 0.5]))


def _problem(name: str, knots: int) -> TrajOptProblem:
    if name == "base":
        return study1_problem(knots)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # panda's mimic finger joint is locked (a warning)
        robot = angle_robot(load_model(name))
    if name == "ur5":
        start, goal = UR5
    else:
        lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
        finite = np.isfinite(lo) & np.isfinite(hi) & (hi - lo < 100.0)
        lo, hi = np.where(finite, lo, -1.0), np.where(finite, hi, 1.0)  # continuous: +-1 rad
        mid = np.where(finite, 0.5 * (lo + hi), 0.0)
        half = np.where(finite, np.minimum(0.25 * (hi - lo), 1.0), 1.0)
        start, goal = mid - half, mid + half
    return TrajOptProblem(
        robot=robot, start=BoundaryState(q=start), goal=BoundaryState(q=goal), n_knots=knots
    )


def history(name: str, method: str, knots: int, budget: RefinementBudget) -> dict:
    """Refine one problem; print and return its rounds."""
    tic = time.perf_counter()
    solver = TrajOptSolver(_problem(name, knots), method)
    result = refine(solver, budget=budget)
    total = time.perf_counter() - tic
    record = result.refinement
    print(f"\n{name}, {method}, from {knots} knots ({budget.describe()}): {record.reason}, "
          f"{total:.2f} s in all")  # fmt: skip
    print(f"  {'round':>5} {'knots':>6} {'f':>12} {'T [s]':>9} {'max err':>9} {'fb RMS':>8} "
          f"{'fb peak':>8} {'cert':>5} {'solve s':>8} {'check s':>8}")  # fmt: skip
    for r in record.rounds:
        cert = {True: "pass", False: "fail", None: "-"}[r.certificate_passed]
        print(f"  {r.index:>5} {r.n_knots:>6} {r.objective:>12.6f} {r.duration:>9.4f} "
              f"{r.max_error:>9.3g} {r.feedback_rms:>8.4f} {r.feedback_peak:>8.4f} {cert:>5} "
              f"{r.solve_time:>8.3f} {r.check_time:>8.3f}")  # fmt: skip
    return {"robot": name, "method": method, "result": result, "total_s": total,
            **record.summary()}  # fmt: skip


def refined_vs_uniform(grids: list[int], tolerance: float) -> dict:
    """Base case, trapezoidal: a refined plan at ``tolerance`` against uniform grids."""
    TrajOptSolver(study1_problem(50), "trapezoidal").solve()  # warm-up: kernel cache, imports
    budget = RefinementBudget(
        tolerance=tolerance, max_rounds=12, max_knots=4000, certify_every_round=False
    )
    tic, cpu = time.perf_counter(), time.process_time()
    result = refine(TrajOptSolver(study1_problem(50), "trapezoidal"), budget=budget)
    refined_time = time.perf_counter() - tic
    refined_cpu = time.process_time() - cpu
    refined_err = abs(result.objective - F_STAR)
    rows = []
    for n in grids:
        tic, cpu = time.perf_counter(), time.process_time()
        r = TrajOptSolver(study1_problem(n), "trapezoidal").solve()
        wall, cpu = time.perf_counter() - tic, time.process_time() - cpu
        rows.append((n, r.objective, abs(r.objective - F_STAR), wall, cpu, certify(r).ok))
    print(f"\nbase case, trapezoidal: refined at error tolerance {tolerance:g} against uniform "
          f"grids (f* = {F_STAR})")  # fmt: skip
    print(f"  refined: {result.problem.n_knots} knots, f = {result.objective:.6f}, "
          f"|f - f*| = {refined_err:.2e}, {refined_time:.3f} s wall / {refined_cpu:.3f} s CPU "
          f"(builds, solves, error estimates, final certificate; "
          f"{len(result.refinement.rounds)} rounds), certified: {result.certified}")  # fmt: skip
    print("  refined rounds, f against knots: " + ", ".join(
        f"{r.n_knots}: {r.objective:.6f}" for r in result.refinement.rounds))  # fmt: skip
    print(f"  {'uniform knots':>13} {'f':>12} {'|f - f*|':>10} {'build+solve s':>14} "
          f"{'CPU s':>7} {'certified':>9}")  # fmt: skip
    for n, f, err, wall, cpu, ok in rows:
        print(f"  {n:>13} {f:>12.6f} {err:>10.2e} {wall:>14.3f} {cpu:>7.3f} {ok!s:>9}")
    reaching = [row for row in rows if row[2] <= refined_err]
    if reaching:
        n, f, err, wall, cpu, _ = reaching[0]
        print(f"  smallest uniform grid as accurate: {n} knots, {wall:.3f} s wall / {cpu:.3f} s "
              f"CPU (refined: {result.problem.n_knots} knots, {refined_time:.3f} s wall / "
              f"{refined_cpu:.3f} s CPU)")  # fmt: skip
    else:
        print(f"  no uniform grid up to {grids[-1]} knots is as accurate as the refined plan")
    return {
        "result": result,
        "refined": {"knots": result.problem.n_knots, "f": result.objective,
                    "error": refined_err, "time_s": refined_time, "cpu_s": refined_cpu,
                    "rounds": [(r.n_knots, r.objective) for r in result.refinement.rounds]},
        "uniform": [{"knots": n, "f": f, "error": e, "time_s": w, "cpu_s": c, "certified": ok}
                    for n, f, e, w, c, ok in rows],
    }  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="base case only, fewer grids")
    parser.add_argument("--robots", default="base,ur5,panda,kinova")
    parser.add_argument("--tolerance", type=float, default=1e-3, help="histories' error tolerance")
    parser.add_argument("--figures", type=Path, default=None, metavar="DIR")
    parser.add_argument("--json", type=Path, default=None, metavar="FILE")
    args = parser.parse_args()
    robots = ["base"] if args.quick else args.robots.split(",")
    budget = RefinementBudget(tolerance=args.tolerance, max_rounds=12, max_knots=2000)
    runs = []
    for name in robots:
        methods = ["trapezoidal", "hermite_simpson"] if name == "base" else ["trapezoidal"]
        for method in methods:
            runs.append(history(name, method, 50 if name == "base" else 40, budget))
    grids = [50, 100, 200, 400] if args.quick else [50, 100, 150, 200, 300, 400, 600, 800, 1200]
    versus = refined_vs_uniform(grids, 1e-4)
    if args.figures is not None:
        from matplotlib.figure import Figure

        from youbot_opt.viz.plots.trajopt import plot_refinement

        args.figures.mkdir(parents=True, exist_ok=True)
        for run in runs:
            fig = plot_refinement(run["result"], title=f"{run['robot']}, {run['method']}: "
                                  f"{run['reason']}")  # fmt: skip
            fig.savefig(args.figures / f"refinement_{run['robot']}_{run['method']}.png", dpi=90)
        fig = plot_refinement(versus["result"], title="base case, trapezoidal, tolerance 1e-4")
        fig.savefig(args.figures / "refinement_base_tol1e-4.png", dpi=90)
        fig = Figure(figsize=(6.5, 4.0), layout="constrained")
        ax = fig.subplots()
        uni = versus["uniform"]
        ax.plot([u["knots"] for u in uni], [u["f"] for u in uni], "o-", label="uniform grids")
        ref = versus["refined"]["rounds"]
        ax.plot([k for k, _ in ref], [f for _, f in ref], "s-", label="refinement rounds (1e-4)")
        ax.axhline(F_STAR, color="k", linestyle="--", linewidth=1, label=f"f* = {F_STAR}")
        ax.set_xscale("log")
        ax.set_xlabel("knots")
        ax.set_ylabel("f")
        ax.set_title("study-1 base case, trapezoidal: f against knots")
        ax.legend()
        fig.savefig(args.figures / "refinement_f_vs_knots.png", dpi=90)
    if args.json is not None:
        out = {"histories": [{k: v for k, v in r.items() if k != "result"} for r in runs],
               "versus": {k: v for k, v in versus.items() if k != "result"}}  # fmt: skip
        args.json.write_text(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
