"""Tests of youbot_opt.sweeps.options.SweepOptions and youbot_opt.sweeps.worker_solver."""

from __future__ import annotations

import dataclasses
import pickle
from pathlib import Path

import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.worker_solver import WorkerSolver, hold_solver


def test_defaults_and_frozen() -> None:
    """Defaults: the sweep's executor, all CPUs, no limit, 2 attempts, nothing saved."""
    opts = SweepOptions()
    assert (opts.executor, opts.workers, opts.timeout, opts.max_attempts) == (None, None, None, 2)
    assert opts.out is None and opts.directory is None and opts.progress is None
    assert opts.with_executor("process").executor == "process"
    assert SweepOptions(executor="serial").with_executor("process").executor == "serial"
    assert SweepOptions(out="x").directory == Path("x")
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.workers = 3  # type: ignore[misc]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"executor": "threads"}, "executor must be"),
        ({"workers": 0}, "workers must be an int >= 1, got 0"),
        ({"workers": True}, "workers must be an int >= 1"),
        ({"max_attempts": 0}, "max_attempts must be an int >= 1, got 0"),
        ({"timeout": -1}, r"timeout must be > 0 \[s\], got -1"),
        ({"timeout": float("inf")}, "timeout must be > 0"),
        ({"keep_results": 0}, "keep_results must be True or False, got 0"),
        ({"keep_results": False}, "keep_results=False needs out="),
        ({"worker_writes": "yes"}, "worker_writes must be True, False or None"),
    ],
)
def test_bad_options_are_refused(kwargs: dict[str, object], match: str) -> None:
    """Each bad value raises ParameterError with the argument's name and value."""
    with pytest.raises(ParameterError, match=match) as info:
        SweepOptions(**kwargs)  # type: ignore[arg-type]
    assert info.value.name == next(iter(kwargs))


def test_worker_solver_pickles_as_a_recipe_and_is_cached_per_token() -> None:
    """The prebuilt solver stays behind; a worker builds once per run token and reuses it."""
    built = {"prebuilt": True}
    handle = WorkerSolver.of(dict, [("n", 1)], prebuilt=built)
    assert handle.get() is built
    copy = pickle.loads(pickle.dumps(handle))
    assert copy.prebuilt is None and copy.token == handle.token
    first = copy.get()
    assert first == {"n": 1} and copy.get() is first  # cached
    other = pickle.loads(pickle.dumps(WorkerSolver.of(dict, [("n", 2)])))
    assert other.get() == {"n": 2}  # another run's token: built anew
    hold_solver(handle)  # the pool initializer holds the prebuilt one for this token
    assert copy.get() is built


def test_workers_write_their_items_where_they_share_the_folder() -> None:
    """By default workers on this machine write their own items; Dask workers only if told."""
    assert SweepOptions().writes_in_workers and SweepOptions(executor="serial").writes_in_workers
    remote = "tcp://10.0.0.5:8786"
    assert not SweepOptions(executor=remote).writes_in_workers
    assert SweepOptions(executor=remote, worker_writes=True).writes_in_workers
    assert not SweepOptions(worker_writes=False).writes_in_workers
