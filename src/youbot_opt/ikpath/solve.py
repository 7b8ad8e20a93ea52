"""One IK-path solve: ``solve(problem, method="al" | "ipopt")``, defaults per robot kind.

A planar robot's problem has its reachability decided first (exact verdicts,
:mod:`.reachability.planar`; :class:`~youbot_opt.exceptions.UnreachableTarget`
if a target is unreachable) and is solved by the planar methods; any other
robot's by the general ones (:func:`solve` says which defaults). The start is
``x0`` (default: the zero vector, clipped into the limits).

>>> result = solve(problem, method="ipopt")  # doctest: +SKIP
"""

from __future__ import annotations

import logging
import warnings
from typing import Literal

from numpy.typing import ArrayLike

from youbot_opt.exceptions import ParameterError, YoubotOptWarning
from youbot_opt.ikpath.methods.al import (
    ALOptions,
    solve_augmented_lagrangian,
    solve_augmented_lagrangian_3d,
)
from youbot_opt.ikpath.methods.ipopt import IpoptIKSolver3D, solve_ipopt, solve_ipopt_3d
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability import Reachability
from youbot_opt.ikpath.reachability.general import require_reachable_3d
from youbot_opt.ikpath.reachability.planar import ReachVerdict, require_reachable
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


def uses_planar_methods(problem: CyclicIKProblem, method: str, planar: bool | None) -> bool:
    """Whether ``problem`` goes to the planar methods (default: with a chain, no clearance).

    A problem with a clearance goes to the general methods (IPOPT or the AL, both
    hold the clearance rows, docs/ikpath.md "Clearance").

    Raises
    ------
    ParameterError
        A problem with a clearance and ``planar=True``.
    """
    clear = problem.clearance_rows is not None
    use_planar = problem.chain is not None and not clear if planar is None else bool(planar)
    if clear and use_planar:
        raise ParameterError(
            "a problem with a clearance is solved by the general methods only (planar=False "
            "or unset, method='ipopt' or 'al'); the planar methods do not hold clearance "
            f"rows (got planar=True, method={method!r})",
            name="planar",
            value=planar,
        )
    return use_planar


def solve(
    problem: CyclicIKProblem,
    *,
    method: Method = "al",
    x0: ArrayLike | None = None,
    options: ALOptions | IpoptOptions | None = None,
    check_reachability: bool | None = None,
    planar: bool | None = None,
) -> IKPathResult:
    """Solve the cyclic IK-path problem once, with the defaults of its robot's kind.

    One local solve from ``x0``: for the best path without choosing a start, use
    :func:`~youbot_opt.ikpath.multistart.run_multistart` (its automatic starts).

    A problem with a planar chain (:attr:`CyclicIKProblem.chain`: a PlanarChain,
    or a RobotModel that is planar for the frame with position targets) is
    solved by the planar methods: the exact reachability verdicts first, the
    study's AL settings (``ALOptions()``) or IPOPT on the chain's closed form, a
    result with per-target residuals (:class:`IKPathResult`). Any other problem
    (or ``planar=False``) by the general ones: the AL with
    :data:`~youbot_opt.ikpath.methods.al.AL_OPTIONS_3D` or IPOPT on the
    frame's symbolic kinematics, reachability not decided unless asked, a
    result with position and orientation errors (:class:`IKPathResult`).

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    method : {"al", "ipopt"}
        Augmented Lagrangian with (projected) BFGS, or CasADi + IPOPT.
    x0 : array_like, shape (n s,) or (s, n), optional
        Start in [rad]; the zero vector (clipped into the limits) by default.
    options : ALOptions or IpoptOptions, optional
        Settings of the chosen method (default: the robot kind's, see above;
        IPOPT: :meth:`IpoptOptions.for_ikpath`); ``max_wall_time`` [s] bounds
        the solve (status ``max_time``).
    check_reachability : bool, optional
        Decide every target's reachability first (default: True for the planar
        methods, False for the general ones).
    planar : bool, optional
        Use the planar methods (default: when the problem has a chain); False
        solves a planar robot by the general methods (to compare them).

    Returns
    -------
    IKPathResult
        A failed solve is a status; call ``raise_for_status()`` to raise
        (planar), or read ``status`` and ``message`` (which names the blocking
        target).

    Raises
    ------
    UnreachableTarget
        If the reachability is checked and a target is unreachable (message:
        verdict, reach, nearest point or certificate).
    ParameterError
        For an unknown method, foreign options, an invalid start, or
        ``planar=True`` on a problem without a chain or with a clearance.
    """
    check_method(method, options)
    use_planar = uses_planar_methods(problem, method, planar)
    if use_planar:
        problem.planar_chain  # noqa: B018 - raises ParameterError without a chain
        if check_reachability is None or check_reachability:
            check_targets(problem)
        if method == "al":
            return solve_augmented_lagrangian(problem, x0, options)  # type: ignore[arg-type]
        return solve_ipopt(problem, x0, options)  # type: ignore[arg-type]
    if check_reachability:
        require_reachable_3d(problem)
    if method == "ipopt":
        if options is None:
            return solve_ipopt_3d(problem, x0)
        return IpoptIKSolver3D(problem, options).solve(x0)  # type: ignore[arg-type]
    return solve_augmented_lagrangian_3d(problem, x0, options)  # type: ignore[arg-type]
