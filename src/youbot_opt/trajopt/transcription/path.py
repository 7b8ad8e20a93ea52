"""Path constraints: a CasADi function of the joint state held within bounds along the motion.

A :class:`PathConstraint` is ``c(q, v)`` (rows labelled) with lower and upper
bounds, evaluated at the knots and interior points of :meth:`Transcription.path_points
<youbot_opt.trajopt.transcription.base.Transcription.path_points>` as blocks
``<name>_<group>`` of ``g``: clearance (#28,
:func:`youbot_opt.trajopt.clearance.clearance_constraint`), tool constraints (#30).
Near a fixed end where a row misses its lower bound, a :class:`PathRamp` bounds it
by a ramp from its value there instead (the clearance balls' overshoot).

    PathConstraint(name="clearance", function=f, lower=margin, upper=np.inf, labels=pairs)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypeVar

import casadi as ca
import numpy as np

from youbot_opt._checks import check_end_window
from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError

__all__ = ["PathConstraint", "PathRamp"]

_E = TypeVar("_E", ca.SX, ca.MX)  # a CasADi expression: evaluated on either, returned alike


@dataclass(frozen=True, slots=True, kw_only=True)
class PathConstraint:
    """Bounds on ``c(q, v)`` at every point of the motion the transcription controls.

    Attributes
    ----------
    name : str
        Block name prefix in ``g`` (``"clearance"`` -> ``clearance_knots``, ...).
    function : casadi.Function
        ``(q (nv,), v (nv,)) -> c (m,)``, twice differentiable, in the rows' units.
    lower, upper : ndarray, shape (m,)
        Bounds of each row (``-inf`` / ``inf``: none); scalars are broadcast.
    labels : tuple of str
        One name per row (e.g. ``"link / obstacle"``), for reports.
    end_window : float
        Fraction of the normalised time, in [0, 0.5], over which a row below its
        lower bound at the fixed start (goal) ramps up to it (:class:`PathRamp`);
        0 (default): the bounds hold at every point, the ends included.
    """

    name: str
    function: ca.Function
    lower: Array
    upper: Array
    labels: tuple[str, ...] = ()
    end_window: float = 0.0

    def __post_init__(self) -> None:
        fn = self.function
        if not isinstance(fn, ca.Function) or fn.n_in() != 2 or fn.n_out() != 1:
            raise ParameterError(
                f"path constraint {self.name!r}: function must map (q, v) -> c", name="function"
            )
        m = int(fn.size1_out(0))
        for side in ("lower", "upper"):
            arr = np.broadcast_to(np.asarray(getattr(self, side), dtype=float), (m,)).copy()
            arr.setflags(write=False)
            object.__setattr__(self, side, arr)
        if np.any(self.lower > self.upper):
            raise ParameterError(
                f"path constraint {self.name!r}: lower bounds above upper ones", name="lower"
            )
        labels = tuple(self.labels) or tuple(f"{self.name}[{i}]" for i in range(m))
        if len(labels) != m:
            raise ParameterError(
                f"path constraint {self.name!r}: {len(labels)} labels for {m} rows", name="labels"
            )
        object.__setattr__(self, "labels", labels)
        window = check_end_window(self.end_window)
        object.__setattr__(self, "end_window", window)

    @property
    def width(self) -> int:
        """Number of rows ``m`` per point."""
        return int(self.function.size1_out(0))

    def evaluate(self, q: _E, v: _E) -> _E:
        """``c`` at ``count`` points: ``q``, ``v`` of shape ``(nv, count)`` -> ``(m, count)``."""
        mapped = self.function.map(int(q.size2()))
        if isinstance(q, ca.SX) and isinstance(v, ca.SX):
            return mapped(q, v)
        assert isinstance(q, ca.MX) and isinstance(v, ca.MX)
        return mapped(q, v)


@dataclass(frozen=True, slots=True, kw_only=True)
class PathRamp:
    """Lower bounds of one path-constraint block that ramp up from the fixed ends.

    A row whose value ``e`` at the start is below its lower bound ``b`` is held
    at or above ``e + (b - e) min(s / w, 1)`` at normalised time ``s``, and
    likewise from the goal (``1 - s``); the smaller of the two ramps and ``b``
    applies. Rows that keep ``b`` at both ends keep ``b`` everywhere.

    Attributes
    ----------
    function : casadi.Function
        The constraint's ``(q (nv,), v (nv,)) -> c (m,)``.
    window : float
        The ramp's length ``w`` in (0, 0.5], a fraction of the normalised time.
    times : ndarray, shape (count,)
        Normalised times ``s`` in [0, 1] of the block's points
        (:meth:`~youbot_opt.trajopt.transcription.base.Transcription.point_times`).
    """

    function: ca.Function
    window: float
    times: Array

    def lower(self, bound: Array, at_start: Array, at_goal: Array) -> Array:
        """Return the block's lower bounds, shape ``(count, m)``, for these ends.

        Parameters
        ----------
        bound : ndarray, shape (m,)
            The rows' own lower bounds (in the rows' units; ``-inf``: none).
        at_start, at_goal : ndarray, shape (m,)
            The rows' values :attr:`function` takes at the fixed start and goal
            (their configurations and velocities), in the rows' units.
        """
        bound = np.asarray(bound, dtype=float)
        s = np.asarray(self.times, dtype=float)[:, None]
        out = np.broadcast_to(bound, (s.shape[0], bound.size)).copy()
        for end, share in ((at_start, s), (at_goal, 1.0 - s)):
            end = np.asarray(end, dtype=float).ravel()
            short = end < bound
            if np.any(short):
                ramp = end + (bound - end) * np.minimum(share / self.window, 1.0)
                out[:, short] = np.minimum(out[:, short], ramp[:, short])
        return out
