"""The worker-local cache of a built solver: build it once per worker, reuse it for every item.

A :class:`WorkerSolver` travels with every task and pickles as a recipe
(``build(*args)`` and a run token); :meth:`WorkerSolver.get` returns the
prebuilt solver (serial runs, forked pools), else the one this worker built
for the token, else builds and caches one. :func:`hold_solver` is the pool
initializer that fills the cache when a worker starts. ``build`` is any callable.

    handle = WorkerSolver.of(TrajOptSolver, problem, method, options, prebuilt=solver)
    run_tasks(tasks, initializer=hold_solver, initargs=(handle,))
"""

from __future__ import annotations

import threading
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

__all__ = ["WorkerSolver", "hold_solver"]

S = TypeVar("S")

# Per-process (and per-thread) solver of pool workers, keyed by the run's token:
# set by the pool initializer or the first task, read by every later task. It is
# filled only inside workers (and by serial runs that pass no prebuilt solver).
_CACHE = threading.local()


@dataclass(frozen=True, slots=True, kw_only=True)
class WorkerSolver(Generic[S]):
    """A solver for the items of one sweep run: prebuilt here, rebuilt once per worker.

    Attributes
    ----------
    build : callable
        Module-level (picklable) callable that builds the solver, e.g. a class.
    args : tuple
        Its positional arguments (picklable for spawned workers).
    token : str
        Identifies the run: a worker's cached solver is reused only for it.
    prebuilt : object, optional
        The solver already built in this process; not pickled.
    ship : bool
        Pickle the recipe (default). ``False`` (:meth:`by_token`): pickle only
        the token, for tasks sent to workers that hold the solver already
        (Dask: the initializer :func:`hold_solver` is sent once per worker).
    """

    build: Callable[..., S]
    args: tuple[object, ...] = ()
    token: str = field(default_factory=lambda: uuid.uuid4().hex)
    prebuilt: S | None = field(default=None, compare=False)
    ship: bool = field(default=True, compare=False)

    @classmethod
    def of(
        cls, build: Callable[..., S], *args: object, prebuilt: S | None = None
    ) -> WorkerSolver[S]:
        """Make the handle of one run (a fresh token) for ``build(*args)``."""
        return cls(build=build, args=tuple(args), prebuilt=prebuilt)

    def by_token(self) -> WorkerSolver[S]:
        """Return this handle, pickled as its token (for workers that hold the solver already)."""
        return WorkerSolver(
            build=self.build, args=self.args, token=self.token, prebuilt=self.prebuilt, ship=False
        )

    def __getstate__(self) -> tuple[Any, ...]:
        if not self.ship:
            return (None, (), self.token, False)
        return (self.build, self.args, self.token, True)

    def __setstate__(self, state: tuple[Any, ...]) -> None:
        for name, value in zip(("build", "args", "token", "ship"), state, strict=True):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "prebuilt", None)

    def get(self) -> S:
        """Return the prebuilt solver, this worker's cached one, or a new one (then cached).

        Raises
        ------
        RuntimeError
            If the handle travelled by token and this worker holds no solver for it.
        """
        if self.prebuilt is not None:
            return self.prebuilt
        if getattr(_CACHE, "token", None) != self.token:
            if self.build is None:
                raise RuntimeError(
                    f"this worker holds no solver for sweep run {self.token} "
                    "(its initializer hold_solver did not run here)"
                )
            _CACHE.solver = self.build(*self.args)
            _CACHE.token = self.token
        solver: S = _CACHE.solver
        return solver


def hold_solver(handle: WorkerSolver[S]) -> None:
    """Pool initializer: hold ``handle``'s solver for every item this worker runs."""
    _CACHE.solver = handle.get()
    _CACHE.token = handle.token
