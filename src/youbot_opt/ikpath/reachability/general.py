"""Reachability of 3-D targets on any robot: witness, certificate, or undecided (issue 14, item 3).

Each target of a :class:`~youbot_opt.ikpath.problem.CyclicIKProblem` gets a
:class:`ReachVerdict3D`: reachable (joint values within the limits that meet it,
checked by Pinocchio), unreachable with a certificate (beyond the reach sphere,
or every box of a bisected joint box excluded by interval forward kinematics,
:mod:`youbot_opt.ikpath.reachability.interval`), or undecided when the budget runs out.
Position, pose and approach targets are all decided (docs/ikpath.md, "Interval
reachability").

>>> verdicts = check_reachability_3d(problem, interval_seconds=1.0)
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from youbot_opt._checks import check_int, check_nonnegative
from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError, UnreachableTarget
from youbot_opt.ikpath.dls import dls_ik, random_theta
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability import Reachability
from youbot_opt.ikpath.reachability.branch_and_bound import bisect_boxes
from youbot_opt.ikpath.reachability.interval import (
    ROUNDING_RELATIVE,
    Interval,
    IntervalChain,
    IntervalPlacement,
)
from youbot_opt.ikpath.targets import Target

__all__ = [
    "DEFAULT_INTERVAL_BOXES",
    "DEFAULT_INTERVAL_SECONDS",
    "IntervalOutcome",
    "ReachVerdict3D",
    "check_reachability_3d",
    "interval_search",
    "joint_box",
    "require_reachable_3d",
]

DEFAULT_INTERVAL_SECONDS = 1.0
"""Default wall-time budget [s] of the interval search, per target."""

DEFAULT_INTERVAL_BOXES = 200_000
"""Default budget of the interval search in boxes evaluated, per target."""

Mask = npt.NDArray[np.bool_]
_log = logging.getLogger(__name__)
_BATCH = 1024  # boxes bounded per vectorised call
_MAX_POLISH = 8  # DLS polishes from promising midpoints per target
_DECISION_MARGIN = 1e-12  # [1] below the rounding of the trace/cosine thresholds


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class ReachVerdict3D:
    """Reachability of one target, with its witness or certificate.

    Attributes
    ----------
    index : int
        Target index (0-based).
    status : Reachability
        The verdict.
    witness : ndarray or None
        Joint values [rad] (or [m]) within the limits meeting the target,
        checked by ``pin.framesForwardKinematics`` (reachable only).
    distance : float
        Distance [m] of the target from the reach sphere's centre.
    reach : float
        Radius [m] of the reach sphere (a certificate when ``distance > reach + tol``).
    message : str
        Human-readable reason, with the certificate or the budget spent.
    method : str
        What decided: ``"reach_sphere"``, ``"dls"`` (a damped least-squares
        witness), ``"interval"`` (certificate or witness of the interval search),
        or ``"none"`` (undecided).
    boxes : int
        Boxes bounded by the interval search (0 if it did not run).
    depth : int
        Deepest bisection level of the interval search.
    """

    index: int
    status: Reachability
    witness: Array | None
    distance: float
    reach: float
    message: str
    method: str = "none"
    boxes: int = 0
    depth: int = 0


class IntervalOutcome(NamedTuple):
    """What the interval search decided for one target.

    Attributes
    ----------
    status : Reachability
        UNREACHABLE (every box excluded), REACHABLE (witness) or UNDECIDED (budget).
    witness : ndarray or None
        Joint values within the limits meeting the target (REACHABLE only).
    boxes : int
        Boxes bounded.
    depth : int
        Deepest bisection level reached.
    pending : int
        Boxes neither excluded nor bisected when the search stopped.
    by_position, by_orientation : int
        Boxes excluded because the frame's position (resp. orientation) interval
        cannot meet the target's tolerance.
    seconds : float
        Wall time [s].
    """

    status: Reachability
    witness: Array | None
    boxes: int
    depth: int
    pending: int
    by_position: int
    by_orientation: int
    seconds: float


def joint_box(problem: CyclicIKProblem) -> tuple[Array, Array]:
    """Return the joint box searched: the limits, revolute ranges cut to one turn.

    A revolute joint's placement repeats every 2 pi, so an unlimited or
    continuous joint is searched over ``[-pi, pi]`` and a range wider than
    2 pi over its first turn (``[lo, lo + 2 pi]``): the same placements, and
    every point of the box is within the limits.

    Raises
    ------
    ParameterError
        If a prismatic joint has no finite travel (no box contains its values).
    """
    n = problem.n_joints
    lo = np.array(problem.lower[:n], dtype=float)
    hi = np.array(problem.upper[:n], dtype=float)
    revolute = IntervalChain.from_model(problem.model, problem.frame_id).revolute
    for k in range(n):
        if not revolute[k]:
            if not (math.isfinite(lo[k]) and math.isfinite(hi[k])):
                raise ParameterError(
                    f"prismatic joint {problem.joint_names[k]!r} has no finite travel "
                    f"([{lo[k]}, {hi[k]}] m); the interval search needs a bounded box",
                    name="q_lower",
                    value=(lo[k], hi[k]),
                )
            continue
        if math.isfinite(lo[k]) and hi[k] - lo[k] >= 2.0 * math.pi:
            hi[k] = lo[k] + 2.0 * math.pi
        elif math.isfinite(hi[k]) and not math.isfinite(lo[k]):
            lo[k] = hi[k] - 2.0 * math.pi
        elif not math.isfinite(lo[k]):
            lo[k], hi[k] = -math.pi, math.pi
    return lo, hi


def _upper_sum(coefficient: Array, x: Interval) -> Array:
    """Upper bound of ``sum_ab c_ab x_ab`` over the last two axes (widened)."""
    terms = np.maximum(coefficient * x.lo, coefficient * x.hi)
    magnitude = np.maximum(np.abs(coefficient * x.lo), np.abs(coefficient * x.hi))
    return terms.sum(axis=(-2, -1)) + ROUNDING_RELATIVE * magnitude.sum(axis=(-2, -1))


def _excluded(target: Target, bounds: IntervalPlacement) -> tuple[Mask, Mask]:
    """Per box: whether its position, resp. orientation, interval cannot meet the target.

    Position: the distance from the target to the position box exceeds
    ``position_tol``, or to a joint origin's box exceeds that origin's reach.
    Pose: the rotation angle of ``R_t^T R`` is at most ``tol`` iff
    ``tr(R_t^T R) = sum R_t * R >= 1 + 2 cos(tol)``; approach: the angle between
    ``R a`` and ``d`` is at most ``tol`` iff ``d^T R a >= cos(tol)``. A box is
    excluded when an upper bound of the left side is below the threshold.
    """
    rot, pos, origins = bounds.rotation, bounds.translation, bounds.origins
    gap = np.maximum(np.maximum(pos.lo - target.position, target.position - pos.hi), 0.0)
    # sqrt(sum gap^2) carries <= 5 roundings: the factor keeps the test sound.
    by_position = np.sqrt(np.sum(gap * gap, axis=1)) > target.position_tol * (1.0 + 1e-12)
    # The frame stays within reach_k of joint k's origin (triangle inequality).
    gap = np.maximum(np.maximum(origins.lo - target.position, target.position - origins.hi), 0.0)
    far = np.sqrt(np.sum(gap * gap, axis=2)) > (bounds.reach + target.position_tol) * (1.0 + 1e-12)
    by_position |= np.any(far, axis=1)
    tol = min(target.orientation_tol, math.pi)
    if target.rotation is not None:
        bound = _upper_sum(target.rotation, rot)
        by_orientation = bound < 1.0 + 2.0 * math.cos(tol) - _DECISION_MARGIN
    elif target.approach is not None:
        bound = _upper_sum(np.outer(target.approach, target.approach_axis), rot)
        by_orientation = bound < math.cos(tol) - _DECISION_MARGIN
    else:
        by_orientation = np.zeros(by_position.shape, dtype=bool)
    return by_position, by_orientation


def _score(target: Target, rot: Interval, pos: Interval) -> Array:
    """Miss [m] of each box's centre placement (orientation weighted): picks midpoints to try."""
    centre = 0.5 * (pos.lo + pos.hi)
    miss = np.linalg.norm(centre - target.position, axis=1)
    r = 0.5 * (rot.lo + rot.hi)
    if target.rotation is not None:
        miss = miss + target.orientation_weight * np.linalg.norm(r - target.rotation, axis=(1, 2))
    elif target.approach is not None:
        axis = r @ target.approach_axis
        miss = miss + target.orientation_weight * np.linalg.norm(axis - target.approach, axis=1)
    return miss


