"""A timed trajectory through waypoints against TOPP-RA (issue 30, item 3).

Run ``python benchmarks/bench_timed.py [--quick] [--json FILE]``.

For each case the same configurations are passed through, in order, starting
and ending at rest, under the same joint velocity and torque limits
(``robot.bounds()``; our problems have no acceleration limits, so none is given
to either side):

* **ours**: :func:`youbot_opt.trajopt.timed.solve_through` with ``beta = 1``
  (minimum time), the path free between the waypoints;
* **TOPP-RA** (the ``toppra`` wheel, in the ``bench`` extra): a cubic spline
  through the same configurations (``toppra.SplineInterpolator``, clamped: zero
  path velocity at both ends, path parameter = cumulative chord length in joint
  space), retimed under ``JointVelocityConstraint`` and ``JointTorqueConstraint``
  with inverse dynamics ``pin.rnea(q, v, a) + b v`` (our dynamics: the joint
  damping ``b`` opposes the motion, ``M a + h = tau - b v``), then sampled into
  our :class:`~youbot_opt.trajopt.trajectory.Trajectory` (Hermite-Simpson: knots
  at ``--samples`` uniform times, torques at knots and mid-intervals by the same
  inverse dynamics) and run through OUR certificate
  (:func:`youbot_opt.trajopt.certify.certify`). TOPP-RA holds its constraints
  at its gridpoints only, so its motion exceeds the limits slightly between
  them (measured: up to 2 % speed, 7 % torque at 400 gridpoints, not less at
  1600): it is run again with the limits it is given scaled by ``--margin``
  (0.9) and certified against the full limits.

Both ``W`` are the study's ``integral tau . tau dt`` [N^2 m^2 s] by Simpson's rule
on each interval (our Hermite-Simpson quadrature, ``trajopt/check.py``'s
``_work``). The table prints ``T``, ``W``, the certificate (pass/fail and its
worst failure, or its largest local position error), the wall time of each
solve (ours: build of the NLP and the solve, separately), the ratio
``T_ours / T_toppra`` and whether ``T_ours <= T_toppra`` holds (the issue
requires it: our path is free between the waypoints, TOPP-RA's is fixed).
Unless ``--no-refine``, our plan is also refined until certified
(``TimedSolver.refine`` with the default budget, the trapezoidal fallback
included, as ``youbot-opt ikpath --timed`` does): its ``T``, ``W``, verdict,
knots per round and wall time, and ``T_refined / T_toppra``.

TOPP-RA cannot express a torque term linear in the path speed (its constraint
is ``a(s) sdd + b(s) sd^2 + c(s)``): a robot with nonzero joint damping is
refused (every robot here has none). Without toppra the comparison is skipped
with the install hint, as ``bench_trajopt.py`` skips Drake.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

TOPPRA_HINT = 'pip install -e ".[bench]"'
DEFAULT_SAMPLES = 401  # knots of the sampled TOPP-RA trajectory
DEFAULT_GRIDPOINTS = 400  # TOPP-RA's path grid

Array = np.ndarray


# ---------------------------------------------------------------- pure helpers
def path_visits(start: Array, waypoints: Array, goal: Array | None, *, atol: float = 0.0) -> Array:
    """Configurations visited in order: start, the waypoints, then the goal (or none).

    A first waypoint equal to the start (within ``atol``) is the start itself, as
    in :class:`~youbot_opt.trajopt.timed.TimedSolver`; ``goal = None`` ends at
    the last waypoint (a closed cycle passes its first row again as last row).
    """
    rows = [np.asarray(start, dtype=float)]
    w = np.atleast_2d(np.asarray(waypoints, dtype=float))
    if w.shape[0] and np.allclose(w[0], rows[0], rtol=0.0, atol=atol):
        w = w[1:]
    rows += list(w)
    if goal is not None:
        rows.append(np.asarray(goal, dtype=float))
    return np.vstack(rows)


def chord_parameters(visits: Array) -> Array:
    """Cumulative joint-space chord length of ``visits`` [rad], starting at 0.

    A repeated configuration (zero chord) gets a small step so the parameter
    stays strictly increasing.
    """
    steps = np.linalg.norm(np.diff(visits, axis=0), axis=1)
    floor = 1e-3 * max(float(steps.max(initial=0.0)), 1.0)
    return np.concatenate([[0.0], np.cumsum(np.maximum(steps, floor))])


def simpson_work(t: Array, tau: Array, tau_mid: Array) -> float:
    """``integral tau . tau dt`` [N^2 m^2 s] by Simpson's rule on each interval.

    ``tau`` at the knots ``t`` (N, nv), ``tau_mid`` at the interval midpoints
    (N - 1, nv): the Hermite-Simpson quadrature of our transcription.
    """
    p = np.sum(np.asarray(tau) ** 2, axis=1)
    pm = np.sum(np.asarray(tau_mid) ** 2, axis=1)
    h = np.diff(np.asarray(t, dtype=float))
    return float(np.sum(h / 6.0 * (p[:-1] + 4.0 * pm + p[1:])))


def grid_time(grid: Array, sd: Array) -> Array:
    """Time [s] at each path gridpoint of a retiming with path speeds ``sd`` there.

    Constant path acceleration on each grid interval: ``dt = 2 ds / (sd_i + sd_i+1)``.
    """
    ds = np.diff(np.asarray(grid, dtype=float))
    speed = np.asarray(sd, dtype=float).ravel()
    return np.concatenate([[0.0], np.cumsum(2.0 * ds / (speed[:-1] + speed[1:]))])


def limit_pairs(lower: Array, upper: Array) -> Array:
    """TOPP-RA's ``(dof, 2)`` limit array ``[[lower, upper], ...]``."""
    return np.column_stack([np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)])


