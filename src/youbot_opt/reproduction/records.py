"""Columns and records of the study-1 reproduction (spec ``trajopt.md``).

A :class:`Variant` is one column of the comparison: a transcription on an arm
(the study's code with its deviations, or a correct transcription with or
without the code's damping). :func:`record` turns one solve into a JSON-ready
row with its forward-simulation certificates (:func:`youbot_opt.trajopt.certify.certify`)
against the arm its NLP describes and against the paper's arm;
:func:`optima_record` does the same for a multistart, with its distinct optima.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from youbot_opt._typing import JSONDict
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.reproduction.study1 import (
    STUDY_DAMPING,
    StudyDeviations,
    StudyTranscription,
    study1_problem,
)
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel
from youbot_opt.trajopt.certify import certify
from youbot_opt.trajopt.multistart import MultistartResult
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.transcription import Transcription, get_transcription

__all__ = ["VARIANTS", "ArmSolvers", "Variant", "ablation_variant", "optima_record", "record"]


class Variant(NamedTuple):
    """A transcription on an arm: one column of the comparison.

    Attributes
    ----------
    key : str
        Identifier (``"study"``, ``"trapezoidal"``, ``"hermite_simpson_b0.1"``, ...).
    label : str
        Human-readable name for the tables.
    method : str
        ``"study1_code"``, ``"trapezoidal"`` or ``"hermite_simpson"``.
    deviations : StudyDeviations or None
        The study's deviations (``method == "study1_code"`` only).
    damping : float
        Joint damping of the arm model in [N m s/rad] (0 for the paper's arm;
        the study's code adds its damping through deviation (3) instead).
    """

    key: str
    label: str
    method: str
    deviations: StudyDeviations | None = None
    damping: float = 0.0

    def transcription(self) -> Transcription:
        """Return the transcription strategy of this variant."""
        if self.deviations is not None:
            return StudyTranscription(self.deviations)
        return get_transcription(self.method)

    @property
    def model_damping(self) -> float:
        """Damping in [N m s/rad] of the dynamics the NLP describes."""
        return self.deviations.damping if self.deviations is not None else self.damping

    def objective(self, result: TrajOptResult) -> float:
        """Return the objective as this variant's NLP defines it (the study's code: T = n dt)."""
        if self.deviations is not None:
            return self.deviations.objective(result)
        return float(result.objective)


def ablation_variant(deviations: StudyDeviations) -> Variant:
    """Make the variant of the study's transcription with ``deviations``, keyed by their label."""
    return Variant(
        key=f"deviations {deviations.label}",
        label=f"deviations {deviations.label}",
        method=StudyTranscription.name,
        deviations=deviations,
    )


VARIANTS: dict[str, Variant] = {
    v.key: v
    for v in (
        Variant("study", "study's code, deviations (1)-(4)", "study1_code", StudyDeviations()),
        Variant("trapezoidal", "trapezoidal, b = 0", "trapezoidal"),
        Variant("hermite_simpson", "Hermite-Simpson, b = 0", "hermite_simpson"),
        Variant("trapezoidal_b0.1", "trapezoidal, b = 0.1", "trapezoidal", None, STUDY_DAMPING),
        Variant(
            "hermite_simpson_b0.1",
            "Hermite-Simpson, b = 0.1",
            "hermite_simpson",
            None,
            STUDY_DAMPING,
        ),
    )
}
"""The comparison's columns: the study's code, and the correct transcriptions with b = 0 and 0.1."""


class ArmSolvers:
    """Each (variant, knots) solver built once; arm models by damping.

    Parameters
    ----------
    options : IpoptOptions
        Options of every solver built.
    """

    def __init__(self, options: IpoptOptions) -> None:
        self.options = options
        self._robots: dict[float, RobotModel] = {}
        self._solvers: dict[tuple[str, int], TrajOptSolver] = {}

    def robot(self, damping: float) -> RobotModel:
        """Return the youBot arm with joint damping ``damping`` in [N m s/rad] (cached)."""
        if damping not in self._robots:
            self._robots[damping] = load_model("youbot", damping=damping or None)
        return self._robots[damping]

    def get(self, variant: Variant, n_knots: int) -> TrajOptSolver:
        """Return the solver of ``variant`` at ``n_knots`` knots (built on first use)."""
        key = (variant.key, n_knots)
        if key not in self._solvers:
            problem = study1_problem(n_knots, robot=self.robot(variant.damping))
            self._solvers[key] = TrajOptSolver(problem, variant.transcription(), self.options)
        return self._solvers[key]


def _certificate(result: TrajOptResult, robot: RobotModel) -> dict[str, Any] | None:
    if result.trajectory is None:
        return None
    cert = certify(result, robot=robot, damping=True)
    out = cert.summary()
    out["failures"] = cert.failures()
    return out


