"""Tests of youbot_opt.sweeps.pool beyond crashes: plain pickling, no global state.

The crash, hang and retry tests of the pool are in tests/trajopt/test_kill_resume.py.
"""

from __future__ import annotations

import pickle
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

import pytest

from youbot_opt.sweeps.pool import Task, WorkerPool, process_context, run_tasks


def _copy(d: dict[str, int]) -> dict[str, int]:
    return dict(d)


def _total(m: dict[str, int]) -> int:
    return sum(m.values())


def test_importing_the_package_registers_no_pickler() -> None:
    """Importing the sweep modules registers no reducer in multiprocessing (nor copyreg)."""
    code = (
        "import multiprocessing.connection, concurrent.futures.process  # stdlib's own reducers\n"
        "from multiprocessing.reduction import ForkingPickler\n"
        "import copyreg\n"
        "from types import MappingProxyType\n"
        "before = dict(ForkingPickler._extra_reducers)\n"
        "import youbot_opt, youbot_opt.sweeps.pool, youbot_opt.sweeps.options\n"
        "import youbot_opt.trajopt.multistart, youbot_opt.ikpath.multistart\n"
        "after = dict(ForkingPickler._extra_reducers)\n"
        "assert before == after, set(after) ^ set(before)\n"
        "assert MappingProxyType not in copyreg.dispatch_table\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("executor", ["process", "pool", "process-executor", "threads"])
def test_mappings_cross_the_process_boundary(executor: str) -> None:
    """Dict arguments and return values travel to and from workers on every executor."""
    tasks = [
        Task(key="sum", fn=_total, args=({"a": 1, "b": 2},)),
        Task(key="make", fn=_copy, args=({"c": 3},)),
    ]
    if executor == "pool":
        with WorkerPool(1) as pool:
            out = run_tasks(tasks, executor=pool)
    elif executor == "process-executor":
        with ProcessPoolExecutor(1, mp_context=process_context()) as ex:
            out = run_tasks(tasks, executor=ex)
    elif executor == "threads":
        with ThreadPoolExecutor(1) as ex:
            out = run_tasks(tasks, executor=ex)
    else:
        out = run_tasks(tasks, executor="process", workers=2)
    assert out["sum"].ok and out["sum"].value == 3
    assert out["make"].ok and out["make"].value == {"c": 3}


def test_frozen_data_pickles_with_the_standard_pickler() -> None:
    """Options and bound structures hold plain dicts: pickle.dumps sends them, no reducer."""
    from youbot_opt.nlp.ipopt import IpoptOptions
    from youbot_opt.trajopt.result import BoundStructure

    opts = IpoptOptions(extra={"print_level": 0})
    assert pickle.loads(pickle.dumps(opts)) == opts
    structure = BoundStructure(unbounded=("dt",), path={})
    assert pickle.loads(pickle.dumps(structure)) == structure


def test_a_value_that_does_not_pickle_fails_only_its_task() -> None:
    """A task whose value cannot be sent back fails with the reason; the worker carries on."""
    tasks = [Task(key="bad", fn=_lambda_maker), Task(key="ok", fn=_total, args=({"x": 2},))]
    out = run_tasks(tasks, executor="process", workers=1, max_attempts=1)
    assert not out["bad"].ok and "pickle" in str(out["bad"].error).lower()
    assert out["ok"].ok and out["ok"].value == 2


def _lambda_maker():  # type: ignore[no-untyped-def]
    return lambda: None
