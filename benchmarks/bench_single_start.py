"""A single start's solve: cheaper, or a better optimum? (issue 27, what is left).

Run ``python benchmarks/bench_single_start.py [--robots ur5 panda] [--pairs 20]
[--seed 7] [--knots 50] [--method radau] [--strategies direct coarse:12 screen:4:12
ipopt:perturb_dec_fact=0.1 ...]``.

One start (the straight line, as ``youbot-opt solve`` runs by default) stops at
a local optimum after as many iterations as that optimum takes; the benchmark
pair of ``bench_wait.py`` on panda takes 118 IPOPT iterations to f = 522.2
where other starts reach 368.7. This script measures strategies on random
start-goal pairs (each joint's start and goal uniform in 20-80 % of its range,
``numpy.random.default_rng(seed)``; ``--pairs 0``: the pair of ``bench_wait.py``'s
panda and xarm7 cases, 35 % and 65 % of each joint's range),
compiled kernels, beta = 0.5, against the direct solve in the same run:

* ``direct``: the default, the straight line on the full grid;
* ``coarse:N``: the straight line on ``N`` knots first, then the full grid from
  that plan, primal and dual (``refine.transfer_start``, as a refinement round
  starts), cold from its trajectory if that warm start fails;
* ``screen:K:N``: ``K`` starts on ``N`` knots (the straight line and ``K - 1``
  random spline guesses, seeds 1..K-1), the full grid from the best of them;
* ``ipopt:NAME=VALUE[,NAME=VALUE]``: the direct solve with extra IPOPT options
  (``IpoptOptions(extra=...)``; values parsed as JSON, else strings).

Printed per strategy: successes, IPOPT iterations and CPU time [s] summed over
the pairs, and its objective against the direct one: pairs better and worse
by more than 1e-4 relative, and the geometric mean of the ratio (< 1: better).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_wait import start_goal  # noqa: E402 - the wait's pair (panda's, xarm7's)

from youbot_opt.nlp.ipopt import IpoptOptions  # noqa: E402
from youbot_opt.robot.load import load_model  # noqa: E402
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem  # noqa: E402
from youbot_opt.trajopt.refine import transfer_start  # noqa: E402
from youbot_opt.trajopt.result import TrajOptResult  # noqa: E402
from youbot_opt.trajopt.solver import TrajOptSolver  # noqa: E402
from youbot_opt.trajopt.spline_guess import random_spline_guess  # noqa: E402

LOCKS = {"panda": {"panda_finger_joint1": 0.02}}
"""Joints locked per robot (the fingers, as ``bench_wait.py``)."""

Outcome = tuple[bool, int, float, float]
"""(success, IPOPT iterations, CPU time [s], objective)."""


def _pairs(robot_name: str, n_pairs: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    robot = load_model(robot_name, lock_joints=LOCKS.get(robot_name))
    if n_pairs == 0:
        start, goal = start_goal(robot_name)
        return [(np.asarray(start, dtype=float), np.asarray(goal, dtype=float))]
    lo, hi = robot.q_lower, robot.q_upper
    rng = np.random.default_rng(seed)
    draws = [lo + (hi - lo) * rng.uniform(0.2, 0.8, lo.size) for _ in range(2 * n_pairs)]
    return list(zip(draws[0::2], draws[1::2], strict=True))


def _fine_from(
    coarse: TrajOptResult, solver: TrajOptSolver, n_knots: int
) -> tuple[TrajOptResult, int]:
    """Solve on ``n_knots`` uniform knots from a coarse plan: the result, its iterations."""
    assert coarse.trajectory is not None
    fine = solver.on_grid(np.ones(n_knots - 1))
    t_new = fine.method.solution_times(coarse.duration / (n_knots - 1), n_knots)
    mids = 0.5 * (t_new[1:] + t_new[:-1])
    t_old = coarse.trajectory.t
    parent = np.clip(np.searchsorted(t_old[1:], mids), 0, t_old.size - 2).astype(np.intp)
    result = fine.solve(
        beta=0.5, guess=coarse.trajectory, initial=transfer_start(coarse, fine, parent, t_new)
    )
    iterations = result.iterations
    if not result.success:  # as a refinement round: cold from the same trajectory
        result = fine.solve(beta=0.5, guess=coarse.trajectory, warm_start=False)
        iterations += result.iterations
    return result, iterations


def _strategy(spec: str, method: str) -> Callable[[TrajOptProblem], tuple[TrajOptResult, int]]:
    """Return a function solving a problem by strategy ``spec`` (result, total iterations)."""
    kind, _, rest = spec.partition(":")
    if kind == "direct":

        def direct(problem: TrajOptProblem) -> tuple[TrajOptResult, int]:
            result = TrajOptSolver(problem, method, compile="wait").solve(beta=0.5)
            return result, result.iterations

        return direct
    if kind == "ipopt":
        extra: dict[str, object] = {}
        for item in rest.split(","):
            name, _, text = item.partition("=")
            try:
                extra[name] = json.loads(text)
            except json.JSONDecodeError:
                extra[name] = text
        options = IpoptOptions(extra=extra)  # type: ignore[arg-type]

        def tuned(problem: TrajOptProblem) -> tuple[TrajOptResult, int]:
            result = TrajOptSolver(problem, method, options=options, compile="wait").solve(beta=0.5)
            return result, result.iterations

        return tuned
    if kind in ("coarse", "screen"):
        numbers = [int(x) for x in rest.split(":")]
        starts, coarse_knots = (1, numbers[0]) if kind == "coarse" else (numbers[0], numbers[1])

        def screened(problem: TrajOptProblem) -> tuple[TrajOptResult, int]:
            small = dataclasses.replace(problem, n_knots=coarse_knots)
            solver = TrajOptSolver(small, method, compile="wait")
            best, iterations = None, 0
            for k in range(starts):
                guess = None
                if k:
                    guess = random_spline_guess(
                        problem.robot, problem.start, problem.goal, coarse_knots, seed=k,
                        dt=4.9 / (coarse_knots - 1),
                    )  # fmt: skip
                result = solver.solve(beta=0.5, guess=guess)
                iterations += result.iterations
                if result.success and (best is None or result.objective < best.objective):
                    best = result
            if best is None:
                return result, iterations
            fine, more = _fine_from(best, solver, problem.n_knots)
            return fine, iterations + more

        return screened
    raise SystemExit(f"unknown strategy {spec!r} (direct, coarse:N, screen:K:N, ipopt:NAME=VALUE)")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=["ur5", "panda"])
    parser.add_argument("--pairs", type=int, default=20, help="random pairs (0: the wait's pair)")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--knots", type=int, default=50)
    parser.add_argument("--method", default="radau")
    parser.add_argument(
        "--strategies", nargs="+", default=["direct", "coarse:12", "coarse:25", "screen:4:12"]
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore")  # the solver's notes on every pair
    specs = ["direct", *[s for s in args.strategies if s != "direct"]]
    for name in args.robots:
        robot = load_model(name, lock_joints=LOCKS.get(name))
        outcomes: dict[str, list[Outcome]] = {s: [] for s in specs}
        for q0, q1 in _pairs(name, args.pairs, args.seed):
            problem = TrajOptProblem(
                robot=robot, start=BoundaryState(q=q0), goal=BoundaryState(q=q1), n_knots=args.knots
            )
            for spec in specs:
                tic = time.process_time()
                result, iterations = _strategy(spec, args.method)(problem)
                cpu = time.process_time() - tic
                outcomes[spec].append((result.success, iterations, cpu, result.objective))
        base = outcomes["direct"]
        print(f"\n{name}: {len(base)} pair(s), {args.knots} knots, {args.method}, beta 0.5")
        head = ("solved", "its", "CPU [s]", "better", "worse", "gm f")
        print(f"{'strategy':32s} " + " ".join(f"{h:>7s}" for h in head))
        for spec, rows in outcomes.items():
            both = [(b[3], x[3]) for b, x in zip(base, rows, strict=True) if b[0] and x[0]]
            better = sum(x < b * (1 - 1e-4) for b, x in both)
            worse = sum(x > b * (1 + 1e-4) for b, x in both)
            gm = math.exp(float(np.mean([math.log(x / b) for b, x in both]))) if both else math.nan
            print(
                f"{spec:32s} {sum(r[0] for r in rows):3d}/{len(rows):<3d} "
                f"{sum(r[1] for r in rows):7d} {sum(r[2] for r in rows):7.2f} "
                f"{better:7d} {worse:7d} {gm:7.4f}",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
