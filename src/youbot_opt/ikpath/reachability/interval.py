"""Interval forward kinematics of a Pinocchio chain over boxes of joint values (issue 14).

:class:`IntervalChain` bounds the world placement of a frame for every joint
value in a box: interval sine and cosine of each revolute joint's range,
interval rotations (Rodrigues) and translations (prismatic) composed along the
chain with the model's fixed placements, batched over many boxes. Every bound
is widened outwards so that it contains the exact placement *and* any float64
evaluation of it (Pinocchio's): see docs/ikpath.md, "Interval reachability".

>>> chain = IntervalChain.from_model(model, frame_id)
>>> bounds = chain.placement(lower, upper)  # bounds.rotation: Interval (B, 3, 3)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError

__all__ = [
    "Interval",
    "IntervalChain",
    "IntervalPlacement",
    "ROUNDING_RELATIVE",
    "TRIG_ABSOLUTE",
    "add",
    "matmul",
    "matmul_point",
    "mul",
    "point",
    "sin_cos",
]

ROUNDING_RELATIVE = 4e-15
"""Outward widening of every interval operation, relative to the sum of the magnitudes
of its terms: 36 unit roundoffs, above Higham's gamma_n = n u / (1 - n u) for the
inner products of n <= 4 terms used here, and above gamma_9 for a float64 evaluation
of the chain that associates the products differently (Pinocchio's)."""

TRIG_ABSOLUTE = 1e-14
"""Outward widening [1] of interval sin and cos: 45 ulp of 1.0, well above the error
of the libm and numpy SIMD float64 sin/cos (a few ulp)."""

_TINY = 1e-300  # absolute widening: covers underflow of products of tiny numbers
_REVOLUTE = {
    "JointModelRX": (1.0, 0.0, 0.0),
    "JointModelRY": (0.0, 1.0, 0.0),
    "JointModelRZ": (0.0, 0.0, 1.0),
    "JointModelRUBX": (1.0, 0.0, 0.0),
    "JointModelRUBY": (0.0, 1.0, 0.0),
    "JointModelRUBZ": (0.0, 0.0, 1.0),
}
_PRISMATIC = {
    "JointModelPX": (1.0, 0.0, 0.0),
    "JointModelPY": (0.0, 1.0, 0.0),
    "JointModelPZ": (0.0, 0.0, 1.0),
}
_UNALIGNED = {
    "JointModelRevoluteUnaligned": "revolute",
    "JointModelRevoluteUnboundedUnaligned": "revolute",
    "JointModelPrismaticUnaligned": "prismatic",
}


class Interval(NamedTuple):
    """Elementwise interval ``[lo, hi]`` of arrays of equal shape."""

    lo: Array
    hi: Array


def _widened(lo: Array, hi: Array, magnitude: Array) -> Interval:
    pad = ROUNDING_RELATIVE * magnitude + _TINY
    return Interval(lo - pad, hi + pad)


def point(value: Array) -> Interval:
    """Return the degenerate interval ``[value, value]``."""
    arr = np.asarray(value, dtype=float)
    return Interval(arr, arr)


def _extremum_inside(lo: Array, hi: Array, phase: float) -> npt.NDArray[np.bool_]:
    """Whether ``phase + 2 k pi`` lies in ``[lo, hi]`` for some integer k (errs towards True)."""
    k = np.ceil((lo - phase) / (2.0 * math.pi) - 1e-9)
    return phase + 2.0 * math.pi * k <= hi + 1e-9


def sin_cos(lo: Array, hi: Array) -> tuple[Interval, Interval]:
    """Intervals containing ``sin`` and ``cos`` of every angle in ``[lo, hi]`` [rad].

    Endpoint values, the extrema ``+-1`` where ``[lo, hi]`` contains one, widened by
    :data:`TRIG_ABSOLUTE` and clipped to ``[-1, 1]``.
    """
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    out = []
    for fn, top, bottom in ((np.sin, 0.5 * math.pi, -0.5 * math.pi), (np.cos, 0.0, math.pi)):
        a, b = fn(lo), fn(hi)
        low = np.where(_extremum_inside(lo, hi, bottom), -1.0, np.minimum(a, b))
        high = np.where(_extremum_inside(lo, hi, top), 1.0, np.maximum(a, b))
        out.append(
            Interval(np.maximum(low - TRIG_ABSOLUTE, -1.0), np.minimum(high + TRIG_ABSOLUTE, 1.0))
        )
    return out[0], out[1]


def _scaled(coefficient: Array, x: Interval) -> tuple[Array, Array, Array]:
    """``c x`` for point ``c``: (lo, hi, magnitude) before widening."""
    p, q = coefficient * x.lo, coefficient * x.hi
    return np.minimum(p, q), np.maximum(p, q), np.maximum(np.abs(p), np.abs(q))


def matmul(a: Interval, b: Interval) -> Interval:
    """Interval matrix product ``a @ b`` over the last two axes (broadcast batch axes)."""
    a_lo, a_hi = a.lo[..., :, :, None], a.hi[..., :, :, None]
    b_lo, b_hi = b.lo[..., None, :, :], b.hi[..., None, :, :]
    products = (a_lo * b_lo, a_lo * b_hi, a_hi * b_lo, a_hi * b_hi)
    low = np.minimum(np.minimum(products[0], products[1]), np.minimum(products[2], products[3]))
    high = np.maximum(np.maximum(products[0], products[1]), np.maximum(products[2], products[3]))
    magnitude = np.maximum(np.abs(low), np.abs(high)).sum(axis=-2)
    return _widened(low.sum(axis=-2), high.sum(axis=-2), magnitude)


def matmul_point(a: Interval, b: Array) -> Interval:
    """Interval matrices ``a`` (..., m, k) times one point matrix ``b`` (k, p): ``a @ b``."""
    rows = a.lo.shape[:-1]  # (..., i): one 2-D product for all batch rows (fast BLAS)
    shape = (*rows, b.shape[-1])
    lo, hi = a.lo.reshape(-1, a.lo.shape[-1]), a.hi.reshape(-1, a.hi.shape[-1])
    pos, neg = np.maximum(b, 0.0), np.minimum(b, 0.0)
    magnitude = (np.maximum(np.abs(lo), np.abs(hi)) @ np.abs(b)).reshape(shape)
    low = (lo @ pos + hi @ neg).reshape(shape)
    return _widened(low, (hi @ pos + lo @ neg).reshape(shape), magnitude)


def mul(a: Interval, b: Interval) -> Interval:
    """Elementwise interval product ``a * b``."""
    products = (a.lo * b.lo, a.lo * b.hi, a.hi * b.lo, a.hi * b.hi)
    low = np.minimum(np.minimum(products[0], products[1]), np.minimum(products[2], products[3]))
    high = np.maximum(np.maximum(products[0], products[1]), np.maximum(products[2], products[3]))
    return _widened(low, high, np.maximum(np.abs(low), np.abs(high)))


def add(a: Interval, b: Interval) -> Interval:
    """Interval sum ``a + b``."""
    magnitude = np.maximum(np.abs(a.lo), np.abs(a.hi)) + np.maximum(np.abs(b.lo), np.abs(b.hi))
    return _widened(a.lo + b.lo, a.hi + b.hi, magnitude)


def _plane(axis: Array) -> tuple[int, int] | None:
    """``(k+1, k+2) mod 3`` if ``axis`` is exactly the coordinate axis ``e_k``, else None."""
    for k in range(3):
        if np.array_equal(axis, np.eye(3)[k]):
            return (k + 1) % 3, (k + 2) % 3
    return None


class IntervalPlacement(NamedTuple):
    """Bounds of a frame's placement over a batch of B joint boxes.

    Attributes
    ----------
    rotation : Interval
        World rotation matrix of the frame, shape (B, 3, 3).
    translation : Interval
        World position of the frame [m], shape (B, 3).
    origins : Interval
        World position of each joint's origin [m], shape (B, n, 3).
    reach : ndarray, shape (B, n)
        Upper bound [m] of the distance from each joint's origin to the frame.
    """

    rotation: Interval
    translation: Interval
    origins: Interval
    reach: Array


@dataclass(frozen=True, slots=True)
class _Joint:
    revolute: bool
    axis: Array  # unit axis in the joint frame
    rotation: Array  # fixed placement from the parent joint, rotation (3, 3)
    translation: Array  # and translation (3,) [m]
    name: str
    plane: tuple[int, int] | None  # (k+1, k+2) mod 3 for a joint about axis e_k, else None


@dataclass(frozen=True, slots=True)
class IntervalChain:
    """Interval forward kinematics of one frame of a Pinocchio model.

    Attributes
    ----------
    joints : tuple
        The 1-DoF joints that move the frame, root first (internal records).
    frame_rotation, frame_translation : ndarray
        Placement of the frame in its parent joint, (3, 3) and (3,) [m].
    """

    joints: tuple[_Joint, ...]
    frame_rotation: Array
    frame_translation: Array

    @classmethod
    def from_model(cls, model: pin.Model, frame_id: int) -> IntervalChain:
        """Build the chain of joints that move frame ``frame_id``.

        Raises
        ------
        ParameterError
            If a joint of the chain is not revolute (aligned, unaligned or
            continuous) or prismatic (aligned or unaligned).
        """
        frame = model.frames[int(frame_id)]
        joints = []
        for j in (j for j in model.supports[frame.parentJoint] if j > 0):
            joint = model.joints[j]
            kind = joint.shortname()
            if kind in _REVOLUTE or kind in _PRISMATIC:
                revolute = kind in _REVOLUTE
                axis = np.array(_REVOLUTE[kind] if revolute else _PRISMATIC[kind])
            elif kind in _UNALIGNED:
                revolute = _UNALIGNED[kind] == "revolute"
                axis = np.array(joint.extract().axis, dtype=float)
            else:
                supported = ", ".join([*_REVOLUTE, *_PRISMATIC, *_UNALIGNED])
                raise ParameterError(
                    f"joint {model.names[j]!r} is a {kind}; interval kinematics supports "
                    f"{supported}",
                    name="model",
                    value=model.names[j],
                )
            placement = model.jointPlacements[j]
            joints.append(
                _Joint(
                    revolute,
                    axis,
                    np.array(placement.rotation),
                    np.array(placement.translation),
                    str(model.names[j]),
                    _plane(axis) if revolute else None,
                )
            )
        return cls(
            tuple(joints), np.array(frame.placement.rotation), np.array(frame.placement.translation)
        )

    @property
    def n_joints(self) -> int:
        """Number of joints ``n``."""
        return len(self.joints)

    @property
    def revolute(self) -> Array:
        """Bool (n,): which joints are revolute (the others are prismatic)."""
        return np.array([j.revolute for j in self.joints])

    def levers(self) -> Array:
        """Upper bound [m] on the distance from each joint's origin to the frame, shape (n,).

        Sum of the fixed offsets beyond the joint (prismatic travel excluded).
        """
        offsets = [float(np.linalg.norm(j.translation)) for j in self.joints[1:]]
        offsets.append(float(np.linalg.norm(self.frame_translation)))
        return np.cumsum(offsets[::-1])[::-1]

    def placement(self, lower: Array, upper: Array) -> IntervalPlacement:
        """Intervals of the frame's world placement (and of the joint origins) over joint boxes.

        Parameters
        ----------
        lower, upper : ndarray, shape (B, n)
            Boxes of joint values [rad] (revolute) or [m] (prismatic), ``lower <= upper``.

        Returns
        -------
        IntervalPlacement
            Bounds of the frame's rotation and translation, of each joint's
            origin, and of each origin's distance to the frame.
        """
        lower, upper = np.atleast_2d(lower), np.atleast_2d(upper)
        batch = lower.shape[0]
        rot = point(np.broadcast_to(np.eye(3), (batch, 3, 3)))
        pos = point(np.zeros((batch, 3, 1)))
        origins_lo, origins_hi = [], []
        for k, joint in enumerate(self.joints):
            # parent -> joint: the fixed placement (a point), then the joint's motion.
            pos = add(matmul_point(rot, joint.translation[:, None]), pos)
            origins_lo.append(pos.lo[..., 0])
            origins_hi.append(pos.hi[..., 0])
            rot = matmul_point(rot, joint.rotation)
            if joint.revolute and joint.plane is not None:
                rot = self._turn(rot, joint.plane, lower[:, k], upper[:, k])
            elif joint.revolute:
                rot = matmul(rot, self._rotation(joint.axis, lower[:, k], upper[:, k]))
            else:  # translation q u along the axis, in the joint frame
                travel = Interval(lower[:, k, None, None], upper[:, k, None, None])
                pos = add(mul(matmul_point(rot, joint.axis[:, None]), travel), pos)
        pos = add(matmul_point(rot, self.frame_translation[:, None]), pos)
        rot = matmul_point(rot, self.frame_rotation)
        # |frame - origin_k| <= offsets beyond k + travel of prismatic joints from k on;
        # the factor covers the rounding of the norms and sums (a few ulp).
        norms = np.array([float(np.linalg.norm(j.axis)) for j in self.joints])
        stroke = np.where(self.revolute, 0.0, np.maximum(np.abs(lower), np.abs(upper)) * norms)
        reach = (self.levers() + np.cumsum(stroke[:, ::-1], axis=1)[:, ::-1]) * (1.0 + 1e-12)
        origins = Interval(np.stack(origins_lo, axis=1), np.stack(origins_hi, axis=1))
        return IntervalPlacement(rot, Interval(pos.lo[..., 0], pos.hi[..., 0]), origins, reach)

    @staticmethod
    def _turn(rot: Interval, plane: tuple[int, int], lower: Array, upper: Array) -> Interval:
        """``rot @ R_k(q)`` for a coordinate axis ``e_k``: columns ``(i, j) = (k+1, k+2) mod 3``.

        ``R_k`` turns the plane ``(e_i, e_j)``: new column i is ``col_i cos + col_j sin``,
        new column j is ``col_j cos - col_i sin``; column k is unchanged.
        """
        s, c = sin_cos(lower, upper)
        s = Interval(s.lo[:, None], s.hi[:, None])
        c = Interval(c.lo[:, None], c.hi[:, None])
        i, j = plane
        col_i = Interval(rot.lo[:, :, i], rot.hi[:, :, i])
        col_j = Interval(rot.lo[:, :, j], rot.hi[:, :, j])
        new_i = add(mul(col_i, c), mul(col_j, s))
        new_j = add(mul(col_j, c), mul(col_i, Interval(-s.hi, -s.lo)))
        lo, hi = rot.lo.copy(), rot.hi.copy()
        lo[:, :, i], hi[:, :, i] = new_i
        lo[:, :, j], hi[:, :, j] = new_j
        return Interval(lo, hi)

    @staticmethod
    def _rotation(axis: Array, lower: Array, upper: Array) -> Interval:
        """Rotations about ``axis`` by every angle in ``[lower, upper]``, shape (B, 3, 3).

        ``R = u u^T + (I - u u^T) cos + [u]_x sin``: each entry is affine in the
        (independent) intervals of sin and cos, so its bounds are exact up to widening.
        """
        s, c = sin_cos(lower, upper)
        outer = np.outer(axis, axis)
        const = outer[None]
        c_coef = (np.eye(3) - outer)[None]
        s_coef = np.array(pin.skew(axis))[None]
        c_lo, c_hi, c_mag = _scaled(c_coef, Interval(c.lo[:, None, None], c.hi[:, None, None]))
        s_lo, s_hi, s_mag = _scaled(s_coef, Interval(s.lo[:, None, None], s.hi[:, None, None]))
        return _widened(const + c_lo + s_lo, const + c_hi + s_hi, np.abs(const) + c_mag + s_mag)
