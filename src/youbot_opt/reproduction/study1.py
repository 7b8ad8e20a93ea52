"""The study's own (defective) transcription, kept out of the main API.

Spec ``trajopt.md``, "What the study's code actually computed":
:class:`StudyTranscription` reproduces the NLP the study's MATLAB solved,
trapezoidal collocation with four deviations (first knot on the left, same
knot on the right, damping 0.1 N m s/rad, ``T = n dt``), each switchable with
:class:`StudyDeviations`; :func:`study1_problem` builds the study's problem.
The deviations are written out in docs/design.md, "Module notes".

>>> solver = TrajOptSolver(study1_problem(50), StudyTranscription())  # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypedDict, TypeVar, Unpack

import casadi as ca
import numpy as np

from youbot_opt.exceptions import ParameterError, TranscriptionError
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.params import STUDY_Q_GOAL, STUDY_Q_START
from youbot_opt.trajopt.objectives import objective_value
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.transcription import TrapezoidalCollocation
from youbot_opt.trajopt.transcription.base import Expressions
from youbot_opt.trajopt.transcription.path import PathConstraint

if TYPE_CHECKING:
    from youbot_opt.collision.clearance import Clearance
    from youbot_opt.robot.model import BoundFamily
    from youbot_opt.trajopt.result import TrajOptResult
    from youbot_opt.trajopt.tool import ToolConstraint

_E = TypeVar("_E", ca.SX, ca.MX)  # a CasADi expression: the transcription works with both
_N = TypeVar("_N", float, ca.SX, ca.MX)  # a time step: a number or an expression

__all__ = [
    "study1_problem",
    "DEVIATION_NAMES",
    "STUDY_DAMPING",
    "StudyDeviations",
    "StudyTranscription",
]

STUDY_DAMPING = 0.1  # [N m s/rad]
"""Joint damping of the study's code ("arbitrary joint damping")."""

DEVIATION_NAMES: tuple[str, ...] = ("first_knot_left", "same_knot_right", "damping", "time_n_dt")
"""The four deviations, in the spec's order (1) .. (4)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class StudyDeviations:
    """Which of the study code's four deviations are switched on (default: all).

    Attributes
    ----------
    first_knot_left : bool
        (1) Left-end acceleration of every velocity defect taken at knot 1.
    same_knot_right : bool
        (2) Right-end acceleration evaluated at knot ``k``'s state and torque.
    damping : float
        (3) Viscous joint damping ``b`` in [N m s/rad] added to every
        acceleration; 0 switches it off. The study: 0.1.
    time_n_dt : bool
        (4) Time term ``T = n dt`` instead of ``(n - 1) dt``.
    """

    first_knot_left: bool = True
    same_knot_right: bool = True
    damping: float = STUDY_DAMPING
    time_n_dt: bool = True

    def __post_init__(self) -> None:
        for name in ("first_knot_left", "same_knot_right", "time_n_dt"):
            if not isinstance(getattr(self, name), bool):
                raise ParameterError(
                    f"{name} must be True or False, got {getattr(self, name)!r}", name=name
                )
        b = self.damping
        if isinstance(b, bool) or not isinstance(b, int | float) or not math.isfinite(b) or b < 0:
            raise ParameterError(
                f"damping must be a finite number >= 0 in [N m s/rad] (the study: 0.1), got {b!r}",
                name="damping",
                value=b,
            )
        object.__setattr__(self, "damping", float(b))

    # ------------------------------------------------------------ variants
    @classmethod
    def none(cls) -> StudyDeviations:
        """Every deviation off: the correct trapezoidal transcription, no damping."""
        return cls(first_knot_left=False, same_knot_right=False, damping=0.0, time_n_dt=False)

    @classmethod
    def only(cls, name: str) -> StudyDeviations:
        """Exactly one deviation on (``name`` from :data:`DEVIATION_NAMES`).

        Raises
        ------
        ParameterError
            If ``name`` is not a deviation; the message lists them.
        """
        _check_name(name)
        on: dict[str, Any] = {"damping": STUDY_DAMPING} if name == "damping" else {name: True}
        return dataclasses.replace(cls.none(), **on)

    def without(self, name: str) -> StudyDeviations:
        """Return these deviations with ``name`` switched off.

        Raises
        ------
        ParameterError
            If ``name`` is not a deviation; the message lists them.
        """
        _check_name(name)
        off: dict[str, Any] = {name: 0.0 if name == "damping" else False}
        return dataclasses.replace(self, **off)

    @property
    def active(self) -> tuple[str, ...]:
        """Names of the deviations switched on, in spec order."""
        return tuple(n for n in DEVIATION_NAMES if getattr(self, n))

    @property
    def label(self) -> str:
        """Short label such as ``"(1)+(2)+(3)+(4)"``, or ``"none"``."""
        nums = [f"({DEVIATION_NAMES.index(n) + 1})" for n in self.active]
        return "+".join(nums) if nums else "none"

    # ---------------------------------------------------------- objective
    def duration(self, dt: _N, n_knots: int) -> _N:
        """Time term ``T`` in [s] the study's code used: ``n dt`` or ``(n - 1) dt``."""
        return (n_knots if self.time_n_dt else n_knots - 1) * dt

    def objective(self, result: TrajOptResult) -> float:
        """Objective of ``result`` as these deviations define it.

        Parameters
        ----------
        result : TrajOptResult
            A solve (its ``dt`` [s], ``work`` [N^2 m^2 s] and ``beta`` are used).

        Returns
        -------
        float
            ``beta T + (1 - beta) W`` with ``T`` from :meth:`duration`.
        """
        total = self.duration(result.dt, result.problem.n_knots)
        return float(result.beta * total + (1.0 - result.beta) * result.work)


