"""``youbot-opt main`` (and plain ``youbot-opt``): the README's main job.

Solves the study-1 base case -- the planar youBot from (-pi/6, -pi/6, -pi/3)
to (pi/6, pi/6, pi/3) at rest, beta = 0.5, 50 knots, trapezoidal collocation,
straight-line initial guess -- certifies the result by forward simulation
(:func:`youbot_opt.trajopt.certify.certify`) and prints a readable summary: objective,
duration, work, iterations, solve time, certificate figures and the active
bounds. It writes the run's output folder as ``youbot-opt solve`` does
(``summary.json``, ``result.npz``, figures, ``replay.html``) and prints where
it is. Exit code 0 if the solve succeeded, 1 otherwise, 2 on bad input.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from youbot_opt._version import __version__


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``main`` sub-command."""
    p = sub.add_parser("main", help="run the main job (the study-1 base case)")
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="DIR",
        help="output folder (default: a new youbot_opt_runs/main-<date>-<time>)",
    )
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from youbot_opt.cli.solve import (
        certificate_of,
        format_result,
        open_folder,
        report_outputs,
        write_solve_outputs,
    )
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.solver import TrajOptSolver

    tic = time.perf_counter()
    print(f"youbot_opt {__version__}: study-1 base case (beta = 0.5, 50 knots, trapezoidal, "
          "straight-line start)\n")  # fmt: skip
    solver = TrajOptSolver(study1_problem(50, beta=0.5), "trapezoidal")
    result = solver.solve(beta=0.5)
    nlp = solver.nlp
    print(f"NLP build     {solver.build_time:.3f} s "
          f"({nlp.n_variables} variables, {nlp.n_equalities} equalities)")  # fmt: skip
    certificate = certificate_of(result)
    print(format_result(result, certificate))
    if result.success and certificate is not None and not certificate.passed():
        print("\nnote: IPOPT solved the NLP, but the arm cannot follow this plan within the "
              "certificate's tolerances:\n      the 50-knot trapezoidal transcription is too "
              "coarse here. `youbot-opt solve --knots 100`\n      or `youbot-opt solve "
              "--transcription hermite-simpson` gives plans that pass.")  # fmt: skip
    summary = {**result.summary(), "build_time_s": solver.build_time}
    if certificate is not None:
        summary["certificate"] = certificate.summary()
    summary["active_bounds"] = (
        len(result.active_bounds(1e-6)) if result.trajectory is not None else 0
    )
    folder = open_folder("main", args.out)
    files = write_solve_outputs(folder, result, summary)
    print()
    report_outputs(folder, files, as_json=False)
    print(f"main job done in {time.perf_counter() - tic:.2f} s")
    return 0 if result.success else 1