def _dls(
    problem: CyclicIKProblem, j: int, theta0: Array, data: pin.Data, **options: int
) -> tuple[Array, bool]:
    """:func:`dls_ik`, with a singular step system (a rank-deficient pose block) as "not met"."""
    try:
        return dls_ik(problem, j, theta0, data=data, **options)
    except np.linalg.LinAlgError:
        return np.asarray(theta0, dtype=float), False


def _pop_batch(stack: list[tuple[Array, Array, Array]]) -> tuple[Array, Array, Array]:
    """Take up to ``_BATCH`` boxes from the top of the stack (depth first)."""
    taken: list[tuple[Array, Array, Array]] = []
    count = 0
    while stack and count < _BATCH:
        b_lo, b_hi, b_depth = stack.pop()
        room = _BATCH - count
        if b_lo.shape[0] > room:  # split the chunk: its top part now, the rest stays
            stack.append((b_lo[:-room], b_hi[:-room], b_depth[:-room]))
            b_lo, b_hi, b_depth = b_lo[-room:], b_hi[-room:], b_depth[-room:]
        taken.append((b_lo, b_hi, b_depth))
        count += b_lo.shape[0]
    return (
        np.concatenate([t[0] for t in taken]),
        np.concatenate([t[1] for t in taken]),
        np.concatenate([t[2] for t in taken]),
    )


