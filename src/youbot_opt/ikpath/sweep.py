"""Run the starts of an IK multistart (planar or 3-D): one task per start, saved as it ends.

Owns what the IK multistarts add to the robot-agnostic sweep engine
(:mod:`youbot_opt.sweeps`), once for both problem kinds: the resumable start loop
:func:`solve_starts`, whose problem-specific parts (worker tasks, crashed result,
summary figures, store format) come in a :class:`StartSolvers` (:data:`PLANAR_STARTS`,
:data:`STARTS_3D`); the manifest rule (:func:`options_json`,
:func:`store_params`, :func:`result_codec`), start keys and progress. A start that
fails every attempt becomes a ``CRASHED`` result whose message is the last reason.

    outcome = solve_starts(problem, x0s, method="al", options=None, solvers=PLANAR_STARTS,
                           sweep=SweepOptions(executor="serial"), store=None)
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, NamedTuple, Protocol, TypeVar

import numpy as np

from youbot_opt._files import MIGRATION_SCRIPT
from youbot_opt._typing import Array, JSONDict
from youbot_opt.exceptions import ResultFileError
from youbot_opt.ikpath.io import encode_result, load_result, problem_spec, problem_spec_3d
from youbot_opt.ikpath.methods.al import (
    AL_OPTIONS_3D,
    ALOptions,
    solve_augmented_lagrangian,
    solve_augmented_lagrangian_3d,
)
from youbot_opt.ikpath.methods.ipopt import IpoptIKSolver, IpoptIKSolver3D, IpoptOptions
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import IKPathResult, build_result
from youbot_opt.ikpath.stored import (
    ClusterIndices,
    StartSummary,
    StoredResults,
    closest_start,
)
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.sweeps.multistart import LazyStarts, StartTally, tally_starts
from youbot_opt.sweeps.optima import KeepRule
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.pool import Task, TaskOutcome
from youbot_opt.sweeps.resume import ShardReport, run_resumable
from youbot_opt.sweeps.selection import Clusters
from youbot_opt.sweeps.store import Codec, ItemRecord, SweepStore, atomic_write_bytes
from youbot_opt.sweeps.tasks import TaskSequence
from youbot_opt.sweeps.worker_solver import WorkerSolver, hold_solver

__all__ = [
    "PAYLOAD_SUFFIX",
    "PLANAR_STARTS",
    "STARTS_3D",
    "SWEEP_KIND",
    "SWEEP_KIND_3D",
    "StartScore",
    "StartSolvers",
    "StreamedOutcome",
    "SweepOutcome",
    "crashed_result",
    "encoded_saver",
    "minima_rule",
    "options_json",
    "progress_callbacks",
    "status_counts",
    "result_codec",
    "store_params",
    "solve_starts",
    "stream_starts",
    "start_key",
]

SWEEP_KIND = "ikpath_multistart"
"""``kind`` of the sweep store of IK-path multistarts (in its ``manifest.json``)."""

PAYLOAD_SUFFIX = ".ikpath"
"""Suffix of the stored result files (JSON; not ``.json``, which names the records)."""

SWEEP_KIND_3D = "spatial_ikpath_multistart"
"""``kind`` of the sweep store of a multistart by the general (3-D) methods (its manifest)."""

_PAYLOAD_SUFFIX_3D = ".spatial"  # JSON of encode_result (".json" names the records)


ProblemT = TypeVar("ProblemT")
ResultT = TypeVar("ResultT", bound=IKPathResult)


class StartScore(Protocol):
    """What the progress callbacks read of a final start: a result or a :class:`StartSummary`."""

    @property
    def success(self) -> bool:
        """Whether the start met the targets."""
        ...

    @property
    def objective(self) -> float:
        """``E`` in [rad^2]."""
        ...


def _solve_al(problem: CyclicIKProblem, options: ALOptions | None, x0: Array) -> IKPathResult:
    """Worker task: one start with the AL solver (exceptions propagate: they are retried)."""
    return solve_augmented_lagrangian(problem, x0, options)


def _solve_ipopt(handle: WorkerSolver[IpoptIKSolver], x0: Array) -> IKPathResult:
    """Worker task: one start with this worker's IPOPT solver (built once per worker)."""
    return handle.get().solve(None, x0)


