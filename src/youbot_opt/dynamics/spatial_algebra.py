"""Spatial-algebra helpers on CasADi expressions, in Pinocchio's conventions.

A transform is ``(R, p)``, child frame in parent (``x -> R x + p``); spatial
vectors are (6, 1) with the linear part first: motions ``(v, w)`` in [m/s],
[rad/s], forces ``(f, n)`` in [N], [N m]. ``act`` / ``act_inv`` are
Pinocchio's ``SE3.act`` / ``SE3.actInv``. Arguments may be CasADi SX, MX or DM.
Reference: Featherstone, *Rigid Body Dynamics Algorithms* (2008), ch. 2.

>>> act_motion(R, p, motion)  # doctest: +SKIP
"""

from __future__ import annotations

from typing import TypeVar

import casadi as ca
import numpy as np

from youbot_opt._typing import Array

__all__ = [
    "skew",
    "compose",
    "act_motion",
    "act_inv_motion",
    "act_force",
    "act_inv_force",
    "cross_motion",
    "cross_force",
    "inertia_matrix",
    "act_inertia",
    "rotation_about_axis",
]

#: A CasADi expression: the result has the arguments' type; a DM argument (a constant) may
#: join SX or MX ones, as CasADi's own operators allow (DM listed first: all-DM gives DM).
_E = TypeVar("_E", ca.DM, ca.SX, ca.MX)


def skew(x: _E) -> _E:
    """Return the (3, 3) cross-product matrix ``[x]`` with ``[x] y = x × y``.

    Parameters
    ----------
    x : casadi expression, shape (3, 1)
        Vector in any unit.

    Returns
    -------
    casadi expression, shape (3, 3)
        Skew-symmetric matrix of ``x``.
    """
    return ca.skew(x)


def compose(
    rot_a: _E | ca.DM, pos_a: _E | ca.DM, rot_b: _E | ca.DM, pos_b: _E | ca.DM
) -> tuple[_E | ca.DM, _E | ca.DM]:
    """Compose two transforms: ``(a * b)`` maps frame c -> frame a if b: c -> b, a: b -> a.

    Parameters
    ----------
    rot_a, pos_a : casadi expressions, shapes (3, 3) and (3, 1)
        Rotation and translation in [m] of the outer transform.
    rot_b, pos_b : casadi expressions, shapes (3, 3) and (3, 1)
        Rotation and translation in [m] of the inner transform.

    Returns
    -------
    tuple of casadi expressions
        Rotation (3, 3) and translation (3, 1) in [m] of ``a * b``; each one DM if
        its own inputs are (the rotation of two DM rotations is DM).
    """
    return ca.mtimes(rot_a, rot_b), pos_a + ca.mtimes(rot_a, pos_b)


def act_motion(rot: _E | ca.DM, pos: _E | ca.DM, motion: _E | ca.DM) -> _E:
    """Map a motion vector from the child frame to the parent frame.

    Parameters
    ----------
    rot, pos : casadi expressions, shapes (3, 3) and (3, 1)
        Transform child -> parent; translation in [m].
    motion : casadi expression, shape (6, 1)
        Motion ``(v, w)`` in the child frame.

    Returns
    -------
    casadi expression, shape (6, 1)
        The same motion in the parent frame: ``(R v + p × R w, R w)``.
    """
    w = ca.mtimes(rot, motion[3:6])
    v = ca.mtimes(rot, motion[0:3]) + ca.cross(pos, w)
    return ca.vertcat(v, w)


def act_inv_motion(rot: _E | ca.DM, pos: _E | ca.DM, motion: _E | ca.DM) -> _E:
    """Map a motion vector from the parent frame to the child frame.

    Parameters
    ----------
    rot, pos : casadi expressions, shapes (3, 3) and (3, 1)
        Transform child -> parent; translation in [m].
    motion : casadi expression, shape (6, 1)
        Motion ``(v, w)`` in the parent frame.

    Returns
    -------
    casadi expression, shape (6, 1)
        The same motion in the child frame: ``(Rᵀ (v - p × w), Rᵀ w)``.
    """
    w = motion[3:6]
    v = motion[0:3] - ca.cross(pos, w)
    return ca.vertcat(ca.mtimes(rot.T, v), ca.mtimes(rot.T, w))


def act_force(rot: _E | ca.DM, pos: _E | ca.DM, force: _E | ca.DM) -> _E:
    """Map a force vector from the child frame to the parent frame.

    Parameters
    ----------
    rot, pos : casadi expressions, shapes (3, 3) and (3, 1)
        Transform child -> parent; translation in [m].
    force : casadi expression, shape (6, 1)
        Force ``(f, n)`` in the child frame, [N] and [N m].

    Returns
    -------
    casadi expression, shape (6, 1)
        The same force in the parent frame: ``(R f, R n + p × R f)``.
    """
    f = ca.mtimes(rot, force[0:3])
    n = ca.mtimes(rot, force[3:6]) + ca.cross(pos, f)
    return ca.vertcat(f, n)


