"""Apply the independent check to a trajectory result: :func:`checked`, :func:`check_result`.

A :class:`~youbot_opt.trajopt.result.TrajOptResult` may call itself a success
only if IPOPT converged *and* :meth:`~youbot_opt.trajopt.result.TrajOptResult.check`,
which does not use the NLP, agrees: every number finite, every variable within
its bounds, the first and last knots at the start and goal, the collocation
defects recomputed with ``pin.aba`` vanishing, T, W and f following from the
variables. Constructing a result does no work; the solver and the loader of
saved results pass every result through :func:`checked`.

>>> result = checked(result)  # status and message now the check's  # doctest: +SKIP
"""

from __future__ import annotations

from youbot_opt.nlp.status import apply_check
from youbot_opt.trajopt.result import ResultCheck, TrajOptResult

__all__ = ["ResultCheck", "check_result", "checked"]


def check_result(result: TrajOptResult, *, feasibility_tol: float | None = None) -> ResultCheck:
    """Classify a result independently of IPOPT's flag (:meth:`TrajOptResult.check`).

    Parameters
    ----------
    result : TrajOptResult
        The result to check (not changed).
    feasibility_tol : float, optional
        Largest accepted violation in the unit of each row ([rad], [rad/s],
        [N m], [s]); ``result.feasibility_tol`` by default.

    Returns
    -------
    ResultCheck
        The status the result deserves, with the measured figures.
    """
    return result.check(feasibility_tol=feasibility_tol)


def checked(result: TrajOptResult) -> TrajOptResult:
    """Return ``result`` with the status its independent check gives it.

    A success claim that the check refutes is downgraded: the check's status
    replaces :attr:`~TrajOptResult.status` and its reason is appended to
    :attr:`~TrajOptResult.message`. A failure stays as it is (the check only
    downgrades), and so does a success the check confirms.

    Parameters
    ----------
    result : TrajOptResult
        A result as built by the solver or read from a file.

    Returns
    -------
    TrajOptResult
        ``result`` itself, or a copy with the downgraded status and message.
    """
    return apply_check(result)
