r"""Reachability of planar tip targets, decided without sampling (spec ``docs/ikpath.md``).

Every target gets a :class:`ReachVerdict` before optimising, with its evidence:
``REACHABLE`` (a witness configuration within the limits whose tip, by Pinocchio,
is within ``tol`` = 1e-9 m), ``UNREACHABLE`` (a certified lower bound
``distance_lower > tol`` on the distance to the workspace, and the nearest
reachable point found) or ``UNDECIDED`` (limited chains of 4+ links when
``max_evaluations`` runs out: the certified distance interval). Decided by the
annulus test without limits, in closed form for 1-2 links, else by
:mod:`~youbot_opt.ikpath.reachability.branch_and_bound` (docs/ikpath.md, "Reachability").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError, UnreachableTarget
from youbot_opt.ikpath.geometry import TWO_PI, nearest_on_arc, two_link_nearest
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability import Reachability
from youbot_opt.ikpath.reachability.branch_and_bound import BranchAndBound
from youbot_opt.robot.planar import PlanarChain

__all__ = [
    "ReachVerdict",
    "decide_reachability",
    "check_reachability",
    "require_reachable",
]


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class ReachVerdict:
    """Reachability verdict of one target, with its evidence.

    Attributes
    ----------
    index : int
        0-based index of the target in its problem.
    target : ndarray, shape (2,)
        Target in [m].
    status : Reachability
        The verdict.
    method : str
        ``"annulus"``, ``"closed_form"`` or ``"branch_and_bound"``.
    witness : ndarray, shape (n,) or None
        Configuration in [rad] within the limits reaching the target (REACHABLE only).
    witness_error : float
        ``|F(witness) - target|`` in [m] by Pinocchio (NaN without witness).
    distance_lower, distance_upper : float
        Certified bounds on the distance from the target to the workspace in [m].
    nearest : ndarray, shape (2,)
        Tip position in [m] of :attr:`nearest_q`: the reachable point nearest to
        the target that was found (the target itself, up to ``tol``, if reachable).
    nearest_q : ndarray, shape (n,)
        Configuration in [rad] within the limits whose tip is :attr:`nearest`.
    reach : tuple of float
        ``(r_min, r_max)`` in [m]: radii of the workspace annulus about the base
        without joint limits.
    limited : bool
        Whether joint limits were part of the decision.
    tolerance : float
        ``tol`` in [m].
    evaluations : int
        Closed-form sub-problem evaluations used.
    """

    index: int
    target: Array
    status: Reachability
    method: str
    witness: Array | None
    witness_error: float
    distance_lower: float
    distance_upper: float
    nearest: Array
    nearest_q: Array
    reach: tuple[float, float]
    limited: bool
    tolerance: float
    evaluations: int

    @property
    def reachable(self) -> bool:
        """Whether the verdict is REACHABLE."""
        return self.status is Reachability.REACHABLE

    def describe(self) -> str:
        """One-line human-readable statement of the verdict and its evidence."""
        p = f"p{self.index + 1} = ({self.target[0]:.6g}, {self.target[1]:.6g})"
        lim = "under the joint limits" if self.limited else "without joint limits"
        reach = f"reach {self.reach[0]:.6g} <= |p - base| <= {self.reach[1]:.6g} m without limits"
        near = f"({self.nearest[0]:.6g}, {self.nearest[1]:.6g})"
        if self.status is Reachability.REACHABLE and self.witness is not None:
            return (
                f"target {p}: reachable {lim} ({self.method}); witness q = "
                f"{np.round(self.witness, 6).tolist()} rad, tip error {self.witness_error:.2g} m"
            )
        if self.status is Reachability.UNREACHABLE:
            return (
                f"target {p}: unreachable {lim} ({self.method}): at least "
                f"{self.distance_lower:.6g} m from the workspace ({reach}); nearest reachable "
                f"point {near} at {self.distance_upper:.6g} m"
            )
        return (
            f"target {p}: undecided {lim} after {self.evaluations} evaluations: "
            f"distance to the workspace in [{self.distance_lower:.3g}, "
            f"{self.distance_upper:.3g}] m ({reach}); nearest point found {near}"
        )


def theta_ranges(chain: PlanarChain, use_limits: bool) -> list[tuple[float, float]] | None:
    """``(lo, width)`` ranges in [rad] of the study angles, or None when no joint is limited.

    Used by the reachability decision and by the feasible starts
    (:func:`youbot_opt.ikpath.starts.make_starts`).
    """
    ranges = []
    limited = False
    for lo, hi, off in zip(chain.q_lower, chain.q_upper, chain.angle_offset, strict=True):
        if not use_limits or not (math.isfinite(lo) and math.isfinite(hi)) or hi - lo >= TWO_PI:
            ranges.append((-math.pi + off, TWO_PI))
        else:
            ranges.append((lo + off, hi - lo))
            limited = True
    return ranges if limited else None


def _unlimited_angles(lengths: Array, vx: float, vy: float) -> list[float]:
    """Absolute segment angles of an unlimited chain (base at 0) whose tip is at v.

    ``v`` must lie in the chain's annulus. The wrist of the first ``k - 1``
    links is put at the radius in the middle of the feasible interval, which
    keeps the construction away from singular triangles.
    """
    k = lengths.size
    if k == 1:
        return [math.atan2(vy, vx)]
    sub = lengths[:-1]
    m_sub = max(0.0, 2.0 * float(np.max(sub)) - float(np.sum(sub)))
    big_sub = float(np.sum(sub))
    lk = float(lengths[-1])
    r = math.hypot(vx, vy)
    lo, hi = max(m_sub, abs(r - lk)), min(big_sub, r + lk)
    rho = 0.5 * (lo + hi) if hi >= lo else (hi if abs(r - lk) > big_sub else lo)
    if r == 0.0:
        wx, wy = rho, 0.0
    else:
        cos_d = (r * r + rho * rho - lk * lk) / (2.0 * r * rho) if rho > 0.0 else 1.0
        delta = math.acos(min(1.0, max(-1.0, cos_d)))
        ux, uy = vx / r, vy / r
        wx = rho * (ux * math.cos(delta) - uy * math.sin(delta))
        wy = rho * (ux * math.sin(delta) + uy * math.cos(delta))
    return [*_unlimited_angles(sub, wx, wy), math.atan2(vy - wy, vx - wx)]


def _q_from_phi(chain: PlanarChain, phi: list[float]) -> Array:
    """Joint coordinates from absolute segment angles (wrapped to (-pi, pi])."""
    theta = np.diff(np.r_[0.0, phi])
    q = theta - chain.angle_offset
    return np.arctan2(np.sin(q), np.cos(q))


def _verdict(
    chain: PlanarChain,
    p: Array,
    index: int,
    *,
    status: Reachability,
    method: str,
    q: Array,
    lower: float,
    limited: bool,
    tol: float,
    evaluations: int,
) -> ReachVerdict:
    """Assemble a verdict, verifying the configuration ``q`` with Pinocchio."""
    tip = chain.tip_position(q)
    err = float(np.linalg.norm(tip - p))
    q = np.array(q, dtype=float)
    q.setflags(write=False)
    tip.setflags(write=False)
    reachable = status is Reachability.REACHABLE
    return ReachVerdict(
        index=index,
        target=p,
        status=status,
        method=method,
        witness=q if reachable else None,
        witness_error=err if reachable else math.nan,
        distance_lower=0.0 if reachable else lower,
        distance_upper=err,
        nearest=tip,
        nearest_q=q,
        reach=chain.reach,
        limited=limited,
        tolerance=tol,
        evaluations=evaluations,
    )


def _exact_verdict(
    chain: PlanarChain,
    p: Array,
    index: int,
    *,
    method: str,
    q: Array,
    distance: float,
    limited: bool,
    tol: float,
) -> ReachVerdict:
    """Verdict of a closed-form ``method`` from the exact ``distance`` [m] to the workspace.

    Reachable when ``distance <= tol``; ``q`` [rad] is the nearest configuration.
    """
    status = Reachability.REACHABLE if distance <= tol else Reachability.UNREACHABLE
    return _verdict(
        chain,
        p,
        index,
        status=status,
        method=method,
        q=q,
        lower=distance,
        limited=limited,
        tol=tol,
        evaluations=1,
    )


def _annulus(chain: PlanarChain, p: Array, index: int, tol: float, limited: bool) -> ReachVerdict:
    """Exact verdict without joint limits."""
    r_min, r_max = chain.reach
    v = p - chain.base
    r = float(np.hypot(*v))
    dist = max(0.0, r - r_max, r_min - r)
    u = v / r if r > 0.0 else np.array([1.0, 0.0])
    goal = u * min(max(r, r_min), r_max)
    q = _q_from_phi(chain, _unlimited_angles(chain.lengths, float(goal[0]), float(goal[1])))
    return _exact_verdict(
        chain, p, index, method="annulus", q=q, distance=dist, limited=limited, tol=tol
    )


def decide_reachability(
    chain: PlanarChain,
    target: ArrayLike,
    *,
    use_limits: bool = True,
    tol: float = 1e-9,
    max_evaluations: int = 20_000,
    nearest_tol: float = 1e-6,
    index: int = 0,
) -> ReachVerdict:
    """Decide whether ``chain`` can put its tip on ``target``.

    Parameters
    ----------
    chain : PlanarChain
        The arm (limits, base and angle offsets included).
    target : array_like, shape (2,)
        Target in [m].
    use_limits : bool
        Whether the chain's joint limits apply.
    tol : float
        Distance in [m] up to which a target counts as reached (> 0).
    max_evaluations : int
        Budget of closed-form evaluations for the branch and bound (n >= 3);
        once decided, at most a tenth of it is spent refining the nearest point.
    nearest_tol : float
        For unreachable targets, keep refining until the nearest point found is
        within ``max(nearest_tol, 1e-3 * distance)`` in [m] of the certified
        lower bound (or the budget runs out).
    index : int
        Index of the target, reported in the verdict.

    Returns
    -------
    ReachVerdict
        The verdict with its evidence.

    Raises
    ------
    ParameterError
        If the target is not a finite 2-vector or ``tol <= 0``.
    """
    p = np.array(target, dtype=float)
    if p.shape != (2,) or not np.all(np.isfinite(p)):
        raise ParameterError(
            f"target must be a finite 2-vector, got {target!r}", name="target", value=target
        )
    if not tol > 0.0:
        raise ParameterError(f"tol must be > 0, got {tol!r}", name="tol", value=tol)
    p.setflags(write=False)
    ranges = theta_ranges(chain, use_limits)
    if ranges is None:
        return _annulus(chain, p, index, tol, limited=False)
    if chain.n <= 2:
        return _closed_form(chain, p, ranges, index, tol)
    found = BranchAndBound(chain, p, ranges, tol, max_evaluations, nearest_tol).run()
    return _verdict(
        chain,
        p,
        index,
        status=Reachability(found.status),
        method="branch_and_bound",
        q=found.q,
        lower=found.distance_lower,
        limited=True,
        tol=tol,
        evaluations=found.evaluations,
    )


def _closed_form(
    chain: PlanarChain, p: Array, ranges: list[tuple[float, float]], index: int, tol: float
) -> ReachVerdict:
    """Exact verdict for 1- and 2-link chains with limits."""
    bx, by = float(chain.base[0]), float(chain.base[1])
    if chain.n == 1:
        d, t = nearest_on_arc(float(p[0]), float(p[1]), bx, by, float(chain.lengths[0]), *ranges[0])
        theta = np.array([ranges[0][0] + t])
    else:
        near = two_link_nearest(
            float(p[0]),
            float(p[1]),
            bx,
            by,
            0.0,
            float(chain.lengths[0]),
            float(chain.lengths[1]),
            ranges[0],
            ranges[1],
        )
        d, theta = near.distance, np.array([near.alpha, near.beta])
    q = np.clip(theta - chain.angle_offset, chain.q_lower, chain.q_upper)
    return _exact_verdict(
        chain, p, index, method="closed_form", q=q, distance=d, limited=True, tol=tol
    )


def check_reachability(problem: CyclicIKProblem, **kwargs: float) -> tuple[ReachVerdict, ...]:
    """Verdicts for every target of ``problem`` (limits as the problem says).

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    **kwargs
        ``tol``, ``max_evaluations``, ``nearest_tol`` of :func:`decide_reachability`.

    Returns
    -------
    tuple of ReachVerdict
        One verdict per target, in order.
    """
    return tuple(
        decide_reachability(
            problem.planar_chain,
            p,
            use_limits=problem.use_limits,
            index=j,
            **kwargs,  # type: ignore[arg-type]
        )
        for j, p in enumerate(problem.target_points)
    )


def require_reachable(
    problem: CyclicIKProblem, verdicts: tuple[ReachVerdict, ...] | None = None
) -> tuple[ReachVerdict, ...]:
    """Return the verdicts, raising for the first unreachable target.

    Raises
    ------
    UnreachableTarget
        Naming the target, the reach limits and the nearest reachable point;
        ``verdict`` holds the :class:`ReachVerdict`.
    """
    verdicts = check_reachability(problem) if verdicts is None else verdicts
    for v in verdicts:
        if v.status is Reachability.UNREACHABLE:
            raise UnreachableTarget(v.describe(), index=v.index, target=v.target, verdict=v)
    return verdicts
