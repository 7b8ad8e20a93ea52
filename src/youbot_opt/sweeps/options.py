"""How a sweep runs: :class:`SweepOptions`, the one argument every sweep takes for it.

Owns the execution settings shared by the multistarts, the Pareto sweep and
the bound-scaling study (spec: rule 6 of ``ARCHITECTURE.md``): where items
run, how many at once, the per-attempt time limit, the attempts per item,
the output directory a rerun resumes from, and the progress callback. What a
sweep computes (its solver, starts, weights, seeds) stays in its own
arguments; how it is run is this one frozen value.

    sweep = SweepOptions(executor="serial", out="runs/ms", max_attempts=3)
    res = run_multistart(solver, 50, sweep=sweep)
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.pool import ExecutorLike, WorkerPool

__all__ = ["SweepOptions"]


@dataclass(frozen=True, slots=True, kw_only=True)
class SweepOptions:
    """Execution settings of a sweep (all optional; the defaults run a process pool).

    Attributes
    ----------
    executor : {"process", "serial"}, WorkerPool or concurrent.futures.Executor, optional
        Where items run (:func:`youbot_opt.sweeps.pool.run_tasks`): a process
        pool owned by the sweep, a caller's ``WorkerPool``, this process, or a
        caller's executor (not shut down by the sweep). Default ``None``: the
        sweep's default, ``"process"`` (the IK-path multistart: ``"serial"``
        when ``workers`` is 1).
    workers : int, optional
        Items in flight at once (>= 1); default: the CPUs available (a
        caller's pool: its size).
    timeout : float, optional
        Wall-clock limit in [s] per attempt (worker pools only): an item still
        running then is killed with its worker and recorded as failed
        (``"timeout after <timeout> s"``). Default: none.
    max_attempts : int
        Attempts per item in total, earlier runs on ``out`` included (default
        2: a failed item is retried once).
    out : path-like, optional
        Output directory: each finished item is saved there as it completes
        and a rerun with the same parameters resumes.
    progress : callable ``(done, total, last)``, optional
        Called in this process as items finish; ``last`` is what the sweep
        reports per item (see each sweep).
    """

    executor: ExecutorLike | None = None
    workers: int | None = None
    timeout: float | None = None
    max_attempts: int = 2
    out: str | os.PathLike[str] | None = None
    progress: Callable[[int, int, Any], None] | None = None

    def __post_init__(self) -> None:
        ex = self.executor
        if not (ex in (None, "process", "serial") or isinstance(ex, WorkerPool | Executor)):
            raise ParameterError(
                f"executor must be 'process', 'serial', a WorkerPool or a "
                f"concurrent.futures.Executor, got {ex!r}",
                name="executor",
                value=ex,
            )
        w = self.workers
        if w is not None and (isinstance(w, bool) or not isinstance(w, int) or w < 1):
            raise ParameterError(f"workers must be an int >= 1, got {w!r}", name="workers", value=w)
        m = self.max_attempts
        if isinstance(m, bool) or not isinstance(m, int) or m < 1:
            raise ParameterError(
                f"max_attempts must be an int >= 1, got {m!r}", name="max_attempts", value=m
            )
        t = self.timeout
        if t is not None and not (
            isinstance(t, int | float) and not isinstance(t, bool) and math.isfinite(t) and t > 0
        ):
            raise ParameterError(f"timeout must be > 0 [s], got {t!r}", name="timeout", value=t)

    def with_executor(self, default: ExecutorLike) -> SweepOptions:
        """Return these options with ``executor`` set to ``default`` if it is ``None``."""
        return self if self.executor is not None else replace(self, executor=default)

    @property
    def directory(self) -> Path | None:
        """``out`` as a :class:`~pathlib.Path` (``None``: nothing is saved)."""
        return None if self.out is None else Path(self.out)