def _constraint_tol(method: str, options: ALOptions | IpoptOptions | None) -> float:
    """Return the largest accepted ``|c_i|`` in [m] of ``method`` with ``options``."""
    if method == "al":
        return (options if isinstance(options, ALOptions) else ALOptions()).constraint_tol
    ipopt = options if isinstance(options, IpoptOptions) else IpoptOptions.for_ikpath()
    return float(ipopt.constr_viol_tol)  # type: ignore[arg-type]


def crashed_result(
    build: Callable[..., ResultT],
    problem: CyclicIKProblem,
    method: str,
    x0: Array,
    message: str,
    **fields: object,
) -> ResultT:
    """Return the ``CRASHED`` result of a start that produced none (configurations = its start).

    Parameters
    ----------
    build : callable
        The result constructor (:func:`~youbot_opt.ikpath.result.build_result`).
    problem : CyclicIKProblem or CyclicIKProblem
        The problem.
    method : str
        The method that was to solve the start.
    x0 : ndarray, shape (n s,)
        The start in [rad].
    message : str
        Why no result came (the last attempt's reason).
    **fields
        Further fields of ``build`` (zero multipliers, iterations and wall time are set here).
    """
    return build(
        problem,
        method=method,
        status=SolveStatus.CRASHED,
        x=x0,
        multipliers=np.zeros(problem.n_constraints),
        iterations=0,
        wall_time=0.0,
        message=message,
        start=x0,
        **fields,
    )


def _crashed_result(
    problem: CyclicIKProblem,
    method: str,
    options: ALOptions | IpoptOptions | None,
    x0: Array,
    message: str,
) -> IKPathResult:
    tol = _constraint_tol(method, options)
    return crashed_result(
        build_result, problem, method, x0, message, inner_iterations=0, constraint_tol=tol
    )


def _figures(result: IKPathResult) -> dict[str, Any]:
    """Figures of a start's record summary: its largest residual in [m]."""
    value = result.max_position_error()
    return {"max_residual": float(value) if math.isfinite(value) else None}


@dataclass(frozen=True, slots=True, kw_only=True)
class StartSolvers(Generic[ProblemT, ResultT]):
    """What a kind of IK problem (planar or spatial) gives :func:`solve_starts`.

    Every callable is a module-level function or class, so that it pickles to
    the workers.

    Attributes
    ----------
    solve_al : callable ``(problem, options, x0) -> result``
        Worker task: one start with the augmented Lagrangian (exceptions propagate).
    ipopt_solver : callable ``(problem, options) -> solver``
        Builds the IPOPT solver, once per worker.
    solve_ipopt : callable ``(handle, x0) -> result``
        Worker task: one start with the worker's solver (a :class:`WorkerSolver` of the
        planar or the spatial IPOPT solver).
    crashed : callable ``(problem, method, options, x0, message) -> result``
        The ``CRASHED`` result of a start that produced none (configurations = its start).
    figures : callable ``(result) -> dict``
        The problem's figures in a start's record summary (JSON-ready).
    store_kind : str
        ``kind`` of the problem's sweep store (in its ``manifest.json``).
    suffix : str
        Suffix of the stored result files (not ``.json``, which names the records).
    encode : callable ``(result) -> bytes``
        The content of a stored result file (the problem's result format).
    """

    solve_al: Callable[[ProblemT, ALOptions | None, Array], ResultT]
    ipopt_solver: Callable[[ProblemT, IpoptOptions | None], object]
    solve_ipopt: (
        Callable[[WorkerSolver[IpoptIKSolver], Array], ResultT]
        | Callable[[WorkerSolver[IpoptIKSolver3D], Array], ResultT]
    )
    crashed: Callable[[ProblemT, str, ALOptions | IpoptOptions | None, Array, str], ResultT]
    figures: Callable[[ResultT], JSONDict]
    store_kind: str
    suffix: str
    encode: Callable[[ResultT], bytes]


PLANAR_STARTS: StartSolvers[CyclicIKProblem, IKPathResult] = StartSolvers(
    solve_al=_solve_al,
    ipopt_solver=IpoptIKSolver,
    solve_ipopt=_solve_ipopt,
    crashed=_crashed_result,
    figures=_figures,
    store_kind=SWEEP_KIND,
    suffix=PAYLOAD_SUFFIX,
    encode=encode_result,
)
"""How :func:`solve_starts` solves the starts of a planar :class:`CyclicIKProblem`."""


def _solve_al_3d(problem: CyclicIKProblem, options: ALOptions | None, x0: Array) -> IKPathResult:
    """Worker task: one start with the general AL (exceptions propagate: they are retried)."""
    return solve_augmented_lagrangian_3d(problem, x0, options, generated=True)  # may collide


