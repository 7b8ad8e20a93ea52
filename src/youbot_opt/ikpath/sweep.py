"""Run the starts of an IK-path multistart: one task per start, saved as it finishes.

The machinery behind :func:`youbot_opt.ikpath.multistart.run_multistart`:

* each start is one keyed task (``"start_0007"``) of
  :func:`youbot_opt.sweeps.tasks.run_tasks`: a start that raises, or whose worker
  process dies (segfault, out-of-memory kill), is a failed attempt with its
  reason and is retried once; the broken pool is rebuilt and the sweep goes on.
  A start that fails every attempt becomes an ``IKStatus.CRASHED`` result
  whose message is the last reason;
* with an output directory, a :class:`~youbot_opt.sweeps.store.SweepStore`
  (kind ``"ikpath_multistart"``) saves every finished start as it completes,
  atomically: the result file ``items/<key>.ikpath`` (the JSON of
  :func:`youbot_opt.ikpath.io.encode_ikpath_result`, schema
  ``youbot_opt.ikpath_result`` with its SHA-256), then the record
  ``items/<key>.json`` (state, attempts, failure reasons). A rerun with the
  same problem, method, options, starts and seed loads the finished starts
  instead of solving them; other parameters are refused;
* IPOPT workers build one :class:`~youbot_opt.ikpath.ipopt.IpoptIKSolver` per
  process and reuse it for every start they run.
"""

from __future__ import annotations

import dataclasses
import math
import os
import threading
import uuid
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.exceptions import ResultFileError
from youbot_opt.ikpath.augmented_lagrangian import ALOptions, solve_augmented_lagrangian
from youbot_opt.ikpath.io import encode_ikpath_result, load_ikpath_result, problem_spec
from youbot_opt.ikpath.ipopt import IpoptIKSolver, IpoptOptions
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import IKPathResult, IKStatus, build_result
from youbot_opt.sweeps.tasks import ExecutorLike, Task, TaskOutcome, run_tasks
from youbot_opt.sweeps.store import SweepStore, atomic_write_bytes

__all__ = [
    "PAYLOAD_SUFFIX",
    "SWEEP_KIND",
    "SweepOutcome",
    "open_store",
    "solve_starts",
    "start_key",
]

SWEEP_KIND = "ikpath_multistart"
"""``kind`` of the sweep store of IK-path multistarts (in its ``manifest.json``)."""

PAYLOAD_SUFFIX = ".ikpath"
"""Suffix of the stored result files (JSON; not ``.json``, which names the records)."""

# Per-process (and per-thread) IPOPT solver of pool workers, keyed by the run's
# token. The only module-level state; the parent never fills it (serial runs
# pass their solver in the spec).
_WORKER = threading.local()


@dataclass(frozen=True, slots=True, kw_only=True)
class _SolveSpec:
    """What a worker needs to solve a start; pickles without the prebuilt solver."""

    problem: CyclicIKProblem
    method: str
    options: ALOptions | IpoptOptions | None
    token: str
    prebuilt: IpoptIKSolver | None = field(default=None, compare=False)

    def __getstate__(self) -> tuple[Any, ...]:
        return (self.problem, self.method, self.options, self.token)

    def __setstate__(self, state: tuple[Any, ...]) -> None:
        for name, value in zip(("problem", "method", "options", "token"), state, strict=True):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "prebuilt", None)

    def ipopt(self) -> IpoptIKSolver:
        """Return the prebuilt solver, this worker's cached one, or a new one (then cached)."""
        if self.prebuilt is not None:
            return self.prebuilt
        if getattr(_WORKER, "token", None) != self.token:
            _WORKER.solver = IpoptIKSolver(self.problem, self.options)  # type: ignore[arg-type]
            _WORKER.token = self.token
        solver: IpoptIKSolver = _WORKER.solver
        return solver


def _solve_start(spec: _SolveSpec, x0: Array) -> IKPathResult:
    """Worker task: solve one start (exceptions propagate: run_tasks records and retries)."""
    if spec.method == "al":
        return solve_augmented_lagrangian(spec.problem, x0, spec.options)  # type: ignore[arg-type]
    return spec.ipopt().solve(None, x0)


