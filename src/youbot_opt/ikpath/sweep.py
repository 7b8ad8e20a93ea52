"""Run the starts of an IK-path multistart: one task per start, saved as it finishes.

Owns what the IK-path multistart adds to the robot-agnostic sweep engine
(:mod:`youbot_opt.sweeps`): the worker task of one start (the AL solver, or
the worker's cached :class:`~youbot_opt.ikpath.ipopt.IpoptIKSolver`), the store
of one multistart (:func:`open_store`: kind ``"ikpath_multistart"``, payloads
``items/<key>.ikpath`` in the JSON of :func:`youbot_opt.ikpath.io.encode_ikpath_result`),
and :func:`solve_starts`, the resumable start loop. A start that fails every
attempt (it raised, or its worker died) becomes an ``IKStatus.CRASHED``
result whose message is the last reason.

    outcome = solve_starts(problem, x0s, method="al", options=None,
                           sweep=SweepOptions(executor="serial"), store=None)
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Callable, Mapping
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
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.pool import Task, TaskOutcome
from youbot_opt.sweeps.resume import run_resumable
from youbot_opt.sweeps.store import SweepStore, atomic_write_bytes
from youbot_opt.sweeps.worker_solver import WorkerSolver, hold_solver

__all__ = [
    "PAYLOAD_SUFFIX",
    "SWEEP_KIND",
    "SweepOutcome",
    "open_store",
    "solve_starts",
    "stored_start_rng",
    "start_key",
]

SWEEP_KIND = "ikpath_multistart"
"""``kind`` of the sweep store of IK-path multistarts (in its ``manifest.json``)."""

PAYLOAD_SUFFIX = ".ikpath"
"""Suffix of the stored result files (JSON; not ``.json``, which names the records)."""


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


_IPOPT_FIELDS_74BFA23 = ("tol", "constr_viol_tol", "max_iter", "max_wall_time", "extra")
"""The IK IPOPT settings a sweep manifest held before the unified IpoptOptions."""


def _options_json(
    method: str, options: ALOptions | IpoptOptions | None, *, every_field: bool = False
) -> dict[str, Any]:
    """JSON-ready settings of ``method`` (defaults filled in, so None equals the defaults).

    IPOPT fields added since 74bfa23 are left out when they hold their default
    (``every_field=True``: written all the same, as commit 02cdf49 did).
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
            not every_field
            and isinstance(opts, IpoptOptions)
            and f.name not in _IPOPT_FIELDS_74BFA23
            and value == getattr(defaults, f.name)
        ):
            # Fields added since 74bfa23 are written only when they differ from the
            # default, so that a store of that version still resumes (same manifest).
            continue
        if isinstance(value, Mapping):
            value = {
                str(k): v if isinstance(v, str | int | float | bool | None) else repr(v)
                for k, v in sorted(value.items())
            }
        out[f.name] = value
    return out


def _stored_options_form(
    out: str | os.PathLike[str], method: str, options: ALOptions | IpoptOptions | None
) -> dict[str, Any]:
    """Return the options as ``out``'s manifest holds them: every field if so, else compact."""
    full = _options_json(method, options, every_field=True)
    try:
        manifest = json.loads((Path(out) / "manifest.json").read_text(encoding="utf-8"))
        stored = manifest["params"]["options"]
    except (OSError, ValueError, KeyError, TypeError):
        stored = None  # no store yet, or the store itself reports the bad manifest
    return full if stored == full else _options_json(method, options)


def stored_start_rng(out: str | os.PathLike[str]) -> str:
    """How the starts of the IK sweep in ``out`` were drawn (``"per-index"`` for a new one).

    A manifest written before per-index starts names no ``start_rng``: its
    starts are ``"legacy"`` ones, and resuming it keeps them.
    """
    manifest = Path(out) / "manifest.json"
    if not manifest.is_file():
        return "per-index"
    try:
        params = json.loads(manifest.read_text(encoding="utf-8")).get("params") or {}
    except (OSError, ValueError, AttributeError):
        return "per-index"  # the store itself reports the bad manifest
    return str(params.get("start_rng", "legacy"))


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
    rng: str = "per-index",
    clean: bool = True,
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
    rng : {"per-index", "legacy"}
        How their random numbers are drawn (``"legacy"``: stores written
        before per-index starts, whose manifest does not name it).
    clean : bool
        Remove leftover temporary files (not in a shard run: other shards
        may be writing into the same folder).

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
        "options": _stored_options_form(out, method, options),
        "n_starts": int(n_starts),
        "seed": int(seed),
        "starts": kind,
    }
    if rng != "legacy":
        params["start_rng"] = rng
    return SweepStore(
        out,
        kind=SWEEP_KIND,
        params=params,
        save=_save_payload,
        load=load_ikpath_result,
        suffix=PAYLOAD_SUFFIX,
        clean=clean,
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
    sweep: SweepOptions,
    store: SweepStore | None = None,
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
    sweep : SweepOptions
        ``executor`` (``None``: ``"process"``), ``workers``, ``timeout`` in [s]
        and ``max_attempts`` (see :func:`youbot_opt.sweeps.pool.run_tasks`);
        ``out`` and ``progress`` are the caller's.
    store : SweepStore, optional
        Where finished starts are saved and resumed from.
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
    sweep = sweep.with_executor("process")
    init: tuple[Callable[..., Any] | None, tuple[Any, ...]] = (None, ())
    n = len(x0s)
    keys = [start_key(i, n) for i in range(n)]
    index = {k: i for i, k in enumerate(keys)}
    if method == "al":
        tasks = [
            Task(key=key, fn=_solve_al, args=(problem, options, x0s[i]))
            for i, key in enumerate(keys)
        ]
    else:
        # Serial runs build the solver here; pool workers build theirs on their first start.
        prebuilt = IpoptIKSolver(problem, options) if sweep.executor == "serial" else None  # type: ignore[arg-type]
        handle = WorkerSolver.of(IpoptIKSolver, problem, options, prebuilt=prebuilt)
        # On Dask the recipe goes once per worker (initializer); tasks carry its token.
        sent = handle.by_token() if sweep.distributed else handle
        tasks = [Task(key=key, fn=_solve_ipopt, args=(sent, x0s[i])) for i, key in enumerate(keys)]
        if sweep.distributed:
            init = (hold_solver, (handle,))

    def load(key: str) -> IKPathResult:
        assert store is not None  # only finished items of a store are loaded
        rec = store.record(key)
        assert rec is not None  # needs_work said it exists
        if rec.state == "done":
            return _load(store, key)
        reason = rec.reasons[-1] if rec.reasons else "failed"
        return _crashed_result(problem, method, options, x0s[index[key]], reason)

    def convert(o: TaskOutcome) -> IKPathResult:
        if o.ok:
            result: IKPathResult = o.value
            return result
        return _crashed_result(problem, method, options, x0s[index[o.key]], str(o.error))

    got = run_resumable(
        tasks,
        store=store,
        options=sweep,
        load=load,
        convert=convert,
        payload=lambda key, result: (result, _summary(index[key], result)),
        initializer=init[0],
        initargs=init[1],
        on_resumed=None if on_resumed is None else lambda done: on_resumed(list(done.values())),
        on_final=None if on_final is None else lambda key, r, _: on_final(index[key], r),
    )
    return SweepOutcome(
        results=tuple(got.items[k] for k in keys),
        attempts=tuple(got.attempts[k] for k in keys),
        resumed=got.resumed,
    )