def _solve_ipopt_3d(handle: WorkerSolver[IpoptIKSolver3D], x0: Array) -> IKPathResult:
    """Worker task: one start with this worker's IPOPT solver (built once per worker)."""
    return handle.get().solve(x0, generated=True)  # a generated start may collide


def _crashed_3d(
    problem: CyclicIKProblem,
    method: str,
    options: ALOptions | IpoptOptions | None,
    x0: Array,
    message: str,
) -> IKPathResult:
    return crashed_result(build_result, problem, method, x0, message)


def _figures_3d(result: IKPathResult) -> dict[str, Any]:
    """Figures of a start's record summary: its largest target errors in [m] and [rad]."""
    return {
        "max_position_error": float(np.max(result.position_errors)),
        "max_orientation_error": float(np.max(result.orientation_errors)),
    }


STARTS_3D: StartSolvers[CyclicIKProblem, IKPathResult] = StartSolvers(
    solve_al=_solve_al_3d,
    ipopt_solver=IpoptIKSolver3D,
    solve_ipopt=_solve_ipopt_3d,
    crashed=_crashed_3d,
    figures=_figures_3d,
    store_kind=SWEEP_KIND_3D,
    suffix=_PAYLOAD_SUFFIX_3D,
    encode=encode_result,
)
"""How :func:`solve_starts` solves the starts of a problem by the general (3-D) methods."""


def start_key(index: int, n_starts: int) -> str:
    """Store key of start ``index``: ``"start_0007"`` (wider when ``n_starts > 10000``)."""
    width = max(4, len(str(max(int(n_starts) - 1, 0))))
    return f"start_{int(index):0{width}d}"


_IPOPT_FIELDS_74BFA23 = ("tol", "constr_viol_tol", "max_iter", "max_wall_time", "extra")
"""The IK IPOPT settings a sweep manifest held before the unified IpoptOptions."""
_AL_FIELDS_FINAL_PHASE = (
    "initial_multipliers",
    "retry_least_squares",
    "newton_final",
    "newton_violation",
)
"""ALOptions fields added with the spatial final phase (issue 14); written only when not
default, so that planar stores written before them still resume."""


def options_json(method: str, options: ALOptions | IpoptOptions | None) -> JSONDict:
    """Return the JSON-ready settings of ``method`` that a sweep manifest holds.

    The one rule of the planar and spatial IK sweeps. Defaults are filled in,
    so ``None`` equals :class:`ALOptions` ``()`` or :meth:`IpoptOptions.for_ikpath`.
    IPOPT fields added since 74bfa23, and the AL fields of the spatial final
    phase, are written only when they differ from their default (the manifest
    form of today's stores).

    Parameters
    ----------
    method : {"al", "ipopt"}
        The method.
    options : ALOptions or IpoptOptions or None
        Its settings.

    Returns
    -------
    dict
        ``{"type": class name, field: value, ...}``.
    """
    opts = (
        options
        if options is not None
        else (ALOptions() if method == "al" else IpoptOptions.for_ikpath())
    )
    out: dict[str, Any] = {"type": type(opts).__name__}
    defaults = IpoptOptions.for_ikpath()
    for f in dataclasses.fields(opts):
        value = getattr(opts, f.name)
        if (
            isinstance(opts, IpoptOptions)
            and f.name not in _IPOPT_FIELDS_74BFA23
            and value == getattr(defaults, f.name)
        ) or (
            isinstance(opts, ALOptions)
            and f.name in _AL_FIELDS_FINAL_PHASE
            and value == getattr(ALOptions(), f.name)
        ):
            continue  # written only when not default
        if isinstance(value, Mapping):
            value = {
                str(k): v if isinstance(v, str | int | float | bool | None) else repr(v)
                for k, v in sorted(value.items())
            }
        out[f.name] = value
    return out


def _refuse_old(out: Path) -> None:
    """Refuse an IK store of 0.1.0 in ``out``: no ``start_rng``, or every IPOPT field written.

    ``scripts/migrate_0_1_0.py`` carries such a store forward.
    """
    manifest = Path(out) / "manifest.json"
    try:
        stored = json.loads(manifest.read_text(encoding="utf-8"))
        version, params = int(stored["schema_version"]), stored["params"]
        if stored["kind"] != SWEEP_KIND:
            return  # another sweep: the store refuses it
        options = params["options"]
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return  # none, or another form: the store checks it
    defaults = IpoptOptions.for_ikpath()
    every_field = isinstance(options, dict) and any(
        name not in _IPOPT_FIELDS_74BFA23
        and name != "type"
        and hasattr(defaults, name)
        and value == getattr(defaults, name)
        for name, value in options.items()
    )
    if "start_rng" not in params or every_field:
        raise ResultFileError(
            f"sweep manifest {manifest}: written by youbot_opt 0.1.0 (schema {version}); "
            f"run `python {MIGRATION_SCRIPT} {out}` to carry it forward"
        )


