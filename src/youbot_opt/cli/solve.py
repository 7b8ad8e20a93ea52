"""``youbot-opt solve``: one trajectory solve (or a multistart) from the command line.

Exit codes: 0 success, 1 failed solve (the result is still printed and saved),
2 bad input.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from youbot_opt.exceptions import ParameterError

__all__ = ["register", "run_solve", "format_result", "certificate_of"]

_log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``solve`` sub-command."""
    p = sub.add_parser(
        "solve",
        help="optimise a point-to-point trajectory (default: the study-1 youBot problem)",
        description="Solve the time/work trajectory problem f = beta T + (1 - beta) W by "
        "direct collocation with IPOPT.",
    )
    p.add_argument("--robot", default="youbot", help="robot name or URDF path (default: youbot)")
    p.add_argument("--start", type=float, nargs="+", metavar="Q",
                   help="start joint positions [rad] (default for the youBot: the study's)")
    p.add_argument("--goal", type=float, nargs="+", metavar="Q",
                   help="goal joint positions [rad] (default for the youBot: the study's)")
    p.add_argument("--beta", type=float, default=0.5, help="time weight in [0, 1] (default 0.5)")
    p.add_argument("--knots", type=int, default=50, help="number of knots (default 50)")
    p.add_argument("--transcription", choices=("trapezoidal", "hermite-simpson"),
                   default="trapezoidal", help="collocation scheme (default trapezoidal)")
    p.add_argument("--guess", choices=("straight", "spline"), default="straight",
                   help="initial guess: straight line or the study's random feasible spline")
    p.add_argument("--seed", type=int, default=0, help="seed of the spline guess(es) (default 0)")
    p.add_argument("--starts", type=int, default=1,
                   help="number of random starts; > 1 runs a multistart (default 1)")
    p.add_argument("--bound-scale", type=float, default=1.0,
                   help="scale of all bounds, 1.0 = data sheet (default 1.0)")
    p.add_argument("--damping", type=float, default=None,
                   help="youBot joint damping [N m s/rad] (the study's code: 0.1; default 0)")
    p.add_argument("--backend", choices=("symbolic", "pinocchio"), default="symbolic",
                   help="dynamics backend (default symbolic: exact Hessian)")
    p.add_argument("--max-iter", type=int, default=3000, help="IPOPT iteration cap (default 3000)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="directory to save result.npz and summary.json in")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=run_solve)  # fmt: skip


def _problem(args: argparse.Namespace) -> Any:
    from youbot_opt.model import load_model
    from youbot_opt.problem import BoundaryState, TrajOptProblem, study1_problem

    is_youbot = args.robot == "youbot"
    if args.damping is not None and not is_youbot:
        raise ParameterError("--damping applies to the youBot only", name="damping")
    robot = load_model(args.robot, damping=args.damping) if is_youbot else load_model(args.robot)
    if is_youbot and args.start is None and args.goal is None:
        return study1_problem(args.knots, robot=robot, beta=args.beta)
    if args.start is None or args.goal is None:
        raise ParameterError(
            f"--start and --goal (each {robot.nq} joint positions in rad) are required for "
            f"robot {robot.name!r}",
            name="start",
        )
    from youbot_opt.objectives import Objective

    return TrajOptProblem(
        robot=robot,
        start=BoundaryState(q=np.array(args.start)),
        goal=BoundaryState(q=np.array(args.goal)),
        n_knots=args.knots,
        objective=Objective(beta=args.beta),
    )


def certificate_of(result: Any) -> Any:
    """The :func:`youbot_opt.verify.certify` certificate of ``result``, or None if unavailable."""
    if result.trajectory is None:
        return None
    try:
        from youbot_opt.verify import certify
    except ImportError:  # pragma: no cover - verify is part of the package
        return None
    return certify(result)


def format_result(result: Any, certificate: Any = None, *, max_active: int = 12) -> str:
    """Readable multi-line summary of a result (and its certificate)."""
    s = result.summary()
    lines = [
        f"{s['robot']}: {s['n_knots']} knots, {s['method']}, backend {s['backend']}, "
        f"beta = {s['beta']:g}, bound scale = {s['bound_scale']:g}",
        f"status        {s['status']} ({result.message})",
        f"objective f   {result.objective:.6f}   (beta T + (1 - beta) W)",
        f"duration T    {result.duration:.5f} s   (dt = {result.dt:.6f} s)",
        f"work W        {result.work:.5f} N^2 m^2 s",
        f"iterations    {result.iterations}",
        f"solve time    {result.wall_time:.4f} s wall, {result.cpu_time:.4f} s CPU",
        f"max violation {result.max_violation:.2e}",
    ]
    if certificate is not None:
        lines += ["", str(certificate)]
    active = result.active_bounds(1e-6) if result.trajectory is not None else []
    lines += ["", f"active bounds (within 1e-6): {len(active)}"]
    if active:
        lines.append(f"  {'bound':<16}{'knot':>5}{'joint':>6}{'value':>13}{'multiplier':>13}")
        for row in active[:max_active]:
            lines.append(
                f"  {row.name:<16}{row.knot:>5}{row.joint:>6}{row.value:>13.6f}"
                f"{row.multiplier:>13.4e}"
            )
        if len(active) > max_active:
            lines.append(f"  ... {len(active) - max_active} more")
    return "\n".join(lines)


def _json_ready(obj: Any) -> Any:
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _json_ready(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_json_ready(v) for v in obj]
    return obj


def run_solve(args: argparse.Namespace) -> int:
    """Run ``youbot-opt solve``; returns the exit code (0 ok, 1 failed solve, 2 bad input)."""
    from youbot_opt.options import IpoptOptions
    from youbot_opt.solve import TrajOptSolver

    if args.starts < 1:
        raise ParameterError(f"--starts must be >= 1, got {args.starts}", name="starts")
    problem = _problem(args)
    method = args.transcription.replace("-", "_")
    options = IpoptOptions(max_iter=args.max_iter)
    solver = TrajOptSolver(problem, method, options, args.backend)
    extra: dict[str, Any] = {"build_time_s": solver.build_time}
    if args.starts > 1:
        try:
            from youbot_opt.multistart import run_multistart
        except ImportError as exc:  # pragma: no cover - depends on the installed modules
            raise ParameterError(
                "--starts > 1 needs youbot_opt.multistart, which is not available", name="starts"
            ) from exc
        ms = run_multistart(
            solver, args.starts, beta=args.beta, bound_scale=args.bound_scale, seed=args.seed,
            include_straight=args.guess == "straight", executor="serial",
        )  # fmt: skip
        best = ms.best
        if best is None or best.result is None:
            print("youbot-opt: no start converged", file=sys.stderr)
            return 1
        result = best.result
        extra["multistart"] = {"n_starts": ms.n_starts, "success_rate": ms.success_rate}
    else:
        guess = None
        if args.guess == "spline":
            from youbot_opt.spline_guess import random_spline_guess

            guess = random_spline_guess(
                problem.robot, problem.start, problem.goal, problem.n_knots, seed=args.seed,
                bounds=problem.bounds(args.bound_scale), damping=problem.damping,
            )  # fmt: skip
        result = solver.solve(
            beta=args.beta, bound_scale=args.bound_scale, guess=guess,
            seed=args.seed if args.guess == "spline" else None,
        )  # fmt: skip
    certificate = certificate_of(result)
    summary = {**result.summary(), **extra}
    if certificate is not None:
        summary["certificate"] = certificate.summary()
    if args.out is not None:
        from youbot_opt.io import save_result

        args.out.mkdir(parents=True, exist_ok=True)
        summary["result_file"] = str(save_result(result, args.out / "result.npz"))
        (args.out / "summary.json").write_text(json.dumps(_json_ready(summary), indent=2) + "\n")
    if args.json:
        print(json.dumps(_json_ready(summary)))
    else:
        print(format_result(result, certificate))
        if args.out is not None:
            print(f"\nsaved {summary['result_file']}")
    return 0 if result.success else 1
