"""What a plan tells its user to try next: :func:`next_step`, :func:`gripper_note`.

``youbot-opt solve`` prints them under its table: the option to try when the
refinement did not certify (chosen from what failed), and a note when a
prismatic finger or gripper joint moves in a plan (docs/refinement.md, "A
solution that moves").

>>> print(next_step(result, refinement))  # doctest: +SKIP
--transcription radau (L-stable; lbr_iiwa_joint_7's damping relaxes at 561 1/s: ...)
"""

from __future__ import annotations

import math

import numpy as np

from youbot_opt.dynamics.numeric import damping_rate
from youbot_opt.trajopt.refine import Refinement, torque_overshoot
from youbot_opt.trajopt.result import TrajOptResult

__all__ = ["GRIPPER_WORDS", "UNRESOLVED_DAMPING", "gripper_note", "next_step"]


UNRESOLVED_DAMPING = 2.0
"""``damping_rate * h`` above which a grid does not resolve a joint's damping:
the trapezoid's amplification ``(1 - z/2) / (1 + z/2)`` turns negative there,
so the damped mode alternates from knot to knot instead of decaying."""


def next_step(result: TrajOptResult, record: Refinement) -> str:
    """Name the next thing to try for a plan the refinement did not certify.

    Chosen from what failed: a failed solve -> a multistart; a Hermite-Simpson
    torque overshoot no grid removes (:func:`~youbot_opt.trajopt.refine.overshoot_note`:
    the refinement's trapezoidal fallback was off or had no round left) ->
    ``--transcription trapezoidal``; a grid that does
    not resolve the joint damping (``damping_rate * h`` above
    :data:`UNRESOLVED_DAMPING`) or errors that did not fall, under a scheme
    that is not L-stable -> ``--transcription radau``; a budget that ran out
    while the errors fell -> more rounds, knots or time; else a multistart.
    """
    budget, rounds = record.budget, record.rounds
    last = rounds[-1] if rounds else None
    if last is None or not result.success or result.trajectory is None:
        return "a multistart: --starts 8 (the solve failed; other starts may converge)"
    over = torque_overshoot(result, record.certificate)
    if over is not None:
        return (
            f"--transcription trapezoidal (joint {over.joint}'s torque switches between its "
            f"bounds inside an interval, at t = {over.time:.4g} s: the Hermite-Simpson quadratic "
            f"overshoots there, by {100 * over.relative:.3g} % of the half range, up to 25 % "
            "on any grid)"
        )
    traj = result.trajectory
    stiff = damping_rate(result.problem.robot, traj.q, damping=result.problem.damping)
    z = stiff.rate * float(np.max(np.diff(traj.t)))
    scheme = [r for r in rounds if r.method == last.method]  # the fallback's rounds only
    errors = [r.max_error for r in scheme if math.isfinite(r.max_error)]
    falling = len(errors) < 2 or errors[-1] < 0.5 * errors[-2]
    if result.method != "radau" and (z > UNRESOLVED_DAMPING or not falling):
        why = (
            f"{stiff.joint or 'a joint'}'s damping relaxes at {stiff.rate:.3g} 1/s: "
            f"rate x longest interval = {z:.3g} > {UNRESOLVED_DAMPING:g}, unresolved"
            if z > UNRESOLVED_DAMPING
            else "the error did not fall over the last rounds"
        )
        return f"--transcription radau (L-stable; {why})"
    if "the next grid needs" in record.reason:
        return f"--max-knots {2 * budget.max_knots} (the next grid exceeds {budget.max_knots})"
    if " after " in record.reason and "rounds" in record.reason and falling:
        return f"--max-rounds {2 * budget.max_rounds} (the error was still falling)"
    if budget.time_limit is not None and "time" in record.reason:
        return f"--refine-time {2 * budget.time_limit:g} (the time limit ran out)"
    return "a multistart: --starts 8 (the plan may sit on a poor local optimum)"


GRIPPER_WORDS = ("finger", "gripper", "hand", "jaw")
"""Words in a prismatic joint's name that make it a finger or gripper (:func:`gripper_note`)."""


def gripper_note(result: TrajOptResult) -> str:
    """Say so when a prismatic finger or gripper joint moves in the plan ("" when none does).

    Such a joint is planned like any other: its force enters the work ``W``
    (in N^2 s, beside the arm's N^2 m^2 s) and the optimiser drives it wherever
    that is cheapest, often onto a bound. The note names the joint, its motion
    and the ``--lock`` that plans the arm alone.
    """
    robot, traj = result.problem.robot, result.trajectory
    if traj is None:
        return ""
    bounds = result.bounds()
    notes = []
    units = robot.joint_units()
    for name, joint in zip(robot.joint_names, robot.model.joints[1:], strict=True):
        j = joint.idx_v
        if joint.nv != 1 or not units[j].prismatic:
            continue
        if not any(w in name.lower() for w in GRIPPER_WORDS):
            continue
        q = traj.q[:, j]
        span = float(bounds.q_upper[j] - bounds.q_lower[j])
        if not float(np.ptp(q)) > 1e-3 * span:
            continue
        on_bound = [
            side for side, b in (("lower", bounds.q_lower[j]), ("upper", bounds.q_upper[j]))
            if np.any(np.abs(q - b) <= 1e-6 * span)
        ]  # fmt: skip
        reached = f", onto its {' and '.join(on_bound)} bound" if on_bound else ""
        lock = float(q[-1])
        notes.append(
            f"note: the {name} (prismatic: a finger or gripper) moves in this plan, "
            f"{q[0]:.4g} -> {q[-1]:.4g} m{reached}: its force "
            f"adds N^2 s to the work W. To plan the arm alone, lock it: --lock {name}={lock:.4g}"
        )
    return "\n".join(notes)
