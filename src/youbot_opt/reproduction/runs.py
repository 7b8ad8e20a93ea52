"""The study-1 reproduction runs: both halves, certified (spec ``trajopt.md``).

:func:`reproduce_study1` solves the study's problem with

* the study's own transcription (:class:`~youbot_opt.reproduction.study1.StudyTranscription`,
  all four deviations), to reproduce its figures, and
* the correct transcriptions (trapezoidal and Hermite--Simpson) on the paper's
  arm (no damping) and on the arm with the code's damping b = 0.1 N m s/rad,

in five sections: the base case (beta = 0.5, n = 50, seeded random-spline
multistart as the study did), the deviations switched on alone and left out
one at a time, the beta extremes, the weighted-sum Pareto front, and the
optimum as knots are added. Every solution is certified by forward simulation
(:func:`youbot_opt.verify.certify`) against the arm its NLP describes and
against the paper's arm. Every figure is a JSON-ready record (:func:`record`)
that :mod:`youbot_opt.reproduction.report` turns into tables.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from youbot_opt.exceptions import ParameterError
from youbot_opt.model import RobotModel, load_model
from youbot_opt.multistart import MultistartResult, run_multistart
from youbot_opt.options import IpoptOptions
from youbot_opt.pareto import DEFAULT_BETAS, pareto_sweep
from youbot_opt.problem import study1_problem
from youbot_opt.reproduction.study1 import (
    DEVIATION_NAMES,
    STUDY_DAMPING,
    StudyDeviations,
    StudyTranscription,
)
from youbot_opt.result import TrajOptResult
from youbot_opt.solve import TrajOptSolver
from youbot_opt.transcription import Transcription, get_transcription
from youbot_opt.verify import certify

__all__ = [
    "VARIANTS",
    "ReproductionConfig",
    "Study1Reproduction",
    "Variant",
    "ablation_variant",
    "record",
    "reproduce_study1",
]

_log = logging.getLogger(__name__)
Progress = Callable[[str], None]


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


@dataclass(frozen=True, slots=True, kw_only=True)
class ReproductionConfig:
    """What :func:`reproduce_study1` runs (defaults: the full study; :meth:`quick`: a subset).

    Attributes
    ----------
    variants : tuple of str
        Keys of :data:`VARIANTS` to compare (``"study"`` first).
    n_knots : int
        Knots of the base case, extremes, ablation and Pareto front (the study: 50).
    beta : float
        Base-case time weight (the study: 0.5).
    n_starts : int
        Seeded random spline starts of the base case (the study: 50).
    seed : int
        Base seed of every multistart.
    ablation_starts : int
        Starts per deviation set of the ablation.
    ablation_betas : tuple of float
        Time weights of the ablation (0.5: base case; 0.05: long-duration
        effect); empty to skip the ablation.
    extreme_betas : tuple of float
        Time weights of the extremes section.
    extreme_starts : int
        Starts per extreme weight.
    pareto_betas : tuple of float
        Weights of the Pareto sweep (the study: 0.05 .. 0.95 step 0.05).
    pareto_first_starts : int
        Seeded starts (plus the straight line) at the sweep's first weight; the
        others are warm-started from their neighbour.
    refinement_knots : tuple of int
        Knot counts of the refinement section.
    refinement_variants : tuple of str
        Variants refined (the study's transcription shows it does not converge).
    tol : float
        IPOPT tolerance of every solve (tight, so refinement differences are real).
    max_iter : int
        IPOPT iteration cap.
    executor : {"process", "serial"}
        Where multistart starts run.
    workers : int or None
        Parallel starts (default: the CPUs available).
    """

    variants: tuple[str, ...] = tuple(VARIANTS)
    n_knots: int = 50
    beta: float = 0.5
    n_starts: int = 50
    seed: int = 0
    ablation_starts: int = 10
    ablation_betas: tuple[float, ...] = (0.5, 0.05)
    extreme_betas: tuple[float, ...] = (0.0, 0.05, 0.95, 1.0)
    extreme_starts: int = 50
    pareto_betas: tuple[float, ...] = DEFAULT_BETAS
    pareto_first_starts: int = 10
    refinement_knots: tuple[int, ...] = (50, 100, 200, 400, 800)
    refinement_variants: tuple[str, ...] = ("trapezoidal", "hermite_simpson", "study")
    tol: float = 1e-10
    max_iter: int = 3000
    executor: str = "process"
    workers: int | None = None

    def __post_init__(self) -> None:
        for name in ("variants", "refinement_variants"):
            bad = [k for k in getattr(self, name) if k not in VARIANTS]
            if bad:
                raise ParameterError(
                    f"{name} {bad} unknown; choose among {list(VARIANTS)}", name=name, value=bad
                )
        for name in ("n_starts", "ablation_starts", "extreme_starts"):
            if getattr(self, name) < 1:
                raise ParameterError(f"{name} must be >= 1", name=name, value=getattr(self, name))
        if self.executor not in ("process", "serial"):
            raise ParameterError(
                f"executor must be 'process' or 'serial', got {self.executor!r}", name="executor"
            )

    @classmethod
    def quick(cls, **changes: Any) -> ReproductionConfig:
        """Make a fast subset for tests and smoke runs (about 15 s).

        The study's code and the correct trapezoidal transcription, 3 starts at the
        base case, no ablation, one extreme weight, two Pareto weights, and the
        trapezoidal refinement 50 -> 100 knots; ``changes`` override fields.
        """
        base: dict[str, Any] = dict(
            variants=("study", "trapezoidal"),
            n_starts=3,
            ablation_starts=1,
            ablation_betas=(),
            extreme_betas=(0.95,),
            extreme_starts=1,
            pareto_betas=(0.5, 0.95),
            pareto_first_starts=0,
            refinement_knots=(50, 100),
            refinement_variants=("trapezoidal",),
            executor="serial",
        )
        base.update(changes)
        return cls(**base)

    def options(self) -> IpoptOptions:
        """IPOPT options of every solve."""
        return IpoptOptions(tol=self.tol, max_iter=self.max_iter)


class _Solvers:
    """Each (variant, knots) solver built once; arm models by damping."""

    def __init__(self, options: IpoptOptions) -> None:
        self.options = options
        self._robots: dict[float, RobotModel] = {}
        self._solvers: dict[tuple[str, int], TrajOptSolver] = {}

    def robot(self, damping: float) -> RobotModel:
        if damping not in self._robots:
            self._robots[damping] = load_model("youbot", damping=damping or None)
        return self._robots[damping]

    def get(self, variant: Variant, n_knots: int) -> TrajOptSolver:
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
    variant: Variant, result: TrajOptResult, solvers: Any = None, **extra: Any
) -> dict[str, Any]:
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
    row: dict[str, Any] = {
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


def _multistart(
    solver: TrajOptSolver, config: ReproductionConfig, n_starts: int, beta: float
) -> MultistartResult:
    return run_multistart(
        solver, n_starts, beta=beta, seed=config.seed, executor=config.executor,  # type: ignore[arg-type]
        workers=config.workers,
    )  # fmt: skip


def _optima(variant: Variant, ms: MultistartResult, solvers: _Solvers) -> dict[str, Any]:
    """Best record plus every distinct optimum (objective, T, W, count) of a multistart."""
    optima = []
    for opt in ms.distinct_optima(obj_tol=1e-6, traj_tol=1e-2):
        res = opt.best.result
        assert res is not None
        optima.append({
            "objective": variant.objective(res), "objective_true": opt.objective,
            "duration_s": opt.duration, "work": opt.work, "count": opt.count,
            "fraction": opt.fraction, **_upright(res),
        })  # fmt: skip
    best = ms.best
    return {
        "n_starts": ms.n_starts,
        "success_rate": ms.success_rate,
        "wall_time_s": ms.wall_time,
        "best": None
        if best is None or best.result is None
        else record(variant, best.result, solvers),
        "optima": optima,
    }


@dataclass(frozen=True, slots=True, kw_only=True)
class Study1Reproduction:
    """Every figure of the reproduction, as JSON-ready records.

    Attributes
    ----------
    config : ReproductionConfig
        What was run.
    base : dict
        Variant key -> multistart at (beta, n_knots): ``best`` record, ``optima``, rates.
    ablation : list of dict
        Records of the study's transcription with deviation sets (none, each alone,
        each left out, all) at each ablation weight, best of the starts.
    extremes : dict
        Variant key -> list of multistart summaries (as ``base``), one per extreme weight.
    pareto : dict
        Variant key -> list of records in sweep order, with ``dominated`` marked.
    refinement : list of dict
        Records of the refinement (variant x knots), each warm-started from the coarser.
    timings : dict
        Wall time of each section in [s].
    """

    config: ReproductionConfig
    base: dict[str, Any] = field(default_factory=dict)
    ablation: list[dict[str, Any]] = field(default_factory=list)
    extremes: dict[str, Any] = field(default_factory=dict)
    pareto: dict[str, Any] = field(default_factory=dict)
    refinement: list[dict[str, Any]] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """Return the whole reproduction as a JSON-ready dictionary."""
        from dataclasses import asdict

        cfg = asdict(self.config)
        return {
            "config": cfg,
            "base": self.base,
            "ablation": self.ablation,
            "extremes": self.extremes,
            "pareto": self.pareto,
            "refinement": self.refinement,
            "timings": self.timings,
        }


def _ablation_sets() -> list[StudyDeviations]:
    full = StudyDeviations()
    sets = [StudyDeviations.none(), *(StudyDeviations.only(n) for n in DEVIATION_NAMES)]
    return [*sets, *(full.without(n) for n in DEVIATION_NAMES), full]


def reproduce_study1(
    config: ReproductionConfig | None = None, progress: Progress | None = None
) -> Study1Reproduction:
    """Run both halves of the study-1 reproduction (module docstring).

    Parameters
    ----------
    config : ReproductionConfig, optional
        What to run; the full study by default (minutes), ``ReproductionConfig.quick()``
        for a subset.
    progress : callable ``(message)``, optional
        Called as each section and variant starts.

    Returns
    -------
    Study1Reproduction
        Every record.
    """
    config = ReproductionConfig() if config is None else config
    say = progress or (lambda message: _log.info("%s", message))
    solvers = _Solvers(config.options())
    out = Study1Reproduction(config=config)
    variants = [VARIANTS[k] for k in config.variants]
    n = config.n_knots
    best_results: dict[str, TrajOptResult] = {}

    tic = time.perf_counter()
    for v in variants:
        say(f"base case: {v.label}, {config.n_starts} starts")
        ms = _multistart(solvers.get(v, n), config, config.n_starts, config.beta)
        out.base[v.key] = _optima(v, ms, solvers)
        if ms.best is not None and ms.best.result is not None:
            best_results[v.key] = ms.best.result
    out.timings["base"] = time.perf_counter() - tic

    tic = time.perf_counter()
    for dev in _ablation_sets():
        v = ablation_variant(dev)
        say(f"ablation: {v.label}")
        for beta in config.ablation_betas:
            best = _multistart(solvers.get(v, n), config, config.ablation_starts, beta).best
            if best is not None and best.result is not None:
                out.ablation.append(record(v, best.result, solvers))
    out.timings["ablation"] = time.perf_counter() - tic

    tic = time.perf_counter()
    for v in variants:
        say(f"extremes: {v.label}")
        solver = solvers.get(v, n)
        out.extremes[v.key] = [
            {
                "beta": b,
                **_optima(v, _multistart(solver, config, config.extreme_starts, b), solvers),
            }
            for b in config.extreme_betas
        ]
    out.timings["extremes"] = time.perf_counter() - tic

    tic = time.perf_counter()
    for v in variants:
        say(f"Pareto front: {v.label}")
        front = pareto_sweep(
            solvers.get(v, n), config.pareto_betas, first_starts=config.pareto_first_starts,
            seed=config.seed, executor=config.executor, workers=config.workers,  # type: ignore[arg-type]
        )  # fmt: skip
        out.pareto[v.key] = [
            record(v, p.result, solvers, dominated=p.dominated) if p.result is not None
            else {"variant": v.key, "beta": p.beta, "status": p.status, "success": False}
            for p in front.points
        ]  # fmt: skip
    out.timings["pareto"] = time.perf_counter() - tic

    tic = time.perf_counter()
    for key in config.refinement_variants:
        v = VARIANTS[key]
        previous: TrajOptResult | None = best_results.get(key)
        for k in config.refinement_knots:
            say(f"refinement: {v.label}, {k} knots")
            result = solvers.get(v, k).solve(beta=config.beta, guess=previous)
            out.refinement.append(record(v, result, solvers))
            previous = result if result.success else previous
    out.timings["refinement"] = time.perf_counter() - tic
    return out