def act_inv_force(rot: _E | ca.DM, pos: _E | ca.DM, force: _E | ca.DM) -> _E:
    """Map a force vector from the parent frame to the child frame.

    Parameters
    ----------
    rot, pos : casadi expressions, shapes (3, 3) and (3, 1)
        Transform child -> parent; translation in [m].
    force : casadi expression, shape (6, 1)
        Force ``(f, n)`` in the parent frame, [N] and [N m].

    Returns
    -------
    casadi expression, shape (6, 1)
        The same force in the child frame: ``(Rᵀ f, Rᵀ (n - p × f))``.
    """
    f = force[0:3]
    n = force[3:6] - ca.cross(pos, f)
    return ca.vertcat(ca.mtimes(rot.T, f), ca.mtimes(rot.T, n))


def cross_motion(motion: _E | ca.DM, other: _E | ca.DM) -> _E:
    """Spatial cross product of two motions, ``motion × other``.

    Parameters
    ----------
    motion, other : casadi expressions, shape (6, 1)
        Motions ``(v, w)`` in the same frame.

    Returns
    -------
    casadi expression, shape (6, 1)
        ``(w × v' + v × w', w × w')`` where ``other = (v', w')``.
    """
    v, w = motion[0:3], motion[3:6]
    v2, w2 = other[0:3], other[3:6]
    return ca.vertcat(ca.cross(w, v2) + ca.cross(v, w2), ca.cross(w, w2))


def cross_force(motion: _E | ca.DM, force: _E | ca.DM) -> _E:
    """Spatial cross product of a motion with a force, ``motion ×* force``.

    Parameters
    ----------
    motion : casadi expression, shape (6, 1)
        Motion ``(v, w)``.
    force : casadi expression, shape (6, 1)
        Force ``(f, n)`` in the same frame.

    Returns
    -------
    casadi expression, shape (6, 1)
        ``(w × f, w × n + v × f)``.
    """
    v, w = motion[0:3], motion[3:6]
    f, n = force[0:3], force[3:6]
    return ca.vertcat(ca.cross(w, f), ca.cross(w, n) + ca.cross(v, f))


def inertia_matrix(mass: float, lever: Array, rotational: Array) -> Array:
    """Return the (6, 6) spatial inertia of a body about its frame origin.

    Parameters
    ----------
    mass : float
        Body mass in [kg].
    lever : ndarray, shape (3,)
        Centre of mass in the body frame in [m].
    rotational : ndarray, shape (3, 3)
        Rotational inertia about the centre of mass in [kg m^2].

    Returns
    -------
    ndarray, shape (6, 6)
        ``[[m 1, -m [c]], [m [c], I_c - m [c][c]]]`` (Pinocchio ``Inertia.matrix()``).
    """
    c = np.asarray(lever, dtype=float).reshape(3)
    cx = np.array([[0.0, -c[2], c[1]], [c[2], 0.0, -c[0]], [-c[1], c[0], 0.0]])
    out = np.zeros((6, 6))
    out[:3, :3] = mass * np.eye(3)
    out[:3, 3:] = -mass * cx
    out[3:, :3] = mass * cx
    out[3:, 3:] = np.asarray(rotational, dtype=float) - mass * cx @ cx
    return out


def _force_action_matrix(rot: _E | ca.DM, pos: _E | ca.DM) -> _E:
    """Return the (6, 6) matrix of :func:`act_force` for the transform ``(rot, pos)``."""
    zero = ca.DM.zeros(3, 3)
    return ca.vertcat(
        ca.horzcat(rot, zero),
        ca.horzcat(ca.mtimes(ca.skew(pos), rot), rot),
    )


def act_inertia(rot: _E | ca.DM, pos: _E | ca.DM, inertia: _E | ca.DM) -> _E:
    """Express a (6, 6) spatial inertia of the child frame in the parent frame.

    Parameters
    ----------
    rot, pos : casadi expressions, shapes (3, 3) and (3, 1)
        Transform child -> parent; translation in [m].
    inertia : casadi expression, shape (6, 6)
        Spatial inertia (or articulated inertia) in the child frame.

    Returns
    -------
    casadi expression, shape (6, 6)
        ``X* I X*ᵀ`` with ``X*`` the force action matrix of the transform.
    """
    xf = _force_action_matrix(rot, pos)
    return ca.mtimes(ca.mtimes(xf, inertia), xf.T)


def rotation_about_axis(axis: Array, angle: _E) -> _E:
    """Rotation matrix for ``angle`` [rad] about a unit ``axis`` (Rodrigues).

    Exact closed forms are used for the coordinate axes (Pinocchio's RX/RY/RZ);
    other axes use ``cos θ 1 + sin θ [u] + (1 - cos θ) u uᵀ`` as Pinocchio's
    ``RevoluteUnaligned`` joint does.

    Parameters
    ----------
    axis : ndarray, shape (3,)
        Unit rotation axis.
    angle : casadi expression, scalar
        Rotation angle in [rad].

    Returns
    -------
    casadi expression, shape (3, 3)
        Rotation matrix.
    """
    u = np.asarray(axis, dtype=float).reshape(3)
    c, s = ca.cos(angle), ca.sin(angle)
    if np.array_equal(u, [1.0, 0.0, 0.0]):
        return ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c, -s), ca.horzcat(0, s, c))
    if np.array_equal(u, [0.0, 1.0, 0.0]):
        return ca.vertcat(ca.horzcat(c, 0, s), ca.horzcat(0, 1, 0), ca.horzcat(-s, 0, c))
    if np.array_equal(u, [0.0, 0.0, 1.0]):
        return ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))
    outer = np.outer(u, u)
    ux = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    return c * ca.DM.eye(3) + s * ca.DM(ux) + (1 - c) * ca.DM(outer)