# ---------------------------------------------------------------- TOPP-RA side
@dataclass(frozen=True)
class ToppraRun:
    """TOPP-RA's retimed path sampled into our trajectory."""

    trajectory: Any  # youbot_opt.trajopt.trajectory.Trajectory
    duration: float  # [s]
    work: float  # [N^2 m^2 s]
    wall: float  # [s] spline, constraints and TOPP-RA
    visit_times: Array  # [s] when each visit is passed


def _import_toppra() -> Any:
    import logging

    import toppra

    logging.getLogger("toppra").setLevel(logging.WARNING)
    return toppra


def toppra_through(
    problem: Any,
    visits: Array,
    *,
    gridpoints: int = DEFAULT_GRIDPOINTS,
    samples: int = DEFAULT_SAMPLES,
    limit_scale: float = 1.0,
) -> ToppraRun:
    """Retime a clamped cubic spline through ``visits`` with TOPP-RA, sample it as ours.

    ``problem`` supplies the robot, its bounds (``problem.bounds()``) and whether
    its damping acts (``problem.damping``). ``limit_scale`` (<= 1) shrinks the
    velocity and torque limits given to TOPP-RA (not those certified against): a
    margin for its excess between gridpoints.
    """
    ta = _import_toppra()
    from toppra import algorithm, constraint

    from youbot_opt.trajopt.guess import inverse_dynamics
    from youbot_opt.trajopt.trajectory import Trajectory

    robot = problem.robot
    b = np.asarray(robot.damping, dtype=float) if problem.damping else np.zeros(robot.model.nv)
    if np.any(b != 0.0):
        raise ValueError(
            f"{robot.name} has joint damping {b} N m s/rad: TOPP-RA's torque constraint "
            "a(s) sdd + b(s) sd^2 + c(s) cannot hold a term linear in the path speed"
        )
    bounds = problem.bounds()

    def inv_dyn(q: Array, v: Array, a: Array) -> Array:
        return inverse_dynamics(problem, q[None], v[None], a[None])[0]

    tic = time.perf_counter()
    ss = chord_parameters(visits)
    path = ta.SplineInterpolator(ss, visits, bc_type="clamped")
    k = float(limit_scale)
    velocity = constraint.JointVelocityConstraint(k * limit_pairs(bounds.v_lower, bounds.v_upper))
    torque = constraint.JointTorqueConstraint(
        inv_dyn,
        k * limit_pairs(bounds.tau_lower, bounds.tau_upper),
        np.zeros(robot.model.nv),  # no Coulomb friction in our model
        discretization_scheme=constraint.DiscretizationType.Interpolation,
    )
    grid = np.linspace(0.0, ss[-1], gridpoints + 1)
    instance = algorithm.TOPPRA([velocity, torque], path, gridpoints=grid)
    timed = instance.compute_trajectory(0.0, 0.0)
    wall = time.perf_counter() - tic
    if timed is None:
        raise RuntimeError("TOPP-RA found no parametrisation (infeasible path)")
    duration = float(timed.duration)
    t = np.linspace(0.0, duration, samples)
    mid = 0.5 * (t[:-1] + t[1:])
    q, v, a = timed(t), timed(t, 1), timed(t, 2)
    v[0] = v[-1] = 0.0  # at rest at both ends (TOPP-RA's sd = 0 there)
    tau = inverse_dynamics(problem, q, v, a)
    tau_mid = inverse_dynamics(problem, timed(mid), timed(mid, 1), timed(mid, 2))
    trajectory = Trajectory(
        t=t, q=q, v=v, a=a, tau=tau, tau_mid=tau_mid, interpolation="hermite_simpson"
    )
    data = instance.problem_data
    grid_times = grid_time(np.asarray(data.gridpoints), np.asarray(data.sd_vec))
    return ToppraRun(
        trajectory=trajectory,
        duration=duration,
        work=simpson_work(t, tau, tau_mid),
        wall=wall,
        visit_times=np.interp(ss, np.asarray(data.gridpoints), grid_times),
    )