def _constraint_tol(method: str, options: ALOptions | IpoptOptions | None) -> float:
    """Return the largest accepted ``|c_i|`` in [m] of ``method`` with ``options``."""
    if method == "al":
        return (options if isinstance(options, ALOptions) else ALOptions()).constraint_tol
    return (options if isinstance(options, IpoptOptions) else IpoptOptions()).constr_viol_tol


def _crashed_result(
    problem: CyclicIKProblem,
    method: str,
    options: ALOptions | IpoptOptions | None,
    x0: Array,
    message: str,
) -> IKPathResult:
    """Return the ``CRASHED`` result of a start that produced no result (``x`` = its start)."""
    return build_result(
        problem,
        method=method,
        status=IKStatus.CRASHED,
        x=x0,
        multipliers=np.zeros(2 * problem.n_targets),
        iterations=0,
        inner_iterations=0,
        wall_time=0.0,
        message=message,
        start=x0,
        constraint_tol=_constraint_tol(method, options),
    )


def start_key(index: int, n_starts: int) -> str:
    """Store key of start ``index``: ``"start_0007"`` (wider when ``n_starts > 10000``)."""
    width = max(4, len(str(max(int(n_starts) - 1, 0))))
    return f"start_{int(index):0{width}d}"


def _options_json(method: str, options: ALOptions | IpoptOptions | None) -> dict[str, Any]:
    """JSON-ready settings of ``method`` (defaults filled in, so None equals the defaults)."""
    opts = options if options is not None else (ALOptions() if method == "al" else IpoptOptions())
    out: dict[str, Any] = {"type": type(opts).__name__}
    for f in dataclasses.fields(opts):
        value = getattr(opts, f.name)
        if isinstance(value, Mapping):
            value = {
                str(k): v if isinstance(v, str | int | float | bool | None) else repr(v)
                for k, v in sorted(value.items())
            }
        out[f.name] = value
    return out


def _save_payload(result: IKPathResult, path: Path) -> None:
    atomic_write_bytes(path, encode_ikpath_result(result))


def open_store(
    out: str | os.PathLike[str],
    problem: CyclicIKProblem,
    *,
    method: str,
    options: ALOptions | IpoptOptions | None,
    n_starts: int,
    seed: int,
    kind: str,
) -> SweepStore:
    """Open (or create) the output directory of one IK-path multistart.

    Parameters
    ----------
    out : path-like
        Output directory (created if missing).
    problem : CyclicIKProblem
        The problem (its chain, targets and ``use_limits`` go into the manifest).
    method : {"al", "ipopt"}
        Solver.
    options : ALOptions or IpoptOptions or None
        Settings of the method (``None``: its defaults).
    n_starts, seed : int
        Number of starts and seed of the random starts.
    kind : {"feasible", "uniform"}
        How random starts are drawn.

    Returns
    -------
    SweepStore
        The store; ``store.resumed`` tells whether the directory held this sweep.

    Raises
    ------
    ParameterError
        If ``out`` holds another kind of sweep or one with other parameters.
    ResultFileError
        If its manifest is corrupted or from a newer schema.
    """
    params = {
        "problem": problem_spec(problem),
        "method": method,
        "options": _options_json(method, options),
        "n_starts": int(n_starts),
        "seed": int(seed),
        "starts": kind,
    }
    return SweepStore(
        out,
        kind=SWEEP_KIND,
        params=params,
        save=_save_payload,
        load=load_ikpath_result,
        suffix=PAYLOAD_SUFFIX,
    )


class SweepOutcome(NamedTuple):
    """Per-start outcome of :func:`solve_starts`, in start order."""

    results: tuple[IKPathResult, ...]
    """One result per start (``CRASHED`` for a start that failed every attempt)."""
    attempts: tuple[int, ...]
    """Attempts made per start, earlier runs included (0: none was needed here nor before)."""
    resumed: int
    """Starts loaded from the store instead of solved."""


def _summary(index: int, result: IKPathResult) -> dict[str, Any]:
    def num(x: float) -> float | None:
        return float(x) if math.isfinite(x) else None

    return {
        "index": index,
        "status": result.status.value,
        "success": result.success,
        "objective": num(result.objective),
        "max_residual": num(result.max_residual()),
        "iterations": result.iterations,
        "wall_time_s": result.wall_time,
    }


