"""Path constraints: a CasADi function of the joint state held within bounds along the motion.

A :class:`PathConstraint` is ``c(q, v)`` (one row per labelled quantity) with
lower and upper bounds; a transcription evaluates it at its knots and at its
interior points (Hermite-Simpson's midpoints, Radau's stages, the trapezoid's
interval midpoints; :meth:`Transcription.path_points
<youbot_opt.trajopt.transcription.base.Transcription.path_points>`) as inequality
blocks ``<name>_<group>`` of ``g``. Clearance (#28) is the first one
(:func:`youbot_opt.trajopt.clearance.clearance_constraint`); tool constraints
(#30) take the same form.

    PathConstraint(name="clearance", function=f, lower=margin, upper=np.inf, labels=pairs)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypeVar

import casadi as ca
import numpy as np

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError

__all__ = ["PathConstraint"]

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
    """

    name: str
    function: ca.Function
    lower: Array
    upper: Array
    labels: tuple[str, ...] = ()

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