def interval_search(
    problem: CyclicIKProblem,
    j: int,
    *,
    max_boxes: int = DEFAULT_INTERVAL_BOXES,
    max_seconds: float = DEFAULT_INTERVAL_SECONDS,
) -> IntervalOutcome:
    """Branch and bound over the joint box with interval forward kinematics.

    Boxes (:func:`joint_box`, bisected by
    :func:`~youbot_opt.ikpath.reachability.branch_and_bound.bisect_boxes` on the side of
    largest lever-weighted width) are excluded when their interval placement
    cannot meet target ``j`` (:mod:`youbot_opt.ikpath.reachability.interval`: sound, rounding
    included). No box left proves the target unreachable. For each batch the
    surviving box whose centre misses least has its midpoint checked by
    Pinocchio (a witness if it meets the target) and, when the miss has halved,
    polished by DLS from there (at most 8 times).

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem; its limits (``use_limits``) bound the box.
    j : int
        Target index.
    max_boxes : int
        Budget in boxes bounded.
    max_seconds : float
        Budget in wall time [s] (checked between batches of 1024 boxes).

    Raises
    ------
    ParameterError
        For a bad index or budget, a joint type interval kinematics does not
        support, or a prismatic joint without finite travel.
    """
    start = time.perf_counter()
    if not 0 <= check_int(j, "j") < problem.n_targets:
        raise ParameterError(
            f"j must be a target index in [0, {problem.n_targets - 1}], got {j}", name="j", value=j
        )
    max_boxes = check_int(max_boxes, "max_boxes")
    max_seconds = check_nonnegative(max_seconds, "max_seconds", unit="s")
    target = problem.targets[j]
    chain = IntervalChain.from_model(problem.model, problem.frame_id)
    lo, hi = joint_box(problem)
    # Lever arm [m] per joint (+1 m/rad for orientation): angle widths compare in metres.
    scale = np.where(chain.revolute, chain.levers() + 1.0, 1.0)
    stack: list[tuple[Array, Array, Array]] = [(lo[None], hi[None], np.zeros(1, dtype=int))]
    boxes = depth = by_pos = by_ori = polishes = 0
    last_polish = math.inf
    data = problem.create_data()

    def outcome(status: Reachability, witness: Array | None = None) -> IntervalOutcome:
        pending = sum(chunk[0].shape[0] for chunk in stack)
        seconds = time.perf_counter() - start
        _log.debug(
            "target %d: interval search %s after %d boxes (depth %d, %d left) in %.3f s",
            j,
            status.value,
            boxes,
            depth,
            pending,
            seconds,
        )
        return IntervalOutcome(status, witness, boxes, depth, pending, by_pos, by_ori, seconds)

    while stack:
        if boxes >= max_boxes or time.perf_counter() - start >= max_seconds:
            return outcome(Reachability.UNDECIDED)
        b_lo, b_hi, b_depth = _pop_batch(stack)
        bounds = chain.placement(b_lo, b_hi)
        rot, pos = bounds.rotation, bounds.translation
        boxes += b_lo.shape[0]
        depth = max(depth, int(b_depth.max()))
        out_pos, out_ori = _excluded(target, bounds)
        by_pos += int(np.count_nonzero(out_pos))
        by_ori += int(np.count_nonzero(out_ori & ~out_pos))
        keep = ~(out_pos | out_ori)
        if not np.any(keep):
            continue
        b_lo, b_hi, b_depth = b_lo[keep], b_hi[keep], b_depth[keep]
        miss = _score(
            target, Interval(rot.lo[keep], rot.hi[keep]), Interval(pos.lo[keep], pos.hi[keep])
        )
        best = int(np.argmin(miss))
        mid = 0.5 * (b_lo[best] + b_hi[best])
        if target.met(problem.placement(mid, data)):
            return outcome(Reachability.REACHABLE, mid)
        if polishes < _MAX_POLISH and miss[best] < 0.5 * last_polish:
            polishes += 1
            last_polish = float(miss[best])
            theta, met = _dls(problem, j, mid, data, restarts=0, max_iterations=100)
            if met:
                return outcome(Reachability.REACHABLE, theta)
        c_lo, c_hi = bisect_boxes(b_lo, b_hi, scale)
        stack.append((c_lo, c_hi, np.concatenate([b_depth, b_depth]) + 1))
    return outcome(Reachability.UNREACHABLE)