# -------------------------------------------------------------------- cases
def _youbot_case() -> tuple[Any, Array, bool]:
    """The study's planar youBot (study 1's start and goal) through 3 configurations."""
    from youbot_opt.reproduction.study1 import study1_problem

    problem = study1_problem()
    w = np.array([[0.3, -0.2, 0.5], [-0.2, 0.4, 0.9], [0.5, 0.8, -0.4]])
    return problem, w, False


def _ikpath_case() -> tuple[Any, Array, bool]:
    """The youBot round a cyclic IK path through 3 targets, from rest at its first configuration.

    The targets are the tip positions of the youBot case's 3 configurations;
    the path is the best of 20 seeded starts (:func:`youbot_opt.ikpath.run_multistart`),
    timed as ``youbot-opt ikpath ... --timed`` does: a closed cycle.
    """
    import pinocchio as pin

    from youbot_opt.ikpath import CyclicIKProblem, MultistartResult, run_multistart
    from youbot_opt.ikpath.targets import position_targets
    from youbot_opt.robot.load import load_model
    from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem

    robot = load_model("youbot")
    model, data = robot.model, robot.model.createData()
    frame = model.getFrameId(robot.tip_frame)
    targets = []
    for q in _youbot_case()[1]:
        pin.framesForwardKinematics(model, data, q)
        targets.append(np.round(data.oMf[frame].translation, 4))
    problem = CyclicIKProblem(robot=robot, targets=position_targets(targets))
    path = run_multistart(problem, n_starts=20, seed=0)
    if not isinstance(path, MultistartResult) or not path.best.success:
        raise RuntimeError("the cyclic IK path failed")
    w = np.asarray(path.best.configurations, dtype=float)
    state = BoundaryState(q=w[0])
    return TrajOptProblem(robot=robot, start=state, goal=state), w, True


def _ur5_case() -> tuple[Any, Array, bool]:
    """UR5 from rest through 4 configurations and back to the first (a closed cycle)."""
    from youbot_opt.robot.load import load_model
    from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem

    robot = load_model("ur5")
    start = np.array([0.0, -1.2, 1.0, -0.5, 0.3, 0.0])
    w = np.array(
        [
            [0.0, -1.2, 1.0, -0.5, 0.3, 0.0],
            [0.8, -0.6, 0.4, -1.2, -0.3, 0.5],
            [0.4, -1.5, 1.4, -0.2, 0.6, -0.4],
            [-0.5, -0.9, 0.7, -0.9, 0.0, 0.3],
        ]
    )
    state = BoundaryState(q=start)
    problem = TrajOptProblem(robot=robot, start=state, goal=state, n_knots=20)
    return problem, w, True