def _write_encoded(encode: Callable[[Any], bytes], result: Any, path: Path) -> None:
    atomic_write_bytes(path, encode(result))


def encoded_saver(encode: Callable[[ResultT], bytes]) -> Callable[[ResultT, Path], None]:
    """Return the ``save`` of a sweep store whose payloads are ``encode(result)`` (atomic).

    A :func:`functools.partial` of module-level functions, so it pickles to workers.
    """
    return functools.partial(_write_encoded, encode)


def store_params(
    problem: CyclicIKProblem,
    *,
    planar: bool,
    method: str,
    options: ALOptions | IpoptOptions | None,
    n_starts: int,
    seed: int,
    kind: str,
) -> JSONDict:
    """Return the parameters an IK multistart's manifest binds its store to.

    The problem (planar methods: :func:`~youbot_opt.ikpath.io.problem_spec`, its
    chain, targets and ``use_limits``; general ones:
    :func:`~youbot_opt.ikpath.io.problem_spec_3d`, robot fingerprint, frame,
    targets, limits, weights), method, options (:func:`options_json`; the
    general AL's ``None`` written out as its defaults), ``n_starts``, ``seed``
    and start kind, and on the planar methods ``start_rng`` (start ``k`` does
    not depend on ``n_starts``). A rerun with any of them changed is refused
    by the store.

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    planar : bool
        Whether the planar methods solve it (the store's kind: :data:`SWEEP_KIND`,
        else :data:`SWEEP_KIND_3D`).
    method : {"al", "ipopt"}
        Solver.
    options : ALOptions or IpoptOptions or None
        Settings of the method (``None``: its defaults).
    n_starts, seed : int
        Number of starts and seed of the random starts.
    kind : str
        How random starts are drawn.
    """
    if not planar and options is None and method == "al":
        options = AL_OPTIONS_3D  # the defaults of solve(planar=False), written out
    params: dict[str, Any] = {
        "problem": problem_spec(problem) if planar else problem_spec_3d(problem),
        "method": method,
        "options": options_json(method, options),
        "n_starts": int(n_starts),
        "seed": int(seed),
        "starts": kind,
    }
    if planar:
        params["start_rng"] = "per-index"
    return params


def result_codec(
    problem: CyclicIKProblem, *, planar: bool, starts: Sequence[Array] | Array | None = None
) -> Codec[IKPathResult]:
    """Return how an IK multistart's payloads are stored: :mod:`youbot_opt.ikpath.io` JSON.

    Payloads are ``encode_result(result)``, written by the workers without a
    per-item fsync and made durable by group; each is reloaded with the same
    re-check as :func:`~youbot_opt.ikpath.io.load_result`. A planar store of
    0.1.0 is refused (``scripts/migrate_0_1_0.py`` carries it forward). With
    ``starts`` (the sweep's start configurations, by index) a payload read back
    is re-checked against the sweep's own problem (:func:`check_item`).
    """
    solvers = PLANAR_STARTS if planar else STARTS_3D
    check = None if starts is None else functools.partial(check_item, problem, planar, starts)
    return Codec(
        save=encoded_saver(solvers.encode),
        # the sweep's own problem is the caller: its targets' tolerances re-check a payload
        load=load_result
        if planar
        else functools.partial(
            load_result,
            robot=problem.model,
            position_tol=max(t.position_tol for t in problem.targets),
            orientation_tol=max(t.orientation_tol for t in problem.targets),
        ),
        suffix=solvers.suffix,
        encode=solvers.encode,
        refuse_old=_refuse_old if planar else None,
        check=check,
    )