def record(
    variant: Variant, result: TrajOptResult, solvers: ArmSolvers | None = None, **extra: object
) -> JSONDict:
    """JSON-ready figures of one solve, with its certificates.

    Parameters
    ----------
    variant : Variant
        What was solved.
    result : TrajOptResult
        The solve.
    solvers : optional
        Source of the arm models for the certificates (internal); without it no
        certificate is computed.
    **extra
        Further fields (e.g. ``count`` of a local optimum).

    Returns
    -------
    dict
        ``objective`` (the variant's own, the study's code with T = n dt),
        ``objective_true`` (T = (n - 1) dt), ``duration_s`` (true), ``duration_code_s``
        (the T its objective used), ``dt_s``, ``work``, status, iterations, the knot-1
        and last-knot torques [N m], ``certificate`` (against the arm the NLP
        describes, damping included) and ``certificate_paper`` (the paper's arm, b = 0).
    """
    n = result.problem.n_knots
    dev = variant.deviations
    row: JSONDict = {
        "variant": variant.key,
        "label": variant.label,
        "deviations": None if dev is None else dev.label,
        "n_knots": n,
        "beta": result.beta,
        "status": result.status.value,
        "success": result.success,
        "objective": variant.objective(result),
        "objective_true": float(result.objective),
        "duration_s": float(result.duration),
        "duration_code_s": float(dev.duration(result.dt, n) if dev else result.duration),
        "dt_s": float(result.dt),
        "work": float(result.work),
        "iterations": int(result.iterations),
        "solve_time_s": float(result.wall_time),
        "seed": result.seed,
        "tau_first": np.asarray(result.variables["tau"][0]).tolist(),
        "tau_last": np.asarray(result.variables["tau"][-1]).tolist(),
        **_upright(result),
        **extra,
    }
    if solvers is not None and result.success:
        own = _certificate(result, solvers.robot(variant.model_damping))
        paper = own if variant.model_damping == 0.0 else _certificate(result, solvers.robot(0.0))
        row["certificate"], row["certificate_paper"] = own, paper
    return row


def _upright(result: TrajOptResult, radius: float = 0.1) -> dict[str, float]:
    """Closest approach to the upright, stretched arm ``q = 0`` [rad] and time spent near it [s]."""
    dist = np.max(np.abs(np.asarray(result.variables["q"])), axis=1)
    return {
        "upright_distance_rad": float(np.min(dist)),
        "upright_time_s": float(np.count_nonzero(dist < radius) * result.dt),
    }


def optima_record(
    variant: Variant,
    ms: MultistartResult,
    solvers: ArmSolvers,
    *,
    with_trajectory: bool = False,
    obj_tol: float = 1e-6,
) -> JSONDict:
    """Best record plus every distinct optimum (objective, T, W, count) of a multistart.

    Parameters
    ----------
    variant : Variant
        What was solved.
    ms : MultistartResult
        The multistart.
    solvers : ArmSolvers
        Source of the arm models for the certificates.
    with_trajectory : bool
        Add the best solve's knot arrays (``trajectory``: t, q, v, tau) to its record.
    obj_tol : float
        Relative objective tolerance of the clustering into optima (the
        trajectory distance tolerance is 1e-2 rad, the multistart's default).

    Returns
    -------
    dict
        ``n_starts``, ``success_rate``, ``statuses`` (count per status),
        ``wall_time_s``, ``best`` (:func:`record`) and ``optima``.
    """
    optima = []
    for opt in ms.distinct_optima(obj_tol=obj_tol, dist_tol=1e-2):
        res = opt.best.result
        assert res is not None
        optima.append({
            "objective": variant.objective(res), "objective_true": opt.objective,
            "duration_s": opt.duration, "work": opt.work, "count": opt.count,
            "fraction": opt.fraction, **_upright(res),
        })  # fmt: skip
    best = ms.best
    extra = {"trajectory": _arrays(best.result)} if with_trajectory and best and best.result else {}
    return {
        "n_starts": ms.n_starts,
        "success_rate": ms.success_rate,
        "statuses": _status_counts(ms),
        "wall_time_s": ms.wall_time,
        "best": None
        if best is None or best.result is None
        else record(variant, best.result, solvers, **extra),
        "optima": optima,
    }


def _status_counts(ms: MultistartResult) -> dict[str, int]:
    """How many starts ended with each status (``"error"`` for a start that raised)."""
    counts: dict[str, int] = {}
    for s in ms.starts:
        counts[s.status] = counts.get(s.status, 0) + 1
    return counts


def _arrays(result: TrajOptResult) -> dict[str, list[Any]]:
    """Knot times [s], q [rad], v [rad/s] and tau [N m] of a result, as lists."""
    traj = result.trajectory
    if traj is None:
        return {}
    return {name: np.asarray(getattr(traj, name)).tolist() for name in ("t", "q", "v", "tau")}
