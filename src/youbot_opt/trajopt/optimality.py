"""Is a stored plan a first-order optimum of a solver's NLP? :func:`first_order`.

Owns the check a trajectory sweep runs before it trusts a stored success on
resume (#29): at the stored point, with the sweep's own beta, bound scale and
boundary states (never the file's), the KKT conditions of the solver's NLP hold
to a tolerance derived from the solver's IPOPT ``tol`` (:func:`kkt_tolerance`).
The multipliers are the file's, checked, never trusted. Why: docs/design.md.

    report = first_order(solver, result, beta=0.5)
    if not report.passed:
        print(report.reason)
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from youbot_opt.exceptions import ParameterError
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.transcription.base import BOUND_NAMES

__all__ = ["FIRST_ORDER_RTOL", "FIRST_ORDER_MARGIN", "FirstOrder", "first_order", "kkt_tolerance"]

FIRST_ORDER_RTOL = 1e-6
"""Smallest relative tolerance of :func:`first_order` (of ``max(1, |grad f|_inf)``)."""

FIRST_ORDER_MARGIN = 100.0
"""Factor on IPOPT's own tolerance in :func:`kkt_tolerance`.

IPOPT stops on the error of its *scaled* problem (the objective scaled down to a
largest gradient entry of 100 at the start, the dual residual divided by
``s_d >= 1``), so an unscaled residual may exceed ``tol`` by those factors. The
study-1 problem's solves (three transcriptions, beta 0.1, 0.5, 0.9, 15 knots)
measured relative residuals up to 2e-10 at ``tol = 1e-8``; a beta = 0.9 optimum
read at beta = 0.5 measured 0.67."""


def kkt_tolerance(options: IpoptOptions, status: SolveStatus) -> float:
    """Return the relative tolerance of :func:`first_order` for a solve with ``options``.

    ``max(FIRST_ORDER_RTOL, FIRST_ORDER_MARGIN * tol)`` with IPOPT's ``tol``, or its
    ``acceptable_tol`` (``extra``, IPOPT's default 1e-6) for a result solved to an
    acceptable level. ``options`` are the caller's (a sweep's solver's), never a file's.
    """
    tol = float(options.tol)
    if status is SolveStatus.SOLVED_ACCEPTABLE:
        tol = float(options.extra.get("acceptable_tol", 1e-6))  # type: ignore[arg-type]
    return max(FIRST_ORDER_RTOL, FIRST_ORDER_MARGIN * tol)


@dataclass(frozen=True, slots=True)
class FirstOrder:
    """The first-order (KKT) figures of a point of an NLP; each is a largest entry.

    Attributes
    ----------
    stationarity : float
        ``|grad f + J_g^T lam_g + lam_x|_inf``, the gradient of the Lagrangian
        (objective units per variable unit).
    complementarity : float
        Largest ``|lam| * gap`` of a multiplier and the distance of its row (a
        variable or a constraint) from the bound its sign names (``lam > 0``: the
        upper bound).
    wrong_side : float
        Largest ``|lam|`` of a multiplier whose sign names a side without a bound.
    violation : float
        Largest violation of a bound of ``x`` or ``g`` (units of each row).
    scale : float
        ``max(1, |grad f|_inf)``: the three multiplier figures are measured against
        ``rtol * scale``.
    rtol : float
        Relative tolerance (:func:`kkt_tolerance`).
    feasibility_tol : float
        Largest violation accepted (the solver's ``feasibility_tol``).
    """

    stationarity: float
    complementarity: float
    wrong_side: float
    violation: float
    scale: float
    rtol: float
    feasibility_tol: float

    @property
    def passed(self) -> bool:
        """Whether the point is a first-order optimum (all four figures within tolerance)."""
        return self.reason is None

    @property
    def reason(self) -> str | None:
        """Why the point is no first-order optimum (``None``: it is one)."""
        if not self.violation <= self.feasibility_tol:
            return (
                f"it violates a bound of the NLP by {self.violation:.3g} > feasibility_tol = "
                f"{self.feasibility_tol:.3g}"
            )
        limit = self.rtol * self.scale
        figures = (
            ("the gradient of its Lagrangian (with the file's multipliers)", self.stationarity),
            ("a multiplier's complementarity with its bound", self.complementarity),
            ("a multiplier on a side without a bound", self.wrong_side),
        )
        for what, value in figures:
            if not value <= limit:
                return (
                    f"{what} is {value:.3g}, more than {limit:.3g} = {self.rtol:.3g} x "
                    f"max(1, |grad f|_inf = {self.scale:.3g})"
                )
        return None


def first_order(
    solver: TrajOptSolver,
    result: TrajOptResult,
    *,
    beta: float,
    bound_scale: float = 1.0,
    rtol: float | None = None,
) -> FirstOrder:
    """Return the KKT figures of ``result``'s point in ``solver``'s NLP at ``beta``.

    The point is ``result.variables``; the NLP is ``solver``'s (its problem's
    boundary states, its bounds at ``bound_scale``, the objective at ``beta``);
    the multipliers are ``result.multipliers`` (CasADi's sign convention,
    :class:`~youbot_opt.trajopt.result.TrajOptResult`), checked here.

    Parameters
    ----------
    solver : TrajOptSolver
        The NLP (and its derivatives: :meth:`TrajOptSolver.first_order_functions`).
    result : TrajOptResult
        The point and its multipliers, on ``solver``'s transcription and grid.
    beta : float
        Time weight of the objective (the caller's).
    bound_scale : float, optional
        Bound scale of the NLP's bounds (the caller's).
    rtol : float, optional
        Relative tolerance; :func:`kkt_tolerance` of the solver's options and the
        result's status when omitted.

    Returns
    -------
    FirstOrder
        The figures; :attr:`FirstOrder.passed` and :attr:`FirstOrder.reason`.

    Raises
    ------
    ParameterError
        If the result's variables or multipliers do not fit the NLP (another
        transcription, size or grid) or are not finite.
    """
    nlp = solver.nlp
    multipliers = result.multipliers
    try:
        x = nlp.variables.pack(dict(result.variables))
        lam_x = nlp.variables.pack(
            {
                name: multipliers[f"{BOUND_NAMES[name]}_lower"]
                + multipliers[f"{BOUND_NAMES[name]}_upper"]
                for name in nlp.variables.blocks
            }
        )
        lam_g = nlp.constraints.pack({name: multipliers[name] for name in nlp.constraints.blocks})
    except (KeyError, ValueError) as exc:
        raise ParameterError(
            f"its variables or multipliers do not fit the NLP ({type(exc).__name__}: {exc})",
            name="result",
        ) from exc
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(lam_x)) and np.all(np.isfinite(lam_g))):
        raise ParameterError("its variables or multipliers are not finite", name="result")
    grad_f, jac_g = solver.first_order_functions()
    grad = np.asarray(grad_f(x, beta)[1], dtype=float).ravel()
    g_dm, jac = jac_g(x, beta)
    g = np.asarray(g_dm, dtype=float).ravel()
    residual = grad + np.asarray(ca.mtimes(jac.T, ca.DM(lam_g)), dtype=float).ravel() + lam_x
    lbx, ubx, lbg, ubg = solver.nlp_bounds(bound_scale)
    values, lam = np.concatenate([x, g]), np.concatenate([lam_x, lam_g])
    lower, upper = np.concatenate([lbx, lbg]), np.concatenate([ubx, ubg])
    bound = np.where(lam > 0, upper, np.where(lam < 0, lower, values))
    unbounded = ~np.isfinite(bound)
    gap = np.abs(np.where(unbounded, 0.0, values - bound))
    violation = np.maximum(lower - values, values - upper)
    if rtol is None:
        rtol = kkt_tolerance(solver.options, result.status)
    return FirstOrder(
        stationarity=float(np.max(np.abs(residual), initial=0.0)),
        complementarity=float(np.max(np.abs(lam) * gap, initial=0.0)),
        wrong_side=float(np.max(np.where(unbounded, np.abs(lam), 0.0), initial=0.0)),
        violation=float(np.max(violation, initial=0.0)),
        scale=max(1.0, float(np.max(np.abs(grad), initial=0.0))),
        rtol=float(rtol),
        feasibility_tol=solver.feasibility_tol,
    )
