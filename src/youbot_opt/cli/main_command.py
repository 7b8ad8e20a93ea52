"""``youbot-opt main`` (and plain ``youbot-opt``): the README's main job.

Solves the study-1 base case -- the planar youBot from (-pi/6, -pi/6, -pi/3)
to (pi/6, pi/6, pi/3) at rest, beta = 0.5, trapezoidal collocation,
straight-line initial guess -- on 50 uniform knots, then refines the grid
(:func:`youbot_opt.trajopt.refine.refine`) until every interval's collocation
error is within tolerance and the plan passes its forward-simulation
certificate (``--no-refine``: the fixed 50-knot grid). It prints a readable
summary: objective, duration, work, iterations, solve time, the refinement
rounds, certificate figures and the active bounds, and writes the run's output
folder as ``youbot-opt solve`` does. Exit code 0 if the solve succeeded (and,
when refining, the plan is certified), 1 otherwise, 2 on bad input.
"""

from __future__ import annotations

import argparse
import time

from youbot_opt._typing import JSONDict
from youbot_opt._version import __version__
from youbot_opt.cli.drawing import DrawingAhead
from youbot_opt.cli.output import (
    open_folder,
    report_outputs,
    solve_drawing_ahead,
    write_solve_outputs,
)
from youbot_opt.cli.refinement import refine_result
from youbot_opt.cli.trajopt_text import certificate_of, format_result
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.trajopt.problem import TrajOptProblem
from youbot_opt.trajopt.solver import TrajOptSolver

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    """Run ``youbot-opt main``; returns the exit code (0 certified, 1 not, 2 bad input)."""
    tic = time.perf_counter()
    grid = "refined from 50 knots" if args.refine else "50 fixed knots"
    print(f"youbot_opt {__version__}: study-1 base case (beta = 0.5, {grid}, trapezoidal, "
          "straight-line start)\n")  # fmt: skip
    problem = study1_problem(50)
    ahead = solve_drawing_ahead(problem, figures=not args.no_figures)
    try:
        return _main_job(args, problem, ahead, tic)
    finally:
        ahead.stop()  # when no output was drawn (handed over, it is the drawing's)


def _main_job(
    args: argparse.Namespace, problem: TrajOptProblem, ahead: DrawingAhead, tic: float
) -> int:
    """Solve, refine, print and write the run folder (``ahead`` draws its figures and replay)."""
    solver = TrajOptSolver(problem, "trapezoidal")
    result = solver.solve(beta=0.5)
    nlp = solver.nlp
    print(f"NLP build     {solver.build_time:.3f} s "
          f"({nlp.n_variables} variables, {nlp.n_equalities} equalities, 50 knots)")  # fmt: skip
    refined = refine_result(solver, result, args)
    record = None
    if refined is not None:
        result, record = refined
    certificate = certificate_of(result, record)
    print(format_result(result, certificate, refinement=record))
    if result.success and certificate is not None and not certificate.passed():
        print("\nnote: IPOPT solved the NLP, but the arm cannot follow this plan within the "
              "certificate's tolerances:\n      the fixed 50-knot trapezoidal grid is too "
              "coarse here. Without --no-refine the grid\n      is refined until the plan "
              "passes.")  # fmt: skip
    summary: JSONDict = {
        **(result.summary() if refined is None else refined.summary()),
        "build_time_s": solver.build_time,
    }
    if certificate is not None:
        summary["certificate"] = certificate.summary()
    summary["active_bounds"] = (
        len(result.active_bounds(1e-6)) if result.trajectory is not None else 0
    )
    folder = open_folder("main", args.out)
    files = write_solve_outputs(
        folder, result, summary, refinement=record, figures=not args.no_figures, ahead=ahead
    )
    print()
    report_outputs(folder, files, as_json=False)
    print(f"main job done in {time.perf_counter() - tic:.2f} s")
    return 0 if result.success and (record is None or record.certified) else 1
