"""Test-only fault injection for sweeps: tasks that segfault or hang their pool worker.

The package has no test hooks (rule 7 of ARCHITECTURE.md); the tests wrap the
function of chosen tasks instead. :func:`faulty` wraps a list of
:class:`~youbot_opt.sweeps.pool.Task` for a direct :func:`run_tasks` call;
:func:`inject` (the ``faults`` fixture of conftest.py) wraps the tasks of every
sweep that runs through ``run_tasks`` (the resumable start loop, the Pareto
points, the vertex-LP search). A fault fires only in a process other than the
one that made the wrapper (a pool worker), so serial runs are never hit; with
``once_dir`` it fires once per key and leaves a marker ``<crashed|hung>-<key>``.

    run_tasks(faulty(tasks, crash={"k2"}), executor="process")
"""

from __future__ import annotations

import dataclasses
import faulthandler
import os
import signal
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import pytest

from youbot_opt.sweeps import pool

_CALLERS = (
    "youbot_opt.sweeps.resume",
    "youbot_opt.trajopt.pareto",
    "youbot_opt.reproduction.search",
)
"""Modules that call ``run_tasks`` (their name is patched by :func:`inject`)."""


class Faulty:
    """A task function that segfaults (``"crashed"``) or hangs (``"hung"``) in a pool worker."""

    def __init__(
        self, fn: Callable[..., Any], key: str, mode: str, once_dir: str | Path | None = None
    ) -> None:
        assert mode in ("crashed", "hung")
        self.fn, self.key, self.mode = fn, key, mode
        self.once_dir = None if once_dir is None else str(once_dir)
        self.origin = os.getpid()  # the test process: faults never fire there

    def _fires(self) -> bool:
        if os.getpid() == self.origin:
            return False
        if self.once_dir is not None:
            marker = Path(self.once_dir) / f"{self.mode}-{self.key}"
            if marker.exists():
                return False
            marker.touch()
        return True

    def __call__(self, *args: Any) -> Any:
        if self._fires():
            if self.mode == "crashed":
                faulthandler.disable()  # a quiet crash: no inherited traceback dump on stderr
                os.kill(os.getpid(), signal.SIGSEGV)
            time.sleep(3600.0)  # [s] hung: only the timeout ends it
        return self.fn(*args)


def faulty(
    tasks: Iterable[pool.Task],
    *,
    crash: Iterable[str] = (),
    hang: Iterable[str] = (),
    once_dir: str | Path | None = None,
) -> list[pool.Task]:
    """Return ``tasks``, those keyed in ``crash`` (``hang``) segfaulting (hanging) in workers."""
    crash, hang = set(crash), set(hang)
    out = []
    for t in tasks:
        if t.key in crash:
            t = dataclasses.replace(t, fn=Faulty(t.fn, t.key, "crashed", once_dir))
        elif t.key in hang:
            t = dataclasses.replace(t, fn=Faulty(t.fn, t.key, "hung", once_dir))
        out.append(t)
    return out


def inject(
    monkeypatch: pytest.MonkeyPatch,
    *,
    crash: Iterable[str] = (),
    hang: Iterable[str] = (),
    once_dir: str | Path | None = None,
) -> None:
    """Make every sweep's tasks keyed in ``crash`` / ``hang`` fail so in pool workers."""
    import importlib

    real = pool.run_tasks
    crash, hang = tuple(crash), tuple(hang)

    def run_tasks(tasks: Iterable[pool.Task], **kwargs: Any) -> Any:
        return real(faulty(tasks, crash=crash, hang=hang, once_dir=once_dir), **kwargs)

    for name in _CALLERS:
        monkeypatch.setattr(importlib.import_module(name), "run_tasks", run_tasks)


class Slow:
    """A task function that sleeps ``seconds`` [s] before its work, in any process.

    Picklable by reference (this module must be importable where it runs:
    ``tests/`` on ``PYTHONPATH``), so pool workers run it too.
    """

    def __init__(self, fn: Callable[..., Any], seconds: float) -> None:
        self.fn, self.seconds = fn, seconds

    def __call__(self, *args: Any) -> Any:
        time.sleep(self.seconds)
        return self.fn(*args)


def slow_every_item(seconds: float) -> None:
    """Make every sweep item of this process's sweeps take ``seconds`` [s] longer.

    For the kill-and-resume tests (``tests/_slow_cli.py``): an item then costs
    the same on any machine, so a kill lands while work is left.
    """
    import importlib

    real = pool.run_tasks

    def run_tasks(tasks: Iterable[pool.Task], **kwargs: Any) -> Any:
        slowed = (dataclasses.replace(t, fn=Slow(t.fn, seconds)) for t in tasks)
        return real(list(slowed), **kwargs)

    for name in _CALLERS:
        importlib.import_module(name).run_tasks = run_tasks


def slow_square(x: float, seconds: float) -> float:
    """A trivial sweep task that takes ``seconds`` [s]: for kills that must land mid-sweep."""
    time.sleep(seconds)
    return x * x