CASES: dict[str, Callable[[], tuple[Any, Array, bool]]] = {
    "youbot": _youbot_case,
    "youbot-ikpath": _ikpath_case,
    "ur5": _ur5_case,
}


def _certificate_figure(cert: Any) -> str:
    fails = cert.failures()
    if fails:
        return f"FAIL: {fails[0]}" + (f" (+{len(fails) - 1})" if len(fails) > 1 else "")
    return f"pass (local q {cert.local_position_max:.1e} rad)"


def _toppra_row(problem: Any, visits: Array, **kwargs: Any) -> dict[str, Any]:
    from youbot_opt.trajopt.certify import certify

    topp = toppra_through(problem, visits, **kwargs)
    cert = certify(topp.trajectory, problem.robot, bounds=problem.bounds())
    return {
        "T": topp.duration, "W": topp.work, "certified": bool(cert.ok),
        "certificate": _certificate_figure(cert), "failures": cert.failures(),
        "solve_s": topp.wall, "visit_times": [float(x) for x in topp.visit_times],
    }  # fmt: skip


def run_case(
    name: str,
    *,
    samples: int,
    gridpoints: int,
    knots: int,
    margin: float = 0.9,
    refine: bool = True,
) -> dict[str, Any]:
    """Both sides on one case; a JSON-ready row."""
    from youbot_opt.trajopt import timed  # #30 item 3
    from youbot_opt.trajopt.certify import certify
    from youbot_opt.trajopt.waypoints import Waypoints

    problem, w, closed = CASES[name]()
    waypoints = Waypoints(q=w, closed=closed)
    goal = None if closed else problem.goal.q
    visits = path_visits(problem.start.q, waypoints.visits, goal)
    row: dict[str, Any] = {
        "case": name, "robot": problem.robot.name, "visits": len(visits), "closed": closed,
    }  # fmt: skip

    tic = time.perf_counter()
    solver = timed.TimedSolver(problem, waypoints, knots_per_segment=knots)
    build = time.perf_counter() - tic
    tic = time.perf_counter()
    ours = solver.solve(beta=1.0)
    solve = time.perf_counter() - tic
    cert = certify(ours.result)
    row["ours"] = {
        "T": ours.duration, "W": ours.work, "success": bool(ours.success),
        "certified": bool(cert.ok), "certificate": _certificate_figure(cert),
        "failures": cert.failures(), "build_s": build, "solve_s": solve,
        "waypoint_times": [float(x) for x in ours.waypoint_times],
    }  # fmt: skip

    if refine:  # what the command line does by default: refined until certified
        tic = time.perf_counter()
        refined = solver.refine(first=ours)
        row["refined"] = {
            "T": refined.duration, "W": refined.work, "certified": bool(refined.certified),
            "knots": [r.n_knots for r in refined.refinement.rounds],
            "methods": [r.method for r in refined.refinement.rounds],
            "reason": refined.refinement.reason, "refine_s": time.perf_counter() - tic,
        }  # fmt: skip

    grid = {"gridpoints": gridpoints, "samples": samples}
    row["toppra"] = _toppra_row(problem, visits, **grid)
    row["margin"] = margin
    row["toppra_margin"] = _toppra_row(problem, visits, limit_scale=margin, **grid)
    topp = row["toppra"]
    row["ratio"] = ours.duration / topp["T"]
    row["holds"] = bool(ours.duration <= topp["T"])
    if refine:
        row["refined_ratio"] = row["refined"]["T"] / topp["T"]
        row["refined_holds"] = bool(row["refined"]["T"] <= topp["T"])
    return row


