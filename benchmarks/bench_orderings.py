"""MUMPS orderings and the default guess on larger arms: time per IPOPT iteration, optima.

Run ``python benchmarks/bench_orderings.py [--pairs N] [--robots ur5 panda]
[--schemes radau hermite_simpson trapezoidal] [--guesses] [--json]``.

* Orderings (issue 27): for each robot and scheme, ``--pairs`` random in-limit
  start/goal pairs (20-80 % of each joint's range, seeded), each solved from the
  default guess (beta 0.5, 50 knots) by one solver per MUMPS ordering in turn
  (AMD, AMF, PORD: IPOPT's ``mumps_pivot_order`` 0, 2, 4, set through
  ``IpoptOptions.extra``), so that the machine's drift falls on all three alike.
  Prints the iterations, the time of ``solve()`` [s], the time per iteration
  [ms] and its ratio against AMD, and how many pairs reached the same
  objective as AMD (1e-4 relative). The scheme's own choice
  (``Transcription.mumps_pivot_order``) is marked.
* ``--guesses``: the same pairs (Radau) from the default guess (the straight
  line at constant speed over 4.9 s) and from the straight line timed by a cubic
  that meets the boundary velocities, over the duration that minimises the
  guess's own objective within the velocity and torque bounds: iterations,
  time, and in how many pairs each reached the better optimum. Measured, not
  a default (docs/design.md).

Panda has its fingers locked. Compiled kernels are used when cached (a first
run compiles them in the background and measures CasADi's virtual machine:
run twice).
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from typing import Any

import numpy as np

from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.robot.load import load_model
from youbot_opt.trajopt.guess import inverse_dynamics
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.trajectory import Trajectory
from youbot_opt.trajopt.transcription import get_transcription

ORDERINGS = {0: "AMD", 2: "AMF", 4: "PORD"}
SAME = 1e-4  # relative objective difference counted as the same optimum
BETA = 0.5


def _problems(name: str, pairs: int, seed: int) -> list[TrajOptProblem]:
    locks = {"panda_finger_joint1": 0.02} if name == "panda" else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = load_model(name, lock_joints=locks)
    lo = np.maximum(robot.model.lowerPositionLimit, -2 * np.pi)
    hi = np.minimum(robot.model.upperPositionLimit, 2 * np.pi)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(pairs):
        a, b = (lo + (0.2 + 0.6 * rng.random(lo.size)) * (hi - lo) for _ in range(2))
        out.append(TrajOptProblem(robot=robot, start=BoundaryState(q=a), goal=BoundaryState(q=b)))
    return out


def _solve(solver: TrajOptSolver, problem: TrajOptProblem, guess: Any = None) -> tuple[Any, float]:
    tic = time.perf_counter()
    result = solver.solve(beta=BETA, start=problem.start, goal=problem.goal, guess=guess)
    return result, time.perf_counter() - tic


def orderings(name: str, scheme: str, problems: list[TrajOptProblem]) -> dict[str, Any]:
    """Solve every pair with each ordering in turn; totals per ordering."""
    solvers = {
        k: TrajOptSolver(problems[0], scheme, IpoptOptions(extra={"mumps_pivot_order": k}))
        for k in ORDERINGS
    }
    totals = {k: {"iterations": 0, "time_s": 0.0, "same_f": 0} for k in ORDERINGS}
    for problem in problems:
        results = {k: _solve(solvers[k], problem) for k in ORDERINGS}
        f_amd = results[0][0].objective
        for k, (result, seconds) in results.items():
            totals[k]["iterations"] += result.iterations
            totals[k]["time_s"] += seconds
            totals[k]["same_f"] += abs(result.objective - f_amd) <= SAME * abs(f_amd)
    own = get_transcription(scheme).mumps_pivot_order
    return {"robot": name, "scheme": scheme, "own": own, "pairs": len(problems), "totals": totals}


def cubic_line(problem: TrajOptProblem, beta: float) -> Trajectory:
    """The straight line timed by a cubic meeting the boundary velocities, duration by f."""
    bounds = problem.bounds(1.0)

    def sample(total: float, n: int) -> tuple[np.ndarray, ...]:
        t = np.linspace(0.0, total, n)
        s = t / total
        q0, q1 = problem.start.q, problem.goal.q
        v0, v1 = problem.start.velocity * total, problem.goal.velocity * total
        h = (2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2)
        dh = (6 * s**2 - 6 * s, 3 * s**2 - 4 * s + 1, -6 * s**2 + 6 * s, 3 * s**2 - 2 * s)
        ddh = (12 * s - 6, 6 * s - 4, -12 * s + 6, 6 * s - 2)
        ends = np.stack((q0, v0, q1, v1))  # (4, nv)
        q = np.stack(h, axis=1) @ ends
        v = np.stack(dh, axis=1) @ ends / total
        a = np.stack(ddh, axis=1) @ ends / total**2
        return t, q, v, a

    best: tuple[float, float] | None = None
    for total in np.geomspace(0.05, 30.0, 80):  # [s]
        t, q, v, a = sample(total, 25)
        tau = inverse_dynamics(problem, q, v, a)
        inside = np.all((v >= bounds.v_lower) & (v <= bounds.v_upper)) and np.all(
            (tau >= bounds.tau_lower) & (tau <= bounds.tau_upper)
        )
        if inside:
            f = beta * total + (1 - beta) * float(np.trapezoid(np.sum(tau * tau, axis=1), t))
            if best is None or f < best[0]:
                best = (f, float(total))
    total = 30.0 if best is None else best[1]
    t, q, v, a = sample(total, problem.n_knots)
    return Trajectory(t=t, q=q, v=v, a=a, tau=inverse_dynamics(problem, q, v, a))


def guesses(name: str, problems: list[TrajOptProblem]) -> dict[str, Any]:
    """Radau from the default guess and from :func:`cubic_line`, pair by pair."""
    solver = TrajOptSolver(problems[0], "radau")
    rows = {"line": [0, 0.0], "cubic": [0, 0.0]}
    better = {"line": 0, "cubic": 0}
    for problem in problems:
        line, t_line = _solve(solver, problem)
        cubic, t_cubic = _solve(solver, problem, cubic_line(problem, BETA))
        rows["line"][0] += line.iterations
        rows["line"][1] += t_line
        rows["cubic"][0] += cubic.iterations
        rows["cubic"][1] += t_cubic
        if cubic.objective < line.objective * (1 - SAME):
            better["cubic"] += 1
        elif line.objective < cubic.objective * (1 - SAME):
            better["line"] += 1
    return {"robot": name, "pairs": len(problems), "totals": rows, "better": better}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--pairs", type=int, default=12)
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--robots", nargs="+", default=["ur5", "panda"])
    parser.add_argument("--schemes", nargs="+", default=["radau", "hermite_simpson", "trapezoidal"])
    parser.add_argument("--guesses", action="store_true")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    out: dict[str, list[dict[str, Any]]] = {"orderings": [], "guesses": []}
    print(f"{'robot':<6} {'scheme':<16} {'ordering':<8} {'iter':>5} {'time [s]':>9} "
          f"{'ms/iter':>8} {'vs AMD':>7} {'same f':>7}")  # fmt: skip
    for name in args.robots:
        problems = _problems(name, args.pairs, args.seed)
        for scheme in args.schemes:
            row = orderings(name, scheme, problems)
            out["orderings"].append(row)
            amd = row["totals"][0]["time_s"] / row["totals"][0]["iterations"]
            for k, tot in row["totals"].items():
                per = tot["time_s"] / tot["iterations"]
                mark = "*" if k == row["own"] else ""
                print(f"{name:<6} {scheme:<16} {ORDERINGS[k] + mark:<8} {tot['iterations']:>5} "
                      f"{tot['time_s']:>9.2f} {1e3 * per:>8.2f} {per / amd:>7.2f} "
                      f"{tot['same_f']:>4}/{row['pairs']}")  # fmt: skip
        if args.guesses:
            out["guesses"].append(guesses(name, problems))
    print("* the scheme's own ordering (Transcription.mumps_pivot_order)")
    for row in out["guesses"]:
        (it_l, t_l), (it_c, t_c) = row["totals"]["line"], row["totals"]["cubic"]
        print(f"{row['robot']}: default guess {it_l} iterations {t_l:.2f} s; cubic-timed line "
              f"{it_c} iterations {t_c:.2f} s; better optimum: default {row['better']['line']}, "
              f"cubic {row['better']['cubic']} of {row['pairs']}")  # fmt: skip
    if args.json:
        print(json.dumps(out))


if __name__ == "__main__":
    main()
