"""The study-1 reproduction runs: both halves, certified (spec ``trajopt.md``).

:func:`reproduce_study1` solves the study's problem with its own
transcription (all four deviations) and with the correct ones, on the
paper's arm and the damped one, in six sections (base case, second-optimum
search, deviations, beta extremes, Pareto front, refinement), certifying
every solution by forward simulation; figures become JSON-ready records for
:mod:`youbot_opt.reproduction.report`.

>>> repro = reproduce_study1(ReproductionConfig.quick())  # doctest: +SKIP
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TypedDict, Unpack

from youbot_opt._checks import check_int
from youbot_opt._typing import JSONDict
from youbot_opt.exceptions import ParameterError
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.reproduction.records import (
    VARIANTS,
    ArmSolvers,
    ablation_variant,
    optima_record,
    record,
)
from youbot_opt.reproduction.search import (
    cluster_optima,
    converged_results,
    search_record,
    vertex_multistart,
)
from youbot_opt.reproduction.study1 import DEVIATION_NAMES, StudyDeviations
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.multistart import MultistartResult, run_multistart
from youbot_opt.trajopt.pareto import DEFAULT_BETAS, ParetoFront, pareto_sweep
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver

__all__ = ["ReproductionConfig", "Study1Reproduction", "reproduce_study1"]

_log = logging.getLogger(__name__)
Progress = Callable[[str], None]


class _ConfigChanges(TypedDict, total=False):
    """Fields of :class:`ReproductionConfig` that :meth:`ReproductionConfig.quick` may override."""

    variants: tuple[str, ...]
    n_knots: int
    beta: float
    n_starts: int
    seed: int
    ablation_starts: int
    ablation_betas: tuple[float, ...]
    extreme_betas: tuple[float, ...]
    extreme_starts: int
    pareto_betas: tuple[float, ...]
    pareto_first_starts: int
    search_starts: int
    refinement_knots: tuple[int, ...]
    refinement_variants: tuple[str, ...]
    tol: float
    max_iter: int
    executor: str
    workers: int | None


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
    search_starts : int
        Starts of the second-optimum search: the study's random starts read
        literally (:func:`~youbot_opt.reproduction.study_guess.vertex_spline_guess`,
        base seed ``seed``) at the base case, solved with the study's
        transcription and with the correct trapezoidal one: does the study's
        second optimum f = 11.070 appear, and in which? 0 skips the search.
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
    search_starts: int = 200
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
            check_int(getattr(self, name), name, minimum=1)
        if self.search_starts < 0:
            raise ParameterError(
                f"search_starts must be >= 0 (0 skips the search), got {self.search_starts!r}",
                name="search_starts",
                value=self.search_starts,
            )
        if self.executor not in ("process", "serial"):
            raise ParameterError(
                f"executor must be 'process' or 'serial', got {self.executor!r}", name="executor"
            )

    @classmethod
    def quick(cls, **changes: Unpack[_ConfigChanges]) -> ReproductionConfig:
        """Make a fast subset for tests and smoke runs (about 15 s).

        The study's code and the correct trapezoidal transcription, 3 starts at the
        base case, 2 second-optimum search starts, no ablation, one extreme weight, two
        Pareto weights, and the trapezoidal refinement 50 -> 100 knots;
        ``changes`` override fields.
        """
        base: _ConfigChanges = dict(
            variants=("study", "trapezoidal"),
            n_starts=3,
            search_starts=2,
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
        """IPOPT options of every solve but the second-optimum search."""
        return IpoptOptions(tol=self.tol, max_iter=self.max_iter)


def _multistart(
    solver: TrajOptSolver, config: ReproductionConfig, n_starts: int, beta: float
) -> MultistartResult:
    ms = run_multistart(
        solver, n_starts, beta=beta, seed=config.seed,
        sweep=SweepOptions(executor=config.executor, workers=config.workers),  # type: ignore[arg-type]
    )  # fmt: skip
    assert isinstance(ms, MultistartResult)  # no shard: the whole sweep ran
    return ms


@dataclass(frozen=True, slots=True, kw_only=True)
class Study1Reproduction:
    """Every figure of the reproduction, as JSON-ready records.

    Attributes
    ----------
    config : ReproductionConfig
        What was run.
    base : dict
        Variant key -> multistart at (beta, n_knots): ``best`` record (with its
        ``trajectory`` arrays), ``optima``, rates.
    search : dict
        Variant key (``"study"``, ``"trapezoidal"``) -> the second-optimum search
        from vertex-LP starts (as ``base``, every optimum with its own record);
        empty when skipped.
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
    results : dict
        Name -> the :class:`TrajOptResult` behind each record (``base_study``,
        ``pareto_trapezoidal_beta0.50``, ``refinement_hermite_simpson_n800``,
        ...); not part of :meth:`to_json`.
    """

    config: ReproductionConfig
    base: dict[str, JSONDict] = field(default_factory=dict)
    search: dict[str, JSONDict] = field(default_factory=dict)
    ablation: list[JSONDict] = field(default_factory=list)
    extremes: dict[str, list[JSONDict]] = field(default_factory=dict)
    pareto: dict[str, list[JSONDict]] = field(default_factory=dict)
    refinement: list[JSONDict] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    results: dict[str, TrajOptResult] = field(default_factory=dict, repr=False)

    def to_json(self) -> JSONDict:
        """Return the whole reproduction as a JSON-ready dictionary."""
        from dataclasses import asdict

        cfg = asdict(self.config)
        return {
            "config": cfg,
            "base": self.base,
            "search": self.search,
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
    solvers = ArmSolvers(config.options())
    out = Study1Reproduction(config=config)
    variants = [VARIANTS[k] for k in config.variants]
    n = config.n_knots
    keep = out.results

    def store(name: str, ms: MultistartResult) -> None:
        if ms.best is not None and ms.best.result is not None:
            keep[name] = ms.best.result

    tic = time.perf_counter()
    for v in variants:
        say(f"base case: {v.label}, {config.n_starts} starts")
        ms = _multistart(solvers.get(v, n), config, config.n_starts, config.beta)
        out.base[v.key] = optima_record(v, ms, solvers, with_trajectory=True)
        store(f"base_{v.key}", ms)
    out.timings["base"] = time.perf_counter() - tic

    if config.search_starts:
        tic = time.perf_counter()
        for key in ("study", "trapezoidal"):
            v = VARIANTS[key]
            say(f"second-optimum search: {v.label}, {config.search_starts} vertex-LP starts")
            search_solver = TrajOptSolver(
                solvers.get(v, n).problem, v.transcription(), config.options()
            )
            starts = vertex_multistart(
                search_solver, config.search_starts, beta=config.beta, seed=config.seed,
                sweep=SweepOptions(
                    executor=config.executor, workers=config.workers, max_attempts=1  # type: ignore[arg-type]
                ),
            )  # fmt: skip
            out.search[key] = search_record(v, starts, solvers)
            for i, members in enumerate(cluster_optima(converged_results(starts), v.objective)):
                keep[f"search_{key}_optimum{i + 1}"] = members[0]
        out.timings["search"] = time.perf_counter() - tic

    tic = time.perf_counter()
    for dev in _ablation_sets():
        v = ablation_variant(dev)
        say(f"ablation: {v.label}")
        for beta in config.ablation_betas:
            ms = _multistart(solvers.get(v, n), config, config.ablation_starts, beta)
            if ms.best is not None and ms.best.result is not None:
                out.ablation.append(record(v, ms.best.result, solvers))
                store(f"ablation_{_slug(dev.label)}_beta{beta:.2f}", ms)
    out.timings["ablation"] = time.perf_counter() - tic

    tic = time.perf_counter()
    for v in variants:
        say(f"extremes: {v.label}")
        solver = solvers.get(v, n)
        out.extremes[v.key] = []
        for b in config.extreme_betas:
            ms = _multistart(solver, config, config.extreme_starts, b)
            out.extremes[v.key].append({"beta": b, **optima_record(v, ms, solvers)})
            store(f"extreme_{v.key}_beta{b:.2f}", ms)
    out.timings["extremes"] = time.perf_counter() - tic

    tic = time.perf_counter()
    for v in variants:
        say(f"Pareto front: {v.label}")
        front = pareto_sweep(
            solvers.get(v, n), config.pareto_betas, first_starts=config.pareto_first_starts,
            seed=config.seed,
            sweep=SweepOptions(executor=config.executor, workers=config.workers),  # type: ignore[arg-type]
        )  # fmt: skip
        assert isinstance(front, ParetoFront)  # no shard: the whole sweep ran
        out.pareto[v.key] = []
        for p in front.points:
            if p.result is None:
                rec = {"variant": v.key, "beta": p.beta, "status": p.status, "success": False}
            else:
                rec = record(v, p.result, solvers, dominated=p.dominated)
                keep[f"pareto_{v.key}_beta{p.beta:.2f}"] = p.result
            out.pareto[v.key].append(rec)
    out.timings["pareto"] = time.perf_counter() - tic

    tic = time.perf_counter()
    for key in config.refinement_variants:
        v = VARIANTS[key]
        previous: TrajOptResult | None = keep.get(f"base_{key}")
        for k in config.refinement_knots:
            say(f"refinement: {v.label}, {k} knots")
            result = solvers.get(v, k).solve(beta=config.beta, guess=previous)
            out.refinement.append(record(v, result, solvers))
            keep[f"refinement_{key}_n{k}"] = result
            previous = result if result.success else previous
    out.timings["refinement"] = time.perf_counter() - tic
    return out


def _slug(label: str) -> str:
    """Return a file-name-safe form of a deviation label: ``"(1)+(3)"`` -> ``"1_3"``."""
    return "_".join(c for c in label.replace("(", " ").replace(")", " ").replace("+", " ").split())