def check_item(
    problem: CyclicIKProblem,
    planar: bool,
    starts: Sequence[Array] | Array,
    key: str,
    result: IKPathResult,
) -> str | None:
    """Why ``result``, read back as item ``key``, is not that start of the sweep (``None``: it is).

    Its problem (chain or robot, targets, tolerances, limits) must be the
    sweep's, and its start (the configurations it was solved from, which the
    item carries) must be the start the sweep itself draws for ``key``
    (``starts[i]``, equal value for value): an item of start ``j`` passed off
    under start ``i``'s key is refused and start ``i`` solved, whatever its
    checksums say. The loader has re-checked its configurations against the
    targets.
    """
    n = len(starts)
    index = key.rsplit("_", 1)[-1]
    if not (key.startswith("start_") and index.isdigit() and int(index) < n):
        return f"{key!r} is no start of this sweep"
    if start_key(int(index), n) != key:
        return f"{key!r} is no start of this sweep"
    spec = problem_spec if planar else problem_spec_3d
    mine, theirs = spec(problem), spec(result.problem)
    if mine != theirs:
        fields = sorted(k for k in set(mine) | set(theirs) if mine.get(k) != theirs.get(k))
        return f"its problem differs in {', '.join(fields) or 'its values'}"
    i = int(index)
    got = np.asarray(result.start, dtype=float).ravel()
    planned = np.asarray(starts[i], dtype=float).ravel()
    if got.size != planned.size:
        return f"its start has {got.size} values, start {i}'s has {planned.size}"
    if not np.array_equal(got, planned):
        gap = float(np.max(np.abs(got - planned)))
        return (
            f"its start is not start {i} of this sweep (they differ by up to {gap:.3g} rad): "
            "an item solved from another start"
        )
    return None


class SweepOutcome(NamedTuple, Generic[ResultT]):
    """Per-start outcome of :func:`solve_starts`, in start order."""

    results: tuple[ResultT, ...]
    """One result per start (``CRASHED`` for a start that failed every attempt)."""
    attempts: tuple[int, ...]
    """Attempts made per start, earlier runs included (0: none was needed here nor before)."""
    resumed: int
    """Starts loaded from the store instead of solved."""
    not_run: int = 0
    """Starts a deadline left unrun: they follow the starts of ``results``."""


def _summary(
    figures: Callable[[ResultT], dict[str, Any]], index: int, result: ResultT
) -> dict[str, Any]:
    """Return the JSON summary of a start in its record (``figures``: the problem's own)."""
    objective = result.objective
    return {
        "index": index,
        "status": result.status.value,
        "success": result.success,
        "objective": float(objective) if math.isfinite(objective) else None,
        **figures(result),
        "iterations": result.iterations,
        "wall_time_s": result.wall_time,
        **({} if result.success else {"message": result.message}),
    }


def _describe_start(
    figures: Callable[[ResultT], dict[str, Any]],
    key: str,
    args: tuple[Any, ...],
    result: ResultT,
) -> tuple[ResultT, dict[str, Any]]:
    """Worker side: the payload and summary of a solved start (index from its key)."""
    return result, _summary(figures, int(key.rsplit("_", 1)[1]), result)


def _load(store: SweepStore, key: str) -> Any:
    try:
        result = store.load(key)
    except ResultFileError as exc:
        raise ResultFileError(
            f"{exc} (start {key!r} of the sweep in {store.directory}: delete "
            f"{store.payload_path(key)} to recompute it, or use another output directory)"
        ) from exc
    return result


def status_counts(results: Iterable[IKPathResult]) -> dict[str, int]:
    """Count the results per status value (``{"solved": 12, "crashed": 1, ...}``)."""
    counts: dict[str, int] = {}
    for r in results:
        counts[r.status.value] = counts.get(r.status.value, 0) + 1
    return counts


def progress_callbacks(
    progress: Callable[[int, int, float], None] | None, total: int
) -> tuple[Callable[[Iterable[StartScore]], None], Callable[[int, StartScore], None]]:
    """Return the ``on_resumed`` and ``on_final`` of :func:`solve_starts` that feed ``progress``.

    ``progress(done, total, best)`` hears of the starts loaded from the store in
    one call before the first solve, then of every final start; ``best`` is the
    lowest ``E`` in [rad^2] of the successful starts so far (``inf`` before the first).
    The starts are results or (``keep_results=False``) :class:`StartSummary` s.
    """
    best = math.inf
    done = 0

    def on_resumed(results: Iterable[StartScore]) -> None:
        nonlocal best, done
        done, best = 0, math.inf
        for r in results:  # one pass (a stream when keep_results=False)
            done += 1
            if r.success:
                best = min(best, r.objective)
        if progress is not None and done:
            progress(done, total, best)

    def on_final(index: int, result: StartScore) -> None:
        nonlocal best, done
        done += 1
        if result.success:
            best = min(best, result.objective)
        if progress is not None:
            progress(done, total, best)

    return on_resumed, on_final


