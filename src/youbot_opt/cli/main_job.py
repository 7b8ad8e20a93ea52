"""``youbot-opt main`` (and plain ``youbot-opt``): the README's main job.

Solves the study-1 base case -- the planar youBot from (-pi/6, -pi/6, -pi/3)
to (pi/6, pi/6, pi/3) at rest, beta = 0.5, 50 knots, trapezoidal collocation,
straight-line initial guess -- certifies the result by forward simulation
(:func:`youbot_opt.verify.certify`) and prints a readable summary: objective,
duration, work, iterations, solve time, certificate figures and the active
bounds. Exit code 0 if the solve succeeded, 1 otherwise.
"""

from __future__ import annotations

import argparse

from youbot_opt import __version__


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``main`` sub-command."""
    p = sub.add_parser("main", help="run the main job (the study-1 base case)")
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from youbot_opt.cli.solve import certificate_of, format_result
    from youbot_opt.problem import study1_problem
    from youbot_opt.solve import TrajOptSolver

    print(f"youbot_opt {__version__}: study-1 base case (beta = 0.5, 50 knots, trapezoidal, "
          "straight-line start)\n")  # fmt: skip
    solver = TrajOptSolver(study1_problem(50, beta=0.5), "trapezoidal")
    result = solver.solve(beta=0.5)
    print(f"NLP build     {solver.build_time:.3f} s "
          f"({solver.nlp.n_variables} variables, {solver.nlp.n_constraints} equalities)")  # fmt: skip
    print(format_result(result, certificate_of(result)))
    return 0 if result.success else 1