def _load(store: SweepStore, key: str) -> IKPathResult:
    try:
        result: IKPathResult = store.load(key)
    except ResultFileError as exc:
        raise ResultFileError(
            f"{exc} (start {key!r} of the sweep in {store.directory}: delete "
            f"items/{key}.json and items/{key}{PAYLOAD_SUFFIX} to recompute it, or use "
            "another output directory)"
        ) from exc
    return result


def solve_starts(
    problem: CyclicIKProblem,
    x0s: Array,
    *,
    method: str,
    options: ALOptions | IpoptOptions | None,
    executor: ExecutorLike,
    workers: int,
    store: SweepStore | None = None,
    max_attempts: int = 2,
    on_resumed: Callable[[list[IKPathResult]], None] | None = None,
    on_final: Callable[[int, IKPathResult], None] | None = None,
) -> SweepOutcome:
    """Solve every start of ``x0s`` (loading those ``store`` holds), one task per start.

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    x0s : ndarray, shape (n_starts, n s)
        Starts in [rad].
    method : {"al", "ipopt"}
        Solver.
    options : ALOptions or IpoptOptions or None
        Settings of the method.
    executor : {"process", "serial"} or concurrent.futures.Executor
        See :func:`youbot_opt.sweeps.tasks.run_tasks`.
    workers : int
        Tasks in flight at once (>= 1).
    store : SweepStore, optional
        Where finished starts are saved and resumed from.
    max_attempts : int
        Attempts per start in total, earlier runs included (default 2: a retry).
    on_resumed : callable ``(results)``, optional
        Called once, before any solve, with the results loaded from ``store``.
    on_final : callable ``(index, result)``, optional
        Called in this process when a start is final (solved, or out of attempts).

    Returns
    -------
    SweepOutcome
        Results and attempts in start order, and the number of resumed starts.

    Raises
    ------
    ResultFileError
        If a stored record or result is corrupted or from a newer schema.
    """
    n = len(x0s)
    keys = [start_key(i, n) for i in range(n)]
    index = {k: i for i, k in enumerate(keys)}
    results: list[IKPathResult | None] = [None] * n
    attempts = [0] * n
    prebuilt = None
    if method == "ipopt" and executor == "serial":
        prebuilt = IpoptIKSolver(problem, options)  # type: ignore[arg-type]
    spec = _SolveSpec(
        problem=problem, method=method, options=options, token=uuid.uuid4().hex, prebuilt=prebuilt
    )
    todo: list[Task] = []
    for i, key in enumerate(keys):
        made = 0
        if store is not None:
            again, made = store.needs_work(key, max_attempts)
            attempts[i] = made
            if not again:
                rec = store.record(key)
                assert rec is not None  # needs_work said it exists
                if rec.state == "done":
                    results[i] = _load(store, key)
                else:
                    reason = rec.reasons[-1] if rec.reasons else "failed"
                    results[i] = _crashed_result(problem, method, options, x0s[i], reason)
                continue
        todo.append(Task(key=key, fn=_solve_start, args=(spec, x0s[i]), attempts=made))
    resumed = n - len(todo)
    if on_resumed is not None:
        on_resumed([r for r in results if r is not None])

    def record(o: TaskOutcome) -> None:
        i = index[o.key]
        attempts[i] = o.attempts
        if o.ok:
            result: IKPathResult = o.value
            if store is not None:
                store.write_done(o.key, result, _summary(i, result), attempts=o.attempts)
        else:
            result = _crashed_result(problem, method, options, x0s[i], str(o.error))
            if store is not None:
                store.write_failed(o.key, str(o.error), attempts=o.attempts)
        if o.final:
            results[i] = result
            if on_final is not None:
                on_final(i, result)

    run_tasks(
        todo, executor=executor, workers=workers, max_attempts=max_attempts, on_outcome=record
    )
    missing = [keys[i] for i, r in enumerate(results) if r is None]
    assert not missing, f"run_tasks returned no final outcome for {missing}"
    return SweepOutcome(
        results=tuple(r for r in results if r is not None),
        attempts=tuple(attempts),
        resumed=resumed,
    )