def solve_starts(
    problem: ProblemT,
    x0s: Array,
    *,
    method: str,
    options: ALOptions | IpoptOptions | None,
    sweep: SweepOptions,
    solvers: StartSolvers[ProblemT, ResultT],
    store: SweepStore | None = None,
    on_resumed: Callable[[list[ResultT]], None] | None = None,
    on_final: Callable[[int, ResultT], None] | None = None,
    deadline: float | None = None,
) -> SweepOutcome[ResultT] | ShardReport:
    """Solve every start of ``x0s`` (loading those ``store`` holds), one task per start.

    Parameters
    ----------
    problem : CyclicIKProblem or CyclicIKProblem
        The problem.
    x0s : ndarray, shape (n_starts, n s)
        Starts in [rad].
    method : {"al", "ipopt"}
        Solver.
    options : ALOptions or IpoptOptions or None
        Settings of the method.
    sweep : SweepOptions
        ``executor`` (``None``: ``"process"``), ``workers``, ``timeout`` in [s]
        and ``max_attempts`` (see :func:`youbot_opt.sweeps.pool.run_tasks`);
        ``out`` and ``progress`` are the caller's.
    solvers : StartSolvers
        How the problem's starts are solved: :data:`PLANAR_STARTS`, or
        :data:`STARTS_3D`.
    store : SweepStore, optional
        Where finished starts are saved and resumed from.
    on_resumed : callable ``(results)``, optional
        Called once, before any solve, with the results loaded from ``store``.
    on_final : callable ``(index, result)``, optional
        Called in this process when a start is final (solved, or out of attempts).
    deadline : float, optional
        A :func:`time.monotonic` instant after which no new start begins
        (:func:`~youbot_opt.sweeps.resume.run_resumable`): the outcome then holds
        the starts before the first unfinished one and counts the rest as ``not_run``.

    Returns
    -------
    SweepOutcome or ShardReport
        Results and attempts in start order, and the number of resumed starts;
        a shard run (``sweep.shard``) returns its :class:`ShardReport`.

    Raises
    ------
    ResultFileError
        If a stored record or result is corrupted or from a newer schema.
    """
    sweep = sweep.with_executor("process")
    init: tuple[Callable[..., Any] | None, tuple[Any, ...]] = (None, ())
    n = len(x0s)
    keys = [start_key(i, n) for i in range(n)]
    index = {k: i for i, k in enumerate(keys)}
    if method == "al":
        tasks = [
            Task(key=key, fn=solvers.solve_al, args=(problem, options, x0s[i]))
            for i, key in enumerate(keys)
        ]
    else:
        # Serial runs build the solver here; pool workers build theirs on their first start.
        build = solvers.ipopt_solver
        prebuilt = build(problem, options) if sweep.executor == "serial" else None  # type: ignore[arg-type]
        handle = WorkerSolver.of(build, problem, options, prebuilt=prebuilt)
        # On Dask the recipe goes once per worker (initializer); tasks carry its token.
        sent = handle.by_token() if sweep.distributed else handle
        tasks = [
            Task(key=key, fn=solvers.solve_ipopt, args=(sent, x0s[i])) for i, key in enumerate(keys)
        ]
        if sweep.distributed:
            init = (hold_solver, (handle,))

    def load(key: str) -> ResultT:
        assert store is not None  # only finished items of a store are loaded
        rec = store.record(key)
        assert rec is not None  # needs_work said it exists
        if rec.state == "done":
            loaded: ResultT = _load(store, key)
            return loaded
        reason = rec.reasons[-1] if rec.reasons else "failed"
        return solvers.crashed(problem, method, options, x0s[index[key]], reason)

    def convert(o: TaskOutcome) -> ResultT:
        if o.ok:
            result: ResultT = o.value
            return result
        return solvers.crashed(problem, method, options, x0s[index[o.key]], str(o.error))

    got = run_resumable(
        tasks,
        store=store,
        options=sweep,
        load=load,
        convert=convert,
        payload=lambda key, result: (result, _summary(solvers.figures, index[key], result)),
        initializer=init[0],
        initargs=init[1],
        on_resumed=None if on_resumed is None else lambda done: on_resumed(list(done.values())),
        on_final=None if on_final is None else lambda key, r, _: on_final(index[key], r),
        # workers write their own result files
        describe=functools.partial(_describe_start, solvers.figures),
        deadline=deadline,
    )
    if isinstance(got, ShardReport):  # a shard run: its share is saved, nothing to collect
        return got
    ran = keys[: n - got.not_run]
    return SweepOutcome(
        results=tuple(got.items[k] for k in ran),
        attempts=tuple(got.attempts[k] for k in ran),
        resumed=got.resumed,
        not_run=got.not_run,
    )