def _check_name(name: str) -> None:
    if name not in DEVIATION_NAMES:
        raise ParameterError(
            f"unknown deviation {name!r}; choose one of {DEVIATION_NAMES}", name="name", value=name
        )


class StudyTranscription(TrapezoidalCollocation):
    """Trapezoidal collocation as the study's code implemented it.

    Parameters
    ----------
    deviations : StudyDeviations, optional
        Deviations to switch on (default: all four, the study's code).

    Notes
    -----
    Same variables (``9n + 1`` for the youBot) and constraint counts
    (``6(n - 1) + 12``) as :class:`TrapezoidalCollocation`; only the velocity
    defects and the time term differ (module docstring). Use it on a problem
    whose robot has no damping of its own (``study1_problem()``): deviation
    (3) adds the damping inside the transcription, so the problem, and hence
    :func:`youbot_opt.trajopt.certify.certify`, keeps the study's paper arm.
    """

    name = "study1_code"

    def __init__(self, deviations: StudyDeviations | None = None) -> None:
        if deviations is None:
            deviations = StudyDeviations()
        if not isinstance(deviations, StudyDeviations):
            raise ParameterError(
                f"deviations must be a StudyDeviations, got {type(deviations).__name__}",
                name="deviations",
            )
        self.deviations = deviations

    def __repr__(self) -> str:
        return f"StudyTranscription({self.deviations!r})"

    def dynamics_points(self, sym: dict[str, _E]) -> dict[str, tuple[_E, _E, _E]]:
        """Evaluate the dynamics at the knots, deviation (3) folded in: ``FD(q, v, tau - b v)``.

        ``tau - b v`` stays a linear selection of the decision variables, as the
        structured derivatives of :mod:`youbot_opt.trajopt.transcription.derivatives` require.
        """
        q, v, tau = sym["q"], sym["v"], sym["tau"]
        b = self.deviations.damping
        return {"knots": (q, v, tau - b * v if b > 0.0 else tau)}

    def collocation(self, sym: dict[str, _E], accel: dict[str, _E]) -> list[tuple[str, _E]]:
        """Position defects as in the study, velocity defects with deviations (1) and (2)."""
        dev = self.deviations
        q, v, dt = sym["q"], sym["v"], sym["dt"]
        a = accel["knots"]
        n = q.size2()
        left = ca.repmat(a[:, 0], 1, n - 1) if dev.first_knot_left else a[:, :-1]
        right = a[:, :-1] if dev.same_knot_right else a[:, 1:]
        defect_q = q[:, 1:] - q[:, :-1] - 0.5 * dt * (v[:, 1:] + v[:, :-1])
        defect_v = v[:, 1:] - v[:, :-1] - 0.5 * dt * (left + right)
        return [("defect_position", defect_q), ("defect_velocity", defect_v)]

    def expressions(
        self,
        problem: TrajOptProblem,
        sym: dict[str, _E],
        accel: dict[str, _E],
        beta: _E,
        paths: tuple[PathConstraint, ...] = (),
        path_values: Mapping[str, _E] | None = None,
    ) -> Expressions[_E]:
        """Build the trapezoidal pieces, with the time term of deviation (4).

        Raises
        ------
        TranscriptionError
            If deviation (3) is on and the problem's robot already applies its
            own damping (it would count twice).
        """
        own = np.asarray(problem.robot.damping, dtype=float) if problem.damping else np.zeros(1)
        if self.deviations.damping > 0.0 and np.any(own > 0.0):
            raise TranscriptionError(
                f"deviation (3) adds b = {self.deviations.damping} N m s/rad, but the problem's "
                f"robot already applies damping {own.tolist()} N m s/rad, so it would count twice; "
                "load the robot without damping (study1_problem()) or switch deviation (3) off"
            )
        parts = super().expressions(problem, sym, accel, beta, paths, path_values)
        if not self.deviations.time_n_dt:
            return parts
        total = self.deviations.duration(sym["dt"], problem.n_knots)
        f = objective_value(total, parts.work, beta)
        return parts._replace(f=f, duration=total)


class _ProblemFields(TypedDict, total=False):
    """The :class:`TrajOptProblem` fields :func:`study1_problem` passes through."""

    duration: float | None
    scaled_bounds: tuple[BoundFamily, ...]
    dt_min: float
    dt_max: float
    clearance: Clearance | None
    tool: tuple[ToolConstraint, ...]


def study1_problem(
    n_knots: int = 50,
    *,
    robot: RobotModel | None = None,
    damping: float | None = None,
    **kwargs: Unpack[_ProblemFields],
) -> TrajOptProblem:
    """Return the study-1 problem: youBot from (-pi/6, -pi/6, -pi/3) to (pi/6, pi/6, pi/3) at rest.

    Parameters
    ----------
    n_knots : int
        Number of knots (the study: 50).
    robot : RobotModel, optional
        The planar youBot; loaded with :func:`youbot_opt.robot.load.load_model` when omitted.
    damping : float, optional
        Joint damping in [N m s/rad] for the loaded youBot (the study's code
        used 0.1; the paper and the default model have none). Ignored when
        ``robot`` is given.
    **kwargs
        Further :class:`TrajOptProblem` fields (``duration``, ``scaled_bounds``, ...).

    Returns
    -------
    TrajOptProblem
        The problem, with both boundary velocities zero.
    """
    if robot is None:
        robot = load_model("youbot", damping=damping)
    return TrajOptProblem(
        robot=robot,
        start=BoundaryState(q=np.array(STUDY_Q_START)),
        goal=BoundaryState(q=np.array(STUDY_Q_GOAL)),
        n_knots=n_knots,
        **kwargs,
    )
