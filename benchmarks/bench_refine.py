"""Mesh refinement (issue 13): histories per robot, and refined against uniform grids.

Run ``python benchmarks/bench_refine.py [--quick] [--robots base,ur5,panda,kinova]
[--repeats 5] [--figures DIR] [--json FILE]``. Everything is measured in one run:

* **Histories**: :func:`youbot_opt.trajopt.refine.refine` from a coarse uniform
  grid, per round: knots, f, T, the largest relative interval error, the
  certificate's feedback figures and verdict, and the time (build + solve, error
  estimate + certificate), every round certified, and the refinement's time with
  the default decision (the simulation only where the errors pass and on the
  last round; issue 27), from the same first solve. Robots: the study-1 base
  case (50 knots, trapezoidal and Hermite-Simpson), ur5 (the notebook-05
  motion), panda and kinova (a motion from a quarter of each joint's range below
  its middle to a quarter above, at most 1 rad; kinova's continuous joints are
  angles), 40 trapezoidal knots each. kinova's 40-knot grid is exploited (T ~
  28 s).
* **Refined against uniform** (base case, trapezoidal, error tolerance 1e-4):
  the refined plan's knots, CPU time (every round's build, solve and error
  estimate, and the certificate) and objective error against the converged
  optimum f* = 8.074944 (Hermite-Simpson, 800 knots, README), against the
  uniform grids' f and CPU time (build + solve, and their certificates
  apart), alternating runs, medians of ``--repeats``; and the smallest uniform
  grid reaching the refined plan's objective accuracy, with the ratios.

``--figures DIR`` (``docs/img`` for the docs) writes the refinement figure of
each history (:func:`youbot_opt.viz.plots.trajopt.plot_refinement`) and
``refinement_f_vs_knots.png`` (f against knots, |f - f*| against CPU time).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import time
import warnings
from pathlib import Path

import numpy as np

from youbot_opt.dynamics.coordinates import angle_robot
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.robot.load import load_model
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
    first = solver.solve()
    result = refine(solver, first=first, budget=budget)
    total = time.perf_counter() - tic
    record = result.refinement
    # the default decision: the simulation only where the errors pass, and on the last round
    cheap_budget = dataclasses.replace(budget, certify_every_round=False)
    cheap_tic = time.perf_counter()
    cheap = refine(solver, first=first, budget=cheap_budget)
    cheap_s = time.perf_counter() - cheap_tic
    same = [r.n_knots for r in cheap.refinement.rounds] == [r.n_knots for r in record.rounds]
    print(f"\n{name}, {method}, from {knots} knots ({budget.describe()}): {record.reason}, "
          f"{total:.2f} s in all; refinement {record.elapsed:.2f} s certifying every round, "
          f"{cheap_s:.2f} s certifying where the errors pass ({'same' if same else 'OTHER'} "
          f"rounds)")  # fmt: skip
    print(f"  {'round':>5} {'knots':>6} {'f':>12} {'T [s]':>9} {'max err':>9} {'fb RMS':>8} "
          f"{'fb peak':>8} {'cert':>5} {'solve s':>8} {'check s':>8}")  # fmt: skip
    for r in record.rounds:
        cert = {True: "pass", False: "fail", None: "-"}[r.certificate_passed]
        print(f"  {r.index:>5} {r.n_knots:>6} {r.objective:>12.6f} {r.duration:>9.4f} "
              f"{r.max_error:>9.3g} {r.feedback_rms:>8.4f} {r.feedback_peak:>8.4f} {cert:>5} "
              f"{r.solve_time:>8.3f} {r.check_time:>8.3f}")  # fmt: skip
    return {"robot": name, "method": method, "result": result, "total_s": total,
            "cheap_refinement_s": cheap_s, **record.summary()}  # fmt: skip


def _cpu(fn):  # type: ignore[no-untyped-def]
    """Run ``fn()``; return its value, CPU and wall time [s]."""
    tic, cpu = time.perf_counter(), time.process_time()
    value = fn()
    return value, time.process_time() - cpu, time.perf_counter() - tic


def refined_vs_uniform(grids: list[int], tolerance: float, repeats: int) -> dict:
    """Base case, trapezoidal: a refined plan at ``tolerance`` against uniform grids.

    Alternating runs (refine, then every uniform grid, the grid order reversed
    every other repeat), ``repeats`` of each, medians. Each run builds its
    solver from scratch (dynamics, kernels from the disk cache, NLP, IPOPT):
    what a user's ``refine(TrajOptSolver(problem))`` or
    ``TrajOptSolver(problem).solve()`` costs. The refined time includes every
    round's build, solve and error estimate and the final certificate; the
    uniform grids' certificates are timed separately.
    """
    TrajOptSolver(study1_problem(50), "trapezoidal").solve()  # warm-up: kernel cache, imports
    budget = RefinementBudget(
        tolerance=tolerance, max_rounds=12, max_knots=4000, certify_every_round=False
    )
    refined_cpu, refined_wall = [], []
    uni = {n: {"cpu": [], "wall": [], "cert_cpu": []} for n in grids}
    result = uniform = None
    uniforms = {}
    for rep in range(repeats):
        result, cpu, wall = _cpu(
            lambda: refine(TrajOptSolver(study1_problem(50), "trapezoidal"), budget=budget)
        )
        refined_cpu.append(cpu)
        refined_wall.append(wall)
        for n in grids if rep % 2 == 0 else grids[::-1]:
            uniform, cpu, wall = _cpu(lambda n=n: TrajOptSolver(study1_problem(n)).solve())
            uni[n]["cpu"].append(cpu)
            uni[n]["wall"].append(wall)
            cert, cpu, _ = _cpu(lambda u=uniform: certify(u))
            uni[n]["cert_cpu"].append(cpu)
            uniforms[n] = (uniform, cert.ok)
    assert result is not None
    med = statistics.median
    refined = {
        "knots": result.result.problem.n_knots,
        "f": result.result.objective,
        "error": abs(result.result.objective - F_STAR),
        "cpu_s": med(refined_cpu),
        "wall_s": med(refined_wall),
        "certified": result.certified,
        "rounds": [(r.n_knots, r.objective) for r in result.refinement.rounds],
    }
    rows = [
        {
            "knots": n,
            "f": uniforms[n][0].objective,
            "error": abs(uniforms[n][0].objective - F_STAR),
            "cpu_s": med(uni[n]["cpu"]),
            "wall_s": med(uni[n]["wall"]),
            "certify_cpu_s": med(uni[n]["cert_cpu"]),
            "certified": uniforms[n][1],
        }
        for n in grids
    ]
    print(f"\nbase case, trapezoidal: refined at error tolerance {tolerance:g} against uniform "
          f"grids (f* = {F_STAR}); medians of {repeats} alternating runs, CPU time")  # fmt: skip
    rounds = ", ".join(f"{k}: {f:.6f}" for k, f in refined["rounds"])
    print(f"  refined: {refined['knots']} knots, f = {refined['f']:.6f}, |f - f*| = "
          f"{refined['error']:.2e}, {refined['cpu_s']:.3f} s CPU / {refined['wall_s']:.3f} s wall "
          f"(every build, solve, error estimate and the final certificate), "
          f"certified: {refined['certified']}")  # fmt: skip
    print(f"  refined rounds, f against knots: {rounds}")
    print(f"  {'uniform knots':>13} {'f':>12} {'|f - f*|':>10} {'CPU s':>7} {'wall s':>7} "
          f"{'+cert CPU s':>11} {'certified':>9}")  # fmt: skip
    for u in rows:
        print(f"  {u['knots']:>13} {u['f']:>12.6f} {u['error']:>10.2e} {u['cpu_s']:>7.3f} "
              f"{u['wall_s']:>7.3f} {u['certify_cpu_s']:>11.3f} {u['certified']!s:>9}")  # fmt: skip
    reaching = [u for u in rows if u["error"] <= refined["error"]]
    versus: dict = {"result": result, "refined": refined, "uniform": rows, "equal": None}
    if reaching:
        u = reaching[0]
        versus["equal"] = u
        print(f"  smallest uniform grid as accurate: {u['knots']} knots, {u['cpu_s']:.3f} s CPU "
              f"({u['cpu_s'] + u['certify_cpu_s']:.3f} s with its certificate); refined: "
              f"{refined['knots']} knots, {refined['cpu_s']:.3f} s CPU -> uniform / refined = "
              f"{u['knots'] / refined['knots']:.2f}x knots, {u['cpu_s'] / refined['cpu_s']:.2f}x "
              f"CPU ({(u['cpu_s'] + u['certify_cpu_s']) / refined['cpu_s']:.2f}x with "
              f"certificates)")  # fmt: skip
    else:
        print(f"  no uniform grid up to {grids[-1]} knots is as accurate as the refined plan")
    return versus


def plot_versus(versus: dict, path: Path) -> None:
    """f against knots, and |f - f*| against CPU time, for the refined rounds and uniform grids."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10.0, 4.0), layout="constrained")
    ax, bx = fig.subplots(1, 2)
    uni, ref = versus["uniform"], versus["refined"]
    ax.loglog([u["knots"] for u in uni], [u["error"] for u in uni], "o-", label="uniform grids")
    ax.loglog([k for k, _ in ref["rounds"]], [abs(f - F_STAR) for _, f in ref["rounds"]], "s-",
              label="refinement rounds (tolerance 1e-4)")  # fmt: skip
    ax.set_xlabel("knots")
    ax.set_ylabel(f"|f - f*|  (f* = {F_STAR})")
    ax.set_title("study-1 base case, trapezoidal: f against knots")
    ax.legend()
    bx.loglog([u["cpu_s"] for u in uni], [u["error"] for u in uni], "o-", label="uniform grids")
    for u in uni:
        bx.annotate(str(u["knots"]), (u["cpu_s"], u["error"]), fontsize=7,
                    textcoords="offset points", xytext=(3, 3))  # fmt: skip
    bx.loglog([ref["cpu_s"]], [ref["error"]], "s", markersize=8,
              label=f"refined, certified ({ref['knots']} knots)")  # fmt: skip
    bx.set_xlabel("CPU time [s], median")
    bx.set_ylabel("|f - f*|")
    bx.set_title("against time (uniform: build + solve; refined: all + certificate)", fontsize=9)
    bx.legend()
    fig.savefig(path, dpi=90)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="base case only, fewer grids")
    parser.add_argument("--robots", default="base,ur5,panda,kinova")
    parser.add_argument("--tolerance", type=float, default=1e-3, help="histories' error tolerance")
    parser.add_argument("--figures", type=Path, default=None, metavar="DIR")
    parser.add_argument("--json", type=Path, default=None, metavar="FILE")
    parser.add_argument("--repeats", type=int, default=5, help="alternating runs (medians)")
    args = parser.parse_args()
    robots = ["base"] if args.quick else [r for r in args.robots.split(",") if r]
    budget = RefinementBudget(  # every round certified: the histories' figures
        tolerance=args.tolerance, max_rounds=12, max_knots=2000, certify_every_round=True
    )
    runs = []
    for name in robots:
        methods = ["trapezoidal", "hermite_simpson"] if name == "base" else ["trapezoidal"]
        for method in methods:
            runs.append(history(name, method, 50 if name == "base" else 40, budget))
    grids = (
        [50, 200, 400, 500, 600, 700]
        if args.quick
        else [50, 100, 200, 300, 400, 450, 500, 550, 600, 700, 800, 1200]
    )
    versus = refined_vs_uniform(grids, 1e-4, args.repeats)
    if args.figures is not None:
        from youbot_opt.viz.plots.trajopt import plot_refinement

        args.figures.mkdir(parents=True, exist_ok=True)
        for run in runs:
            fig = plot_refinement(run["result"], title=f"{run['robot']}, {run['method']}: "
                                  f"{run['reason']}")  # fmt: skip
            fig.savefig(args.figures / f"refinement_{run['robot']}_{run['method']}.png", dpi=90)
        fig = plot_refinement(versus["result"], title="base case, trapezoidal, tolerance 1e-4")
        fig.savefig(args.figures / "refinement_base_tol1e-4.png", dpi=90)
        plot_versus(versus, args.figures / "refinement_f_vs_knots.png")
    if args.json is not None:
        out = {"histories": [{k: v for k, v in r.items() if k != "result"} for r in runs],
               "versus": {k: v for k, v in versus.items() if k != "result"}}  # fmt: skip
        args.json.write_text(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
