"""Branch and bound reachability search for limited chains of 3+ links (internal).

Used by :func:`youbot_opt.ikpath.reachability.planar.decide_reachability`, which
turns the :class:`SearchOutcome` into a verdict. Boxes of the first ``n - 2``
angles are bounded below by the exact distance to the last two links'
workspace minus a rigorous Lipschitz term, and bisected until decided (spec
``docs/ikpath.md``); the bound and its rounding margin are derived in
docs/design.md, "Module notes". :func:`bisect_boxes` (split boxes on their widest
weighted side) is shared with the 3-D interval search.
"""

from __future__ import annotations

import heapq
import itertools
import math
from typing import NamedTuple

import numpy as np
from scipy.optimize import least_squares

from youbot_opt._typing import Array
from youbot_opt.ikpath.geometry import two_link_nearest
from youbot_opt.robot.planar import PlanarChain

__all__ = ["BranchAndBound", "SearchOutcome", "bisect_boxes"]


def bisect_boxes(lower: Array, upper: Array, scale: Array) -> tuple[Array, Array]:
    """Split boxes in two at the midpoint of their widest scaled side.

    Parameters
    ----------
    lower, upper : ndarray, shape (B, n)
        Boxes, one per row.
    scale : ndarray, shape (n,)
        Weight of each side: the side split is ``argmax(scale * (upper - lower))``
        (first on ties), e.g. a lever arm [m/rad] so that angle widths compare in [m].

    Returns
    -------
    lower, upper : ndarray, shape (2 B, n)
        The lower halves (rows ``0..B-1``), then the upper halves.
    """
    rows = np.arange(lower.shape[0])
    side = np.argmax((upper - lower) * scale, axis=1)
    mid = 0.5 * (lower[rows, side] + upper[rows, side])
    left_upper, right_lower = upper.copy(), lower.copy()
    left_upper[rows, side] = mid
    right_lower[rows, side] = mid
    return np.concatenate([lower, right_lower]), np.concatenate([left_upper, upper])


class SearchOutcome(NamedTuple):
    """What the search decided.

    Attributes
    ----------
    status : str
        ``"reachable"``, ``"unreachable"`` or ``"undecided"`` (the values of
        :class:`~youbot_opt.ikpath.reachability.Reachability`).
    q : ndarray, shape (n,)
        Best configuration found in [rad], within the limits (the witness if reachable).
    distance_lower : float
        Certified lower bound on the distance to the workspace in [m] (0 if reachable).
    evaluations : int
        Closed-form sub-problem evaluations used.
    """

    status: str
    q: Array
    distance_lower: float
    evaluations: int