class StreamedOutcome(NamedTuple, Generic[ResultT]):
    """What :func:`stream_starts` returns: nothing held per start."""

    results: StoredResults[ResultT]
    """Every start's full result, loaded from the output folder when asked for."""
    attempts: Sequence[int]
    """Attempts per start in start order, read from the store when asked for."""
    resumed: int
    """Starts loaded from the store instead of solved."""
    minima: tuple[ClusterIndices, ...]
    """Start indices of each distinct minimum in cluster order (lowest ``E`` first)."""
    kept: dict[int, ResultT]
    """The representatives' full results, by start index."""
    tally: StartTally[int]
    """Counts per status, successes and (``found``) the start closest to the targets."""
    not_run: int = 0
    """Starts a deadline left unrun: they follow the starts of ``results``."""


def minima_rule(
    obj_tol: float, dist_tol: float, distance: Callable[[ResultT, ResultT], float]
) -> KeepRule[StartSummary[ResultT]]:
    """Return the distinct minima's rule over start summaries holding their results.

    :func:`~youbot_opt.ikpath.multistart.cluster_minima`'s rule: successful
    starts by ``E``, ``obj_tol`` relative on ``E``, ``dist_tol`` in [rad] on
    ``distance`` of their results (both finite and > 0, checked here).
    """
    return KeepRule(
        objective=lambda s: s.objective if s.success else None,
        distance=lambda a, b: distance(a.result, b.result),  # type: ignore[arg-type]
        obj_tol=obj_tol,
        dist_tol=dist_tol,
    )


