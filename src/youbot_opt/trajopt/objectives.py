"""Objective terms of the time/energy trajectory problem (study 1, spec ``trajopt.md``).

``f = beta T + (1 - beta) W`` (:func:`objective_value`; ``beta`` is a solve-time
parameter, never part of the problem) with the true duration ``T = (N - 1) dt`` in [s]
and the effort ``W`` (integral of ``tau . tau``) in [N^2 m^2 s] by the
quadrature of the transcription: trapezoidal (the study's), Simpson's rule
(Hermite-Simpson) or Radau's weights (:mod:`youbot_opt.trajopt.quadrature`).
The helpers work on numbers and CasADi expressions alike, so the NLP and the
re-evaluation of a result share one definition.

>>> duration(dt, n_knots=50)  # T = 49 dt [s]  # doctest: +SKIP
"""

from __future__ import annotations

from typing import TypeVar

import casadi as ca
import numpy as np

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt.quadrature import QuadratureRule, quadrature_weights

__all__ = [
    "duration",
    "objective_value",
    "work",
]

_N = TypeVar("_N", float, ca.SX, ca.MX)  # a number or a CasADi expression: both are allowed


def objective_value(duration: _N, work: _N, beta: _N) -> _N:
    """Return ``f = beta T + (1 - beta) W`` for a duration [s] and a work [N^2 m^2 s].

    Parameters
    ----------
    duration : float or casadi expression
        ``T`` in [s].
    work : float or casadi expression
        ``W`` in [N^2 m^2 s].
    beta : float or casadi expression
        Time weight in [0, 1] (the NLP's parameter; validated where it enters,
        :meth:`youbot_opt.trajopt.solver.TrajOptSolver.solve`).

    Returns
    -------
    float or casadi expression
        ``beta * T + (1 - beta) * W``.
    """
    return beta * duration + (1 - beta) * work


def duration(dt: _N, n_knots: int) -> _N:
    """Return the true duration ``T = (N - 1) dt`` in [s] of ``N`` knots, common step ``dt`` [s]."""
    return (n_knots - 1) * dt


def work(
    dt: float, tau: Array, tau_mid: Array | None = None, rule: QuadratureRule = "trapezoidal"
) -> float:
    """Work-like effort ``W`` in [N^2 m^2 s] of knot torques (numeric).

    Parameters
    ----------
    dt : float
        Common time step in [s].
    tau : ndarray, shape (N, nv)
        Knot torques in [N m].
    tau_mid : ndarray, shape (N - 1, nv), optional
        Mid-interval torques in [N m]; required by ``rule="simpson"``.
    rule : {"trapezoidal", "simpson"}
        Quadrature rule.

    Returns
    -------
    float
        ``W`` by the chosen rule.

    Raises
    ------
    ParameterError
        If Simpson's rule is asked for without ``tau_mid``.
    """
    tau = np.asarray(tau, dtype=float)
    w_knots, w_mid = quadrature_weights(rule, tau.shape[0])
    total = float(np.sum(tau * tau, axis=1) @ w_knots)
    if w_mid is not None:
        if tau_mid is None:
            raise ParameterError("Simpson's rule needs tau_mid", name="tau_mid")
        mid = np.asarray(tau_mid, dtype=float)
        total += float(np.sum(mid * mid, axis=1) @ w_mid)
    return dt * total
