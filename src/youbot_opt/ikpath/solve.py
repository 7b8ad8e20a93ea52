"""One IK-path solve: reachability first, then the chosen method.

``solve(problem, method="al" | "ipopt")`` decides every target's reachability
(:mod:`.reachability`), stops with :class:`~youbot_opt.exceptions.UnreachableTarget`
if one is unreachable, and otherwise runs the method from ``x0`` (default:
the zero vector, clipped into the limits).
"""

from __future__ import annotations

import logging
import warnings
from typing import Literal

from numpy.typing import ArrayLike

from youbot_opt.exceptions import ParameterError, YoubotOptWarning
from youbot_opt.ikpath.methods.al import ALOptions, solve_augmented_lagrangian
from youbot_opt.ikpath.methods.ipopt import solve_ipopt
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability.planar import Reachability, ReachVerdict, require_reachable
from youbot_opt.ikpath.result import IKPathResult
from youbot_opt.nlp.ipopt import IpoptOptions

__all__ = ["Method", "METHODS", "solve", "check_targets"]

_log = logging.getLogger(__name__)

Method = Literal["al", "ipopt"]
METHODS: tuple[str, ...] = ("al", "ipopt")


def check_method(method: str, options: ALOptions | IpoptOptions | None) -> None:
    """Validate ``method`` and that ``options`` belong to it.

    Raises
    ------
    ParameterError
        For an unknown method or options of the other method.
    """
    if method not in METHODS:
        raise ParameterError(
            f"unknown method {method!r}; choose one of {', '.join(METHODS)}",
            name="method",
            value=method,
        )
    expected = ALOptions if method == "al" else IpoptOptions
    if options is not None and not isinstance(options, expected):
        raise ParameterError(
            f"options for method {method!r} must be {expected.__name__}, "
            f"got {type(options).__name__}",
            name="options",
            value=options,
        )


def check_targets(problem: CyclicIKProblem) -> tuple[ReachVerdict, ...]:
    """Decide reachability of every target; raise for an unreachable one, warn if undecided.

    Raises
    ------
    UnreachableTarget
        For the first unreachable target (its verdict is attached).
    """
    verdicts = require_reachable(problem)
    for v in verdicts:
        if v.status is Reachability.UNDECIDED:
            warnings.warn(
                f"reachability not decided within the budget: {v.describe()}; solving anyway",
                YoubotOptWarning,
                stacklevel=3,
            )
    return verdicts


def solve(
    problem: CyclicIKProblem,
    *,
    method: Method = "al",
    x0: ArrayLike | None = None,
    options: ALOptions | IpoptOptions | None = None,
    check_reachability: bool = True,
) -> IKPathResult:
    """Solve the cyclic IK-path problem once.

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    method : {"al", "ipopt"}
        Augmented Lagrangian with (projected) BFGS, or CasADi + IPOPT.
    x0 : array_like, shape (n s,) or (s, n), optional
        Start in [rad]; the zero vector (clipped into the limits) by default.
    options : ALOptions or IpoptOptions, optional
        Settings of the chosen method (for ``"ipopt"``: default
        :meth:`IpoptOptions.for_ikpath`, and ``constr_viol_tol`` must be set).
    check_reachability : bool
        Decide every target's reachability first (recommended).

    Returns
    -------
    IKPathResult
        A failed solve is a status; call ``raise_for_status()`` to raise.

    Raises
    ------
    UnreachableTarget
        If a target is unreachable (message: verdict, reach, nearest point).
    ParameterError
        For an unknown method, foreign options or an invalid start.
    """
    check_method(method, options)
    if check_reachability:
        check_targets(problem)
    if method == "al":
        return solve_augmented_lagrangian(problem, x0, options)  # type: ignore[arg-type]
    return solve_ipopt(problem, x0, options)  # type: ignore[arg-type]