def _print(row: dict[str, Any]) -> None:
    o, t = row["ours"], row["toppra"]
    cycle = ", a closed cycle" if row["closed"] else ""
    print(f"\n{row['case']} ({row['robot']}), {row['visits']} configurations{cycle}, rest to rest")
    print(f"  {'':8} {'T [s]':>8} {'W [N^2 m^2 s]':>14} {'wall [s]':>16}  certificate")
    wall = f"{o['build_s']:.2f}+{o['solve_s']:.2f}"
    print(f"  {'ours':8} {o['T']:8.4f} {o['W']:14.4f} {wall:>16}  {o['certificate']}")
    print(f"  {'TOPP-RA':8} {t['T']:8.4f} {t['W']:14.4f} {t['solve_s']:16.2f}  {t['certificate']}")
    if "refined" in row:
        r = row["refined"]
        verdict = "certified" if r["certified"] else f"not certified: {r['reason']}"
        print(f"  {'refined':8} {r['T']:8.4f} {r['W']:14.4f} {r['refine_s']:16.2f}  {verdict}")
        schemes = " -> ".join(dict.fromkeys(r["methods"]))
        print(f"  {'':8} knots {' -> '.join(map(str, r['knots']))} ({schemes})")
    m, label = row["toppra_margin"], f"at {row['margin']:.0%}"
    print(f"  {label:8} {m['T']:8.4f} {m['W']:14.4f} {m['solve_s']:16.2f}  {m['certificate']}")
    print(f"  T_ours / T_toppra = {row['ratio']:.3f}: T_ours <= T_toppra "
          f"{'holds' if row['holds'] else 'DOES NOT hold'}")  # fmt: skip
    if "refined" in row:
        print(f"  T_refined / T_toppra = {row['refined_ratio']:.3f}: T_refined <= T_toppra "
              f"{'holds' if row['refined_holds'] else 'DOES NOT hold'}")  # fmt: skip
    print(f"  ours at the waypoints [s]: {np.round(o['waypoint_times'], 3).tolist()}")
    print(f"  TOPP-RA at the visits [s]: {np.round(t['visit_times'], 3).tolist()}")
    for side, fails in (("ours", o["failures"]), ("TOPP-RA", t["failures"])):
        for line in fails:
            print(f"  {side} certificate: {line}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the youBot case only")
    parser.add_argument("--samples", type=int, default=DEFAULT_SAMPLES)
    parser.add_argument("--gridpoints", type=int, default=DEFAULT_GRIDPOINTS)
    parser.add_argument("--knots", type=int, default=20, help="our knots per segment")
    parser.add_argument(
        "--margin", type=float, default=0.9,
        help="TOPP-RA run again with its limits scaled by this (certified at 100 %%)",
    )  # fmt: skip
    parser.add_argument(
        "--no-refine", dest="refine", action="store_false",
        help="skip the refined plan (refinement until certified, the command line's default)",
    )  # fmt: skip
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)
    try:
        _import_toppra()
    except ImportError as exc:
        print(f"TOPP-RA comparison skipped, toppra is not installed ({exc}): {TOPPRA_HINT}")
        return 0
    print(f"load average {os.getloadavg()[0]:.2f} (wall times inflated on a shared machine)")
    print("ours: beta = 1 (minimum time), Hermite-Simpson; wall = NLP build + solve")
    print(f"TOPP-RA: {args.gridpoints} gridpoints, sampled at {args.samples} knots")
    names = ["youbot"] if args.quick else list(CASES)
    rows = []
    for name in names:
        row = run_case(
            name, samples=args.samples, gridpoints=args.gridpoints, knots=args.knots,
            margin=args.margin, refine=args.refine,
        )  # fmt: skip
        _print(row)
        rows.append(row)
    if not all(r["holds"] and r.get("refined_holds", True) for r in rows):
        print("\nT_ours > T_toppra in a case: see the waypoint times above")
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1, default=float))
    return 0 if math.isfinite(sum(r["ratio"] for r in rows)) else 1


if __name__ == "__main__":
    raise SystemExit(main())