def _interval_message(j: int, target: Target, found: IntervalOutcome) -> str:
    tols = f"{target.position_tol:.3g} m"
    if target.kind != "position":
        tols += f" and {target.orientation_tol:.3g} rad"
    return (
        f"target {j} ({target.kind}) at {target.position.tolist()} m: no joint values within "
        f"the limits meet it to {tols}; interval forward kinematics excludes every box of the "
        f"joint box ({found.boxes} box{'es' if found.boxes != 1 else ''} to bisection depth "
        f"{found.depth}: {found.by_position} "
        f"by position, {found.by_orientation} by orientation)"
    )


def check_reachability_3d(
    problem: CyclicIKProblem,
    *,
    tries: int = 20,
    seed: int = 0,
    interval_boxes: int = DEFAULT_INTERVAL_BOXES,
    interval_seconds: float = DEFAULT_INTERVAL_SECONDS,
) -> tuple[ReachVerdict3D, ...]:
    """Decide each target: reachable (witness), unreachable (certificate), or undecided.

    In order: the reach sphere (:meth:`~CyclicIKProblem.reach_radius`; a
    target farther than ``reach + position_tol`` from its centre is
    unreachable); one DLS solve from zero angles (a witness); the interval
    search (:func:`interval_search`, a certificate or a witness); then the
    remaining ``tries - 1`` seeded DLS solves from random angles in the limits.

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    tries : int
        DLS solves per target (>= 1).
    seed : int
        Seed of the random DLS starts.
    interval_boxes : int
        Budget of the interval search per target, in boxes.
    interval_seconds : float
        Budget of the interval search per target, in [s] (0 skips it).

    Returns
    -------
    tuple of ReachVerdict3D
        One per target, in order.
    """
    tries = check_int(tries, "tries", minimum=1)
    interval_boxes = check_int(interval_boxes, "interval_boxes", minimum=0)
    interval_seconds = check_nonnegative(interval_seconds, "interval_seconds", unit="s")
    centre, reach = problem.reach_radius()
    rng = np.random.default_rng(seed)
    data = problem.create_data()
    out = []
    for j, target in enumerate(problem.targets):
        dist = float(np.linalg.norm(target.position - centre))

        def verdict(
            status: Reachability,
            message: str,
            method: str,
            witness: Array | None = None,
            found: IntervalOutcome | None = None,
            j: int = j,
            dist: float = dist,
        ) -> ReachVerdict3D:
            return ReachVerdict3D(
                index=j,
                status=status,
                witness=None if witness is None else np.array(witness, dtype=float),
                distance=dist,
                reach=reach,
                message=message,
                method=method,
                boxes=0 if found is None else found.boxes,
                depth=0 if found is None else found.depth,
            )

        if dist > reach + target.position_tol:
            message = (
                f"target {j} at {target.position.tolist()} m is {dist:.4g} m from the first "
                f"joint at {centre.tolist()}, beyond the reach sphere of radius {reach:.4g} m "
                "(sum of link lengths)"
            )
            out.append(verdict(Reachability.UNREACHABLE, message, "reach_sphere"))
            continue
        theta, met = _dls(problem, j, np.zeros(problem.n_joints), data)
        if met:
            out.append(verdict(Reachability.REACHABLE, "DLS witness", "dls", theta))
            continue
        found, note = None, ""
        if interval_seconds > 0.0 and interval_boxes > 0:
            try:
                found = interval_search(
                    problem, j, max_boxes=interval_boxes, max_seconds=interval_seconds
                )
            except ParameterError as err:  # a joint type or travel the search cannot box
                note = f"; no interval bound: {err}"
        if found is not None and found.status is Reachability.UNREACHABLE:
            message = _interval_message(j, target, found)
            out.append(verdict(Reachability.UNREACHABLE, message, "interval", None, found))
            continue
        if found is not None and found.witness is not None:
            message = "interval-search witness"
            out.append(verdict(Reachability.REACHABLE, message, "interval", found.witness, found))
            continue
        if found is not None:
            note = (
                f"; interval search undecided after {found.boxes} boxes in "
                f"{found.seconds:.2f} s ({found.pending} boxes left, depth {found.depth})"
            )
        witness = None
        for _ in range(1, tries):
            theta, met = _dls(problem, j, random_theta(problem, rng), data)
            if met:
                witness = theta
                break
        if witness is not None:
            out.append(verdict(Reachability.REACHABLE, "DLS witness", "dls", witness, found))
            continue
        message = f"target {j}: inside the reach sphere but no witness in {tries} DLS tries{note}"
        out.append(verdict(Reachability.UNDECIDED, message, "none", None, found))
    return tuple(out)


def require_reachable_3d(
    problem: CyclicIKProblem,
    *,
    interval_boxes: int = DEFAULT_INTERVAL_BOXES,
    interval_seconds: float = DEFAULT_INTERVAL_SECONDS,
) -> tuple[ReachVerdict3D, ...]:
    """Verdicts of every target; raise :class:`UnreachableTarget` for a certified one.

    Raises
    ------
    UnreachableTarget
        Naming the first unreachable target, with its certificate (the verdict
        is attached as ``verdict``).
    """
    verdicts = check_reachability_3d(
        problem, interval_boxes=interval_boxes, interval_seconds=interval_seconds
    )
    for v in verdicts:
        if v.status is Reachability.UNREACHABLE:
            raise UnreachableTarget(
                f"unreachable: {v.message}",
                index=v.index,
                target=problem.targets[v.index].position,
                verdict=v,
            )
    return verdicts