def stream_starts(
    problem: ProblemT,
    starts: Sequence[Array] | Array,
    *,
    method: str,
    options: ALOptions | IpoptOptions | None,
    sweep: SweepOptions,
    solvers: StartSolvers[ProblemT, ResultT],
    store: SweepStore,
    distance: Callable[[ResultT, ResultT], float],
    obj_tol: float,
    dist_tol: float,
    on_resumed: Callable[[Iterable[StartScore]], None] | None = None,
    on_final: Callable[[int, StartScore], None] | None = None,
    deadline: float | None = None,
) -> StreamedOutcome[ResultT] | ShardReport:
    """Solve every start with ``keep_results=False``: summaries streamed, the minima kept.

    As :func:`solve_starts`, but a start is drawn (``starts[i]``) only when its
    task is made, each start's figures are read back from the store's journal
    as :class:`~youbot_opt.ikpath.stored.StartSummary` when needed, and only the
    distinct minima (``cluster_optima``'s rule with ``obj_tol`` on ``E`` and
    ``dist_tol`` on ``distance``, chosen by
    :func:`~youbot_opt.sweeps.selection.stream_optima`) are held in full.

    Parameters
    ----------
    starts : sequence of ndarray
        Start ``i`` in [rad], drawn when asked for (``PlanarStarts``, ``Starts3D``).
    store : SweepStore
        The output folder (required: the results not kept stay there).
    distance : callable ``(a, b) -> float``
        Distance in [rad] of two successful results' configurations.
    obj_tol, dist_tol : float
        Relative tolerance on ``E`` and tolerance in [rad] on ``distance`` (both
        finite and > 0).
    problem, method, options, sweep, solvers, on_resumed, on_final, deadline
        As :func:`solve_starts`; ``on_resumed`` is given an iterable, read once.

    Returns
    -------
    StreamedOutcome or ShardReport
        Lazy results and attempts, resumed count, minima, kept results, tally;
        a shard run (``sweep.shard``) returns its :class:`ShardReport`.
    """
    sweep = sweep.with_executor("process")
    n = len(starts)
    init: tuple[Callable[..., Any] | None, tuple[Any, ...]] = (None, ())
    if method == "al":

        def make(i: int) -> Task:
            args = (problem, options, starts[i])
            return Task(key=start_key(i, n), fn=solvers.solve_al, args=args)
    else:
        build = solvers.ipopt_solver
        prebuilt = build(problem, options) if sweep.executor == "serial" else None  # type: ignore[arg-type]
        handle = WorkerSolver.of(build, problem, options, prebuilt=prebuilt)
        sent = handle.by_token() if sweep.distributed else handle
        if sweep.distributed:
            init = (hold_solver, (handle,))

        def make(i: int) -> Task:
            return Task(key=start_key(i, n), fn=solvers.solve_ipopt, args=(sent, starts[i]))

    tasks = TaskSequence(n, make, key=lambda i: start_key(i, n))

    def index_of(key: str) -> int:
        return int(key.rsplit("_", 1)[1])

    def crashed(i: int, reason: str) -> ResultT:
        return solvers.crashed(problem, method, options, starts[i], reason)

    def of(i: int, result: ResultT, attempts: int) -> StartSummary[ResultT]:
        light: StartSummary[ResultT] = StartSummary.from_record(
            json_summary(solvers.figures, i, result), attempts
        )
        return light.with_result(result)

    def light(key: str, record: ItemRecord) -> StartSummary[ResultT]:
        if record.state == "done":
            return StartSummary.from_record(record.summary, record.attempts)
        i = index_of(key)  # failed every attempt: the figures of its CRASHED result
        reason = record.reasons[-1] if record.reasons else "failed"
        return dataclasses.replace(of(i, crashed(i, reason), record.attempts), result=None)

    def load(key: str) -> ResultT:
        record = store.record(key)
        if record is None:
            raise ResultFileError(f"start {key!r} is not finished in {store.directory}")
        if record.state == "done":
            result: ResultT = _load(store, key)
            return result
        return crashed(index_of(key), record.reasons[-1] if record.reasons else "failed")

    def full(key: str) -> StartSummary[ResultT]:
        record = store.record(key)
        assert record is not None  # only finished items are loaded
        return light(key, record).with_result(load(key))

    def convert(o: TaskOutcome) -> StartSummary[ResultT]:
        i = index_of(o.key)
        result: ResultT = o.value if o.ok else crashed(i, str(o.error))
        return of(i, result, o.attempts)

    rule = minima_rule(obj_tol, dist_tol, distance)
    got = run_resumable(
        tasks,
        store=store,
        options=sweep,
        load=full,
        convert=convert,
        payload=lambda key, s: _payload(solvers.figures, s),
        initializer=init[0],
        initargs=init[1],
        on_resumed=None if on_resumed is None else lambda done: on_resumed(done.values()),
        on_final=None if on_final is None else lambda key, s, _: on_final(s.index, s),
        describe=functools.partial(_describe_start, solvers.figures),
        light=light,
        keep=rule,
        deadline=deadline,
    )
    if isinstance(got, ShardReport):
        return got
    ran = n - got.not_run  # the starts before the first one a deadline left unrun
    items = got.items
    clusters = got.clusters
    if not isinstance(clusters, Clusters):  # pragma: no cover - IK stores never held the old form
        raise ResultFileError(f"the optima of {store.directory} are in an unknown form")
    kept: dict[int, ResultT] = {}
    for rep in clusters.representatives:
        result = items[rep].result
        assert result is not None  # the selection holds its representatives in full
        kept[index_of(rep)] = result

    def summary(i: int) -> StartSummary[ResultT]:
        return items[start_key(i, n)]

    results = StoredResults(
        ran, load=lambda i: load(start_key(i, n)), summary=summary, kept=kept, items=items,
        full=full,
    )  # fmt: skip
    return StreamedOutcome(
        results=results,
        attempts=LazyStarts(ran, lambda i: got.attempts[start_key(i, n)]),
        resumed=got.resumed,
        minima=tuple(
            ClusterIndices(clusters, c, index_of, sorted_order=False) for c in range(len(clusters))
        ),
        kept=kept,
        tally=tally_starts(
            ((s.status, s.success) for s in results.summaries()),
            found=closest_start(results.summaries()),
        ),
        not_run=got.not_run,
    )


def _payload(
    figures: Callable[[ResultT], dict[str, Any]], start: StartSummary[ResultT]
) -> tuple[ResultT, dict[str, Any]]:
    """Return what the store saves of a solved start: its result and its summary."""
    assert start.result is not None  # converted from a solve, so it holds its result
    return start.result, _summary(figures, start.index, start.result)


def json_summary(figures: Callable[[ResultT], JSONDict], index: int, result: ResultT) -> JSONDict:
    """Return a start's journal summary as the store reads it back (JSON round trip)."""
    return json.loads(json.dumps(_summary(figures, index, result)))
