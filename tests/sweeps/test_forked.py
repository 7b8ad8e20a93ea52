"""ForkedCall: one call in a forked process, its value, errors, logs and warnings brought back."""

from __future__ import annotations

import logging
import os
import signal
import time
import warnings
from pathlib import Path

import pytest

from youbot_opt.sweeps import forked
from youbot_opt.sweeps.forked import ForkedCall, can_fork

pytestmark = pytest.mark.skipif(not can_fork(), reason="ForkedCall forks on Linux only")

_LOG = logging.getLogger("youbot_opt.tests.forked")


def _pid_and_sum(values: list[int], *, offset: int = 0) -> tuple[int, int]:
    return os.getpid(), sum(values) + offset


def _wait_for(path: Path, seconds: float = 60.0) -> None:
    """Wait until ``path`` exists (or fail): proves the child ran before ``result()``."""
    end = time.monotonic() + seconds
    while not path.exists():
        assert time.monotonic() < end, f"{path} was never written"
        time.sleep(0.01)


def _touch_then_return(path: Path, value: int) -> int:
    path.write_text("started")
    return value


def _fail(message: str) -> None:
    raise ValueError(message)


def _log_and_warn(n: int) -> int:
    _LOG.warning("integrated %d intervals", n)
    warnings.warn(f"{n} intervals were stiff", UserWarning, stacklevel=1)
    return n


def _sleep(seconds: float) -> None:
    time.sleep(seconds)


def _unpicklable() -> object:
    return lambda: None


def test_the_value_is_the_calls_and_computed_in_another_process() -> None:
    """Positional and keyword arguments reach the call; its value comes back unchanged."""
    with ForkedCall(_pid_and_sum, [1, 2, 3], offset=4) as call:
        pid, total = call.result()
    assert total == 10
    assert pid != os.getpid()


def test_the_child_runs_from_construction_while_the_caller_goes_on(tmp_path) -> None:
    """The child writes a file before ``result()`` is asked for: it ran meanwhile."""
    flag = tmp_path / "started"
    with ForkedCall(_touch_then_return, flag, 7) as call:
        _wait_for(flag)  # the caller's own work, here: waiting for the child's side effect
        assert call.result() == 7


def test_the_calls_error_is_raised_here_with_the_childs_traceback() -> None:
    """The child's exception, its class and message kept, its traceback a note."""
    call = ForkedCall(_fail, "the 3rd interval diverged")
    with pytest.raises(ValueError, match="the 3rd interval diverged") as info:
        call.result()
    notes = "\n".join(getattr(info.value, "__notes__", []))
    assert "in the forked process" in notes and "_fail" in notes


def test_log_records_and_warnings_of_the_child_are_issued_here(caplog) -> None:
    """A record logged in the child reaches this process's handlers, formatted; a warning too."""
    with caplog.at_level(logging.WARNING, logger="youbot_opt.tests.forked"):
        with pytest.warns(UserWarning, match="12 intervals were stiff"):
            assert ForkedCall(_log_and_warn, 12).result() == 12
    records = [r for r in caplog.records if r.name == "youbot_opt.tests.forked"]
    assert [r.getMessage() for r in records] == ["integrated 12 intervals"]
    assert records[0].levelno == logging.WARNING


def test_a_value_that_does_not_pickle_is_an_error_naming_it() -> None:
    """The value comes back through a pipe: a lambda cannot, and the error says what it was."""
    with pytest.raises(RuntimeError, match="value could not be sent back: .*lambda"):
        ForkedCall(_unpicklable).result()


def test_a_child_killed_before_it_reported_is_an_error() -> None:
    """A child that dies (killed from outside) makes ``result()`` raise, not hang."""
    call = ForkedCall(_sleep, 60.0)
    assert call._pid is not None  # noqa: SLF001 - the child to kill from outside
    os.kill(call._pid, signal.SIGKILL)  # noqa: SLF001
    with pytest.raises(RuntimeError, match="ended before it reported"):
        call.result()


def test_leaving_the_block_ends_an_uncollected_child() -> None:
    """An error here (or cancel) kills and reaps the child; its result is gone."""
    with pytest.raises(KeyError), ForkedCall(_sleep, 60.0) as call:
        pid = call._pid  # noqa: SLF001 - the child, to check it was reaped
        raise KeyError("the caller's own work failed")
    assert pid is not None
    with pytest.raises(ChildProcessError):
        os.waitpid(pid, os.WNOHANG)  # reaped already: no such child any more
    with pytest.raises(RuntimeError, match="already collected or cancelled"):
        call.result()


def test_the_result_is_collected_once() -> None:
    call = ForkedCall(_pid_and_sum, [1])
    call.result()
    with pytest.raises(RuntimeError, match="already collected"):
        call.result()


def test_without_fork_the_call_runs_on_result(monkeypatch) -> None:
    """Where ``fork`` is missing, the call is made by ``result()``, in this process."""
    monkeypatch.setattr(forked, "can_fork", lambda: False)
    call = ForkedCall(_pid_and_sum, [2, 3])
    assert call.result() == (os.getpid(), 5)
