"""Independent check of an IK-path result: :func:`check_ik_result`.

Recomputes the tip positions of every configuration with the study's closed
form ``F = b + sum_i l_i (cos phi_i, sin phi_i)`` in NumPy (neither Pinocchio
nor CasADi, which the solvers use), the energy ``E`` and the joint-limit
excess, and compares them with the targets and with the reported figures
(spec ``ikpath.md``). Used by the property tests of the IK solvers.

>>> check = check_ik_result(solve(problem))  # doctest: +SKIP
>>> check.passed, check.residual
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.ikpath.result import IKPathResult

__all__ = ["IKCheck", "check_ik_result"]


class IKCheck(NamedTuple):
    """Verdict of :func:`check_ik_result` on an IK-path result.

    Attributes
    ----------
    passed : bool
        Finite, every target met within ``residual_tol``, limits within
        ``limit_tol`` and the reported figures equal to the recomputed ones.
    message : str
        What failed (empty when nothing did).
    residual : float
        Largest ``|F(q_j) - p_j|`` in [m] by the study's closed-form kinematics
        (not Pinocchio, not CasADi); ``inf`` when not finite.
    limit_violation : float
        Largest joint-limit excess in [rad] (0 without limits).
    """

    passed: bool
    message: str
    residual: float
    limit_violation: float


def check_ik_result(
    result: IKPathResult, *, residual_tol: float = 1e-8, limit_tol: float = 1e-12
) -> IKCheck:
    """Check an IK-path result independently of the solver that produced it.

    The tip positions come from the study's formula
    ``F = b + sum_i l_i (cos phi_i, sin phi_i)``, ``phi_i = sum_{k <= i} (q_k +
    offset_k)`` evaluated here with NumPy; ``E`` is recomputed from the
    configurations.

    Parameters
    ----------
    result : IKPathResult
        The result to check.
    residual_tol : float, optional
        Largest accepted target residual in [m] (the solvers' defaults reach ~1e-10).
    limit_tol : float, optional
        Largest accepted joint-limit excess in [rad] (both solvers keep their
        iterates inside the box).

    Returns
    -------
    IKCheck
        The verdict and the recomputed figures.
    """
    problem = result.problem
    chain = problem.planar_chain
    q = np.asarray(result.configurations, dtype=float)
    inf = math.inf
    if q.shape != (problem.n_targets, chain.n):
        want = (problem.n_targets, chain.n)
        return IKCheck(False, f"configurations have shape {q.shape}, want {want}", inf, inf)
    figures: dict[str, Array | float] = {
        "objective": float(result.objective),
        "residuals": np.asarray(result.position_errors, dtype=float),
        "limit_violation": float(result.limit_violation),
    }
    nonfinite = [k for k, x in figures.items() if not np.all(np.isfinite(x))]
    if not np.all(np.isfinite(q)):
        nonfinite.insert(0, "configurations")
    if nonfinite:
        return IKCheck(False, f"non-finite values in {', '.join(nonfinite)}", inf, inf)
    phi = np.cumsum(q + chain.angle_offset, axis=1)
    tips = chain.base + np.stack([np.cos(phi) @ chain.lengths, np.sin(phi) @ chain.lengths], axis=1)
    residuals = np.linalg.norm(tips - problem.target_points, axis=1)
    residual = float(np.max(residuals))
    limits = 0.0
    if problem.use_limits:
        limits = float(np.max(np.maximum(chain.q_lower - q, q - chain.q_upper), initial=0.0))
        limits = max(limits, 0.0)
    energy = 0.5 * float(np.sum((np.roll(q, -1, axis=0) - q) ** 2))
    wrong = []
    if not residual <= residual_tol:
        wrong.append(f"target residual {residual:.3g} m > {residual_tol:.3g} m")
    if not limits <= limit_tol:
        wrong.append(f"joint limits violated by {limits:.3g} rad > {limit_tol:.3g} rad")
    # Reported figures against the recomputed ones: Pinocchio's and the closed
    # form's tip positions agree to rounding (1e-12 on unit-size chains).
    scale = 1.0 + float(np.sum(chain.lengths))
    if not abs(float(result.objective) - energy) <= 1e-9 * max(1.0, energy):
        wrong.append(f"reported E = {float(result.objective):.12g}, recomputed {energy:.12g}")
    if not np.allclose(figures["residuals"], residuals, rtol=0.0, atol=1e-9 * scale):
        wrong.append("reported residuals differ from the recomputed ones")
    return IKCheck(not wrong, "; ".join(wrong), residual, limits)
