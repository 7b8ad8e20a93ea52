r"""Damped least-squares IK along a cyclic path: the greedy baseline, witnesses, starts.

:func:`dls_ik` solves one target of a :class:`~youbot_opt.ikpath.problem.CyclicIKProblem`
by damped least squares from a given configuration; :func:`greedy_path` visits every
target in turn from the previous one (the common practice the least-motion path is
compared with); :func:`random_theta` draws a configuration within the limits. The
reachability witnesses and the coherent starts use them. Conventions: docs/ikpath.md.

>>> q, ok = greedy_path(problem)  # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from youbot_opt._typing import Array
from youbot_opt.ikpath.problem import CyclicIKProblem

__all__ = ["dls_ik", "greedy_path", "random_theta"]


def dls_ik(
    problem: CyclicIKProblem,
    j: int,
    theta0: ArrayLike,
    *,
    damping: float = 1e-2,
    max_iterations: int = 300,
    tol: float = 1e-12,
    data: pin.Data | None = None,
    restarts: int = 8,
) -> tuple[Array, bool]:
    """Solve target ``j`` alone from ``theta0`` by damped least squares (clipped to the limits).

    Levenberg-Marquardt steps ``dq = -J^T (J J^T + lambda^2 I)^{-1} c`` on the
    target's constraint rows, projected on the joint box; ``lambda`` starts at
    ``damping`` and is raised tenfold when a step does not reduce ``|c|``
    (lowered again after a success). If the target is not met, up to
    ``restarts`` seeds are tried (seeded by ``j``), alternately ``theta0 + N(0, 0.5 rad)``
    and uniform in the limits (clipped to ``[-pi, pi]``).
    Returns the angles and whether the target is met within its tolerances.
    """
    data = problem.create_data() if data is None else data
    lo = problem.lower[: problem.n_joints]
    hi = problem.upper[: problem.n_joints]
    theta = np.clip(np.array(theta0, dtype=float), lo, hi)
    target = problem.targets[j]
    c, jac = problem.block(j, theta, data)
    cost = float(c @ c)
    lam = float(damping)
    for _ in range(max_iterations):
        if cost <= tol**2 or lam > 1e6:
            break
        # J^T (J J^T + lam^2 I)^-1 c through the SVD of J: the same step, also where
        # J J^T is singular to working precision (more rows than the chain can move)
        u, sv, vt = np.linalg.svd(jac, full_matrices=False)
        trial = np.clip(theta - vt.T @ (sv / (sv**2 + lam**2) * (u.T @ c)), lo, hi)
        c_t, jac_t = problem.block(j, trial, data)
        cost_t = float(c_t @ c_t)
        if cost_t < cost:
            theta, c, jac, cost = trial, c_t, jac_t, cost_t
            lam = max(lam / 10.0, 1e-9)
        else:
            lam *= 10.0
    met = target.met(problem.placement(theta, data))
    if not met and restarts > 0:  # stuck (a singular or folded arm): perturbed seeds
        rng = np.random.default_rng(j)
        for k in range(restarts):
            if k % 2 == 0:  # near the start (keeps the path coherent)
                seed = np.clip(np.asarray(theta0, float) + rng.normal(0.0, 0.5, theta.size), lo, hi)
            else:  # anywhere in the limits (a start trapped against a limit)
                seed = random_theta(problem, rng)
            alt, ok = dls_ik(
                problem,
                j,
                seed,
                damping=damping,
                max_iterations=max_iterations,
                tol=tol,
                data=data,
                restarts=0,
            )
            if ok:
                return alt, True
    return theta, met


def greedy_path(problem: CyclicIKProblem, theta0: ArrayLike | None = None) -> tuple[Array, bool]:
    """Solve each target by DLS from the previous configuration (the common practice).

    The common practice: each target solved by DLS from the previous configuration.

    Returns the (s, n) configurations and whether every target was met.
    """
    data = problem.create_data()
    theta = (
        problem.default_start()[: problem.n_joints] if theta0 is None else np.asarray(theta0, float)
    )
    out, ok = [], True
    for j in range(problem.n_targets):
        theta, met = dls_ik(problem, j, theta, data=data)
        out.append(theta)
        ok = ok and met
    return np.array(out), ok


def random_theta(problem: CyclicIKProblem, rng: np.random.Generator) -> Array:
    """Joint angles uniform in the limits clipped to ``[-pi, pi]`` [rad] (shape (n,))."""
    lo = np.maximum(problem.lower[: problem.n_joints], -np.pi)
    hi = np.minimum(problem.upper[: problem.n_joints], np.pi)
    return rng.uniform(np.minimum(lo, hi), np.maximum(lo, hi))
