"""Hand-derived Lagrangian dynamics of the planar arm: the tests' reference oracle.

Test-only code, so it lives in the tests (ARCHITECTURE rule 7, as crocoddyl keeps
its reference models in ``unittest/bindings/factory.py``); tests import it as
``import _analytic as analytic``.

Codes the study's derivation (spec ``trajopt.md``, "Dynamics (Lagrangian,
derived by hand in the study)") in plain numpy, independently of Pinocchio:
``M(q) a + C(q, v) v + N(q) + b v = tau`` from planar transforms, body
Jacobians, Christoffel symbols (complex-step ``dM/dq``) and ``N = dV/dq`` by
hand. The derivation's steps: docs/design.md, "Module notes".

>>> M = mass_matrix(YOUBOT_PLANAR, q)  # (3, 3), [kg m^2]  # doctest: +SKIP
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from youbot_opt._checks import check_shape
from youbot_opt._typing import Array
from youbot_opt.robot.model import TipPose
from youbot_opt.robot.params import ArmParameters

__all__ = [
    "com_transforms",
    "body_jacobians",
    "mass_matrix",
    "mass_matrix_derivatives",
    "coriolis_matrix",
    "potential_energy",
    "gravity_torque",
    "kinetic_energy",
    "total_energy",
    "inverse_dynamics",
    "forward_dynamics",
    "tip_pose_analytic",
]

_COMPLEX_STEP = 1e-20  # [rad] imaginary step; any tiny value is exact to rounding


def _vector(name: str, x: ArrayLike, n: int) -> Array:
    """Return ``x`` as a finite float array of shape (n,), else raise ParameterError."""
    return check_shape(x, (n,), name)


def _factor(angle: Any, offset: float, com: float) -> tuple[np.ndarray, np.ndarray]:
    """Return ``g(L_{k-1}, L_k)`` and its derivative with respect to its joint angle."""
    c, s = np.cos(angle), np.sin(angle)
    g = np.array([[c, -s, offset + com * c], [s, c, com * s], [0.0, 0.0, 1.0]])
    dg = np.array([[-s, -c, -com * s], [c, -s, com * c], [0.0, 0.0, 0.0]])
    return g, dg


def _inverse(g: np.ndarray) -> np.ndarray:
    """Inverse of a planar homogeneous transform (transpose, never conjugate: complex-step safe)."""
    r_t = g[:2, :2].T
    out = np.zeros_like(g)
    out[:2, :2] = r_t
    out[:2, 2] = -r_t @ g[:2, 2]
    out[2, 2] = 1.0
    return out


def _transforms(params: ArmParameters, q: np.ndarray) -> tuple[list[Any], list[list[Any]]]:
    """Return ``g(S, L_i)`` and ``dg(S, L_i)/dq_j`` (j <= i) for every link."""
    lengths, coms = params.lengths, params.com_distances
    factors = []
    for k in range(params.n_joints):
        offset = 0.0 if k == 0 else lengths[k - 1] - coms[k - 1]
        factors.append(_factor(q[k], offset, coms[k]))
    gs: list[Any] = []
    dgs: list[list[Any]] = []
    for i in range(params.n_joints):
        g = np.eye(3, dtype=q.dtype)
        for k in range(i + 1):
            g = g @ factors[k][0]
        gs.append(g)
        cols = []
        for j in range(i + 1):
            d = np.eye(3, dtype=q.dtype)
            for k in range(i + 1):
                d = d @ (factors[k][1] if k == j else factors[k][0])
            cols.append(d)
        dgs.append(cols)
    return gs, dgs


def _body_jacobians(params: ArmParameters, q: np.ndarray) -> list[np.ndarray]:
    gs, dgs = _transforms(params, q)
    jacobians = []
    for i, g in enumerate(gs):
        g_inv = _inverse(g)
        jac = np.zeros((3, params.n_joints), dtype=q.dtype)
        for j, dg in enumerate(dgs[i]):
            xi = g_inv @ dg
            jac[:, j] = (xi[0, 2], xi[1, 2], xi[1, 0])  # vee
        jacobians.append(jac)
    return jacobians


def _mass_matrix(params: ArmParameters, q: np.ndarray) -> np.ndarray:
    out = np.zeros((params.n_joints, params.n_joints), dtype=q.dtype)
    for link, jac in zip(params.links, _body_jacobians(params, q), strict=True):
        out += jac.T @ np.diag([link.mass, link.mass, link.inertia]) @ jac
    return out


def com_transforms(params: ArmParameters, q: ArrayLike) -> tuple[Array, ...]:
    """Return the planar transforms ``g(S, L_i)`` from joint 1 to each link's COM.

    Parameters
    ----------
    params : ArmParameters
        Arm tables.
    q : array_like
        Joint angles in [rad], shape (3,).

    Returns
    -------
    tuple of numpy.ndarray
        Three 3x3 homogeneous transforms (translations in [m]) in the study's frame.
    """
    return tuple(_transforms(params, _vector("q", q, params.n_joints))[0])


def body_jacobians(params: ArmParameters, q: ArrayLike) -> tuple[Array, ...]:
    """Return the body Jacobians of the three links (vee formula of the study).

    Parameters
    ----------
    params : ArmParameters
        Arm tables.
    q : array_like
        Joint angles in [rad], shape (3,).

    Returns
    -------
    tuple of numpy.ndarray
        Three (3, 3) matrices mapping joint speeds [rad/s] to the COM frame's
        body twist ``(vx [m/s], vy [m/s], w [rad/s])``.
    """
    return tuple(_body_jacobians(params, _vector("q", q, params.n_joints)))


def mass_matrix(params: ArmParameters, q: ArrayLike) -> Array:
    """Return the joint-space inertia matrix ``M(q) = sum_i J_i^T diag(m_i, m_i, I_i) J_i``.

    Parameters
    ----------
    params : ArmParameters
        Arm tables.
    q : array_like
        Joint angles in [rad], shape (3,).

    Returns
    -------
    numpy.ndarray
        ``M`` in [kg m^2], shape (3, 3), symmetric positive definite.
    """
    return _mass_matrix(params, _vector("q", q, params.n_joints))


def mass_matrix_derivatives(params: ArmParameters, q: ArrayLike) -> Array:
    """Return ``dM/dq_h`` for every joint h, by complex-step differentiation.

    Parameters
    ----------
    params : ArmParameters
        Arm tables.
    q : array_like
        Joint angles in [rad], shape (3,).

    Returns
    -------
    numpy.ndarray
        Shape (3, 3, 3) in [kg m^2/rad]; entry ``[h, i, j]`` is ``dM_ij/dq_h``.
    """
    qa = _vector("q", q, params.n_joints)
    n = params.n_joints
    out = np.empty((n, n, n))
    for h in range(n):
        qc = qa.astype(complex)
        qc[h] += 1j * _COMPLEX_STEP
        out[h] = _mass_matrix(params, qc).imag / _COMPLEX_STEP
    return out


def coriolis_matrix(params: ArmParameters, q: ArrayLike, v: ArrayLike) -> Array:
    """Return the Christoffel Coriolis matrix ``C(q, v)`` of the study.

    ``C_ij = 1/2 sum_h (dM_ij/dq_h + dM_ih/dq_j - dM_hj/dq_i) v_h``; with this
    choice ``dM/dt - 2 C`` is skew-symmetric.

    Parameters
    ----------
    params : ArmParameters
        Arm tables.
    q : array_like
        Joint angles in [rad], shape (3,).
    v : array_like
        Joint speeds in [rad/s], shape (3,).

    Returns
    -------
    numpy.ndarray
        ``C`` in [kg m^2/s], shape (3, 3); ``C v`` is in [N m].
    """
    dm = mass_matrix_derivatives(params, q)  # [h, i, j] = dM_ij / dq_h
    va = _vector("v", v, params.n_joints)
    term1 = np.einsum("hij,h->ij", dm, va)
    term2 = np.einsum("jih,h->ij", dm, va)
    term3 = np.einsum("ihj,h->ij", dm, va)
    return 0.5 * (term1 + term2 - term3)


def potential_energy(params: ArmParameters, q: ArrayLike) -> float:
    """Return the potential energy ``V(q)`` of the study (zero at the height of joint 1).

    Parameters
    ----------
    params : ArmParameters
        Arm tables.
    q : array_like
        Joint angles in [rad] from the vertical, shape (3,).

    Returns
    -------
    float
        ``V`` in [J].
    """
    qa = _vector("q", q, params.n_joints)
    (m1, m2, m3), (l1, l2, _), (t1, t2, t3) = params.masses, params.lengths, params.com_distances
    c1, c12, c123 = np.cos(qa[0]), np.cos(qa[0] + qa[1]), np.cos(qa.sum())
    g = params.gravity
    return float(
        m1 * g * t1 * c1 + m2 * g * (l1 * c1 + t2 * c12) + m3 * g * (l1 * c1 + l2 * c12 + t3 * c123)
    )


def gravity_torque(params: ArmParameters, q: ArrayLike) -> Array:
    """Return the gravity torques ``N(q) = dV/dq`` (differentiated by hand).

    Parameters
    ----------
    params : ArmParameters
        Arm tables.
    q : array_like
        Joint angles in [rad], shape (3,).

    Returns
    -------
    numpy.ndarray
        ``N`` in [N m], shape (3,).
    """
    qa = _vector("q", q, params.n_joints)
    (m1, m2, m3), (l1, l2, _), (t1, t2, t3) = params.masses, params.lengths, params.com_distances
    s1, s12, s123 = np.sin(qa[0]), np.sin(qa[0] + qa[1]), np.sin(qa.sum())
    g = params.gravity
    n3 = -m3 * g * t3 * s123
    n2 = -m2 * g * t2 * s12 - m3 * g * l2 * s12 + n3
    n1 = -m1 * g * t1 * s1 - m2 * g * l1 * s1 - m3 * g * l1 * s1 + n2
    return np.array([n1, n2, n3])


def kinetic_energy(params: ArmParameters, q: ArrayLike, v: ArrayLike) -> float:
    """Return the kinetic energy ``v^T M(q) v / 2``.

    Parameters
    ----------
    params : ArmParameters
        Arm tables.
    q : array_like
        Joint angles in [rad], shape (3,).
    v : array_like
        Joint speeds in [rad/s], shape (3,).

    Returns
    -------
    float
        Kinetic energy in [J].
    """
    va = _vector("v", v, params.n_joints)
    return float(0.5 * va @ mass_matrix(params, q) @ va)


def total_energy(params: ArmParameters, q: ArrayLike, v: ArrayLike) -> float:
    """Return kinetic plus potential energy in [J] (see the two functions)."""
    return kinetic_energy(params, q, v) + potential_energy(params, q)


def inverse_dynamics(
    params: ArmParameters,
    q: ArrayLike,
    v: ArrayLike,
    a: ArrayLike,
    *,
    damping: float | None = None,
) -> Array:
    """Return ``tau = M(q) a + C(q, v) v + N(q) + b v``.

    Parameters
    ----------
    params : ArmParameters
        Arm tables.
    q : array_like
        Joint angles in [rad], shape (3,).
    v : array_like
        Joint speeds in [rad/s], shape (3,).
    a : array_like
        Joint accelerations in [rad/s^2], shape (3,).
    damping : float, optional
        Viscous damping ``b`` in [N m s/rad]; defaults to ``params.damping``.

    Returns
    -------
    numpy.ndarray
        Joint torques in [N m], shape (3,).
    """
    n = params.n_joints
    va, aa = _vector("v", v, n), _vector("a", a, n)
    b = params.damping if damping is None else float(damping)
    return (
        mass_matrix(params, q) @ aa
        + coriolis_matrix(params, q, va) @ va
        + gravity_torque(params, q)
        + b * va
    )


def forward_dynamics(
    params: ArmParameters,
    q: ArrayLike,
    v: ArrayLike,
    tau: ArrayLike,
    *,
    damping: float | None = None,
) -> Array:
    """Return ``a = M(q)^-1 (tau - C(q, v) v - N(q) - b v)``.

    Parameters
    ----------
    params : ArmParameters
        Arm tables.
    q : array_like
        Joint angles in [rad], shape (3,).
    v : array_like
        Joint speeds in [rad/s], shape (3,).
    tau : array_like
        Joint torques in [N m], shape (3,).
    damping : float, optional
        Viscous damping ``b`` in [N m s/rad]; defaults to ``params.damping``.

    Returns
    -------
    numpy.ndarray
        Joint accelerations in [rad/s^2], shape (3,).
    """
    n = params.n_joints
    zero = np.zeros(n)
    bias = inverse_dynamics(params, q, v, zero, damping=damping)
    rhs = _vector("tau", tau, n) - bias
    return np.asarray(np.linalg.solve(mass_matrix(params, q), rhs), dtype=float)


def tip_pose_analytic(params: ArmParameters, q: ArrayLike) -> TipPose:
    """Return the gripper-tip pose in the platform's (x, z) plane by planar trigonometry.

    With ``phi_i = q_1 + ... + q_i`` (from the vertical, positive towards -x):
    position ``(a - sum L_i sin phi_i, h + sum L_i cos phi_i)`` and rotation
    ``[[-sin phi_3, -cos phi_3], [cos phi_3, -sin phi_3]]`` (columns: tip x
    axis along the last link, tip y axis).

    Parameters
    ----------
    params : ArmParameters
        Arm tables.
    q : array_like
        Joint angles in [rad], shape (3,).

    Returns
    -------
    TipPose
        Position (2,) in [m] and rotation (2, 2).
    """
    qa = _vector("q", q, params.n_joints)
    phi = np.cumsum(qa)
    lengths = params.lengths
    m = params.mounting
    position = np.array([m.a - float(lengths @ np.sin(phi)), m.h + float(lengths @ np.cos(phi))])
    s, c = np.sin(phi[-1]), np.cos(phi[-1])
    return TipPose(position=position, rotation=np.array([[-s, -c], [c, -s]]))