class BranchAndBound:
    """Lipschitz branch and bound over the first n - 2 angles (see the module docstring)."""

    def __init__(
        self,
        chain: PlanarChain,
        p: Array,
        ranges: list[tuple[float, float]],
        tol: float,
        max_evaluations: int,
        nearest_tol: float,
    ) -> None:
        self.chain, self.p, self.ranges, self.tol = chain, p, ranges, tol
        self.max_evaluations, self.nearest_tol = max_evaluations, nearest_tol
        self.m = chain.n - 2
        self.lengths = [float(v) for v in chain.lengths]
        self.margin = 1e-12 * (1.0 + float(np.hypot(*(p - chain.base))) + sum(self.lengths))
        self.px, self.py = float(p[0]), float(p[1])
        self.evaluations = 0
        self.best_d = math.inf
        self.best_theta = np.array([r[0] for r in ranges])
        self.polishes = 0
        self.last_polish = math.inf
        r_min, r_max = chain.reach
        r = math.hypot(self.px - float(chain.base[0]), self.py - float(chain.base[1]))
        self.annulus_gap = max(0.0, r - r_max, r_min - r)  # exact distance without limits

    def _g(self, outer: Array) -> tuple[float, Array | None, list[tuple[float, float]]]:
        """Exact distance for fixed outer angles, the full theta if it is the best, joints."""
        self.evaluations += 1
        x, y = float(self.chain.base[0]), float(self.chain.base[1])
        phi = 0.0
        joints = [(x, y)]
        for k in range(self.m):
            phi += float(outer[k])
            x += self.lengths[k] * math.cos(phi)
            y += self.lengths[k] * math.sin(phi)
            joints.append((x, y))
        near = two_link_nearest(
            self.px,
            self.py,
            x,
            y,
            phi,
            self.lengths[self.m],
            self.lengths[self.m + 1],
            self.ranges[self.m],
            self.ranges[self.m + 1],
        )
        theta = None
        if near.distance < self.best_d:
            theta = np.append(outer, (near.alpha, near.beta))
            self.best_d, self.best_theta = near.distance, theta
        return near.distance, theta, joints

    def _lipschitz(self, joints: list[tuple[float, float]], half: Array) -> float:
        """``sum_k rho_k h_k`` for a box with the given centre joint positions."""
        px, py = float(self.p[0]), float(self.p[1])
        total = 0.0
        for k in range(self.m):
            rho = math.hypot(px - joints[k][0], py - joints[k][1])
            rho += sum(half[i] * sum(self.lengths[i:k]) for i in range(k))
            total += rho * float(half[k])
        return total

    def _q(self, theta: Array) -> Array:
        return np.clip(theta - self.chain.angle_offset, self.chain.q_lower, self.chain.q_upper)

    def _witness_ok(self, theta: Array) -> bool:
        q = self._q(theta)
        return float(np.linalg.norm(self.chain.tip_position(q) - self.p)) <= self.tol

    def _should_polish(self, bound: float) -> bool:
        """Polish near a sliver (tiny distance) or to tighten the nearest point once decided."""
        if self.polishes >= 4:
            return False
        if bound > self.tol:  # decided unreachable: improve the nearest point
            return self.best_d < 0.5 * self.last_polish
        return self.best_d <= 1e-4 * self.margin * 1e12 and self.best_d < 0.1 * self.last_polish

    def _polish(self) -> bool:
        """Local bounded least squares from the best point; True if it reaches p."""
        self.polishes += 1
        self.last_polish = self.best_d
        chain, lo, hi = self.chain, self.chain.q_lower, self.chain.q_upper
        q0 = self._q(self.best_theta)
        free = hi > lo
        data = chain.create_data()

        def full(z: Array) -> Array:
            q = q0.copy()
            q[free] = z
            return q

        def res(z: Array) -> Array:
            return chain.tip_position(full(z), data) - self.p

        def jac(z: Array) -> Array:
            return chain.tip_jacobian(full(z), data)[:, free]

        sol = least_squares(
            res,
            q0[free],
            jac=jac,
            bounds=(lo[free], hi[free]),
            method="trf",
            xtol=1e-14,
            ftol=1e-15,
            gtol=1e-15,
            max_nfev=40,
        )
        q = np.clip(full(sol.x), lo, hi)
        d = float(np.linalg.norm(chain.tip_position(q) - self.p))
        if d < self.best_d:
            self.best_d, self.best_theta = d, q + chain.angle_offset
        return d <= self.tol

    def _result(self, status: str, lower: float) -> SearchOutcome:
        return SearchOutcome(status, self._q(self.best_theta), lower, self.evaluations)

    def run(self) -> SearchOutcome:
        """Search until decided (and the nearest point is accurate) or out of budget."""
        lo = np.array([r[0] for r in self.ranges[: self.m]])
        hi = lo + np.array([r[1] for r in self.ranges[: self.m]])
        if self.m <= 10:  # the root box's corners: targets reachable only at a limit
            for corner in itertools.product(*zip(lo, hi, strict=True)):
                self._g(np.array(corner))
                if self.best_d <= self.tol and self._witness_ok(self.best_theta):
                    return self._result("reachable", 0.0)
        counter = itertools.count()
        heap: list[tuple[float, int, Array, Array]] = []

        def push(b_lo: Array, b_hi: Array) -> bool:
            centre, half = 0.5 * (b_lo + b_hi), 0.5 * (b_hi - b_lo)
            d, theta, joints = self._g(centre)
            if theta is not None and d <= self.tol and self._witness_ok(theta):
                return True
            bound = d - self._lipschitz(joints, half) - self.margin
            heapq.heappush(heap, (bound, next(counter), b_lo, b_hi))
            return False

        if push(lo, hi):
            return self._result("reachable", 0.0)
        decided_at = None
        while heap:
            bound, _, b_lo, b_hi = heap[0]
            bound = max(bound, self.annulus_gap)
            if bound > self.tol and decided_at is None:
                decided_at = self.evaluations
            gap = max(self.nearest_tol, 1e-3 * self.best_d)
            if bound > self.tol and self.best_d - bound <= gap:
                return self._result("unreachable", bound)
            spent = self.evaluations - (decided_at or 0)
            if self.evaluations >= self.max_evaluations or (
                decided_at is not None and spent >= self.max_evaluations // 10
            ):
                status = "unreachable" if bound > self.tol else "undecided"
                return self._result(status, max(bound, 0.0))
            if self._should_polish(bound) and self._polish() and self._witness_ok(self.best_theta):
                return self._result("reachable", 0.0)
            heapq.heappop(heap)
            if bound > self.best_d:
                continue
            # Outer angles weigh more: they swing the longer rest of the chain.
            lows, highs = bisect_boxes(b_lo[None], b_hi[None], np.arange(self.m + 1.0, 1.0, -1.0))
            if push(lows[0], highs[0]) or push(lows[1], highs[1]):
                return self._result("reachable", 0.0)
        return self._result("unreachable", max(self.best_d, self.annulus_gap))
