"""benchmarks/bench_wait.py: a stale compile lock is reported, not waited for (issue 27)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import time
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_wait.py"


def _bench():
    spec = importlib.util.spec_from_file_location("bench_wait", BENCH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_stale_locks_are_named_and_live_ones_are_not(tmp_path):
    """A dead compiler's lock, a lock without pid past the grace, one older than any compile."""
    from youbot_opt.nlp.codegen import STALE_LOCK

    bench = _bench()
    now = time.time()
    dead = tmp_path / "dead.lock"
    dead.write_text(str(_dead_pid()))
    assert "not running" in bench.lock_is_stale(dead)
    alive = tmp_path / "alive.lock"
    alive.write_text(str(os.getpid()))
    assert bench.lock_is_stale(alive) is None
    os.utime(alive, (now - STALE_LOCK - 10, now - STALE_LOCK - 10))
    assert "longer than any compile" in bench.lock_is_stale(alive)
    empty = tmp_path / "empty.lock"
    empty.write_text("")
    assert bench.lock_is_stale(empty) is None  # the compiler writes its pid as it starts
    os.utime(empty, (now - bench.NO_PID_GRACE - 10, now - bench.NO_PID_GRACE - 10))
    assert "no compiler pid" in bench.lock_is_stale(empty)
    assert bench.lock_is_stale(tmp_path / "gone.lock") is None
    with_estimate = tmp_path / "estimate.lock"
    with_estimate.write_text(f"{os.getpid()}\n42.0\n")  # the compiler's pid, then its estimate
    assert bench.lock_is_stale(with_estimate) is None
    with_estimate.write_text(f"{_dead_pid()}\n42.0\n")
    assert "not running" in bench.lock_is_stale(with_estimate)


def test_a_lock_naming_another_users_process_is_stale(tmp_path, monkeypatch):
    """Locks are per user: a pid that is another user's process is not this user's compiler."""
    bench = _bench()
    lock = tmp_path / "kernel.u0.lock"
    lock.write_text("4242\n10.0\n")

    def kill(pid, sig):
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(bench.os, "kill", kill)
    assert "another user's process" in bench.lock_is_stale(lock)


def test_wait_returns_at_once_on_a_stale_lock(tmp_path, capsys):
    """The wait for background compiles does not sit out its timeout on a dead compiler's lock."""
    bench = _bench()
    (tmp_path / "jit").mkdir()
    (tmp_path / "jit" / "kernel.lock").write_text(str(_dead_pid()))
    assert bench._wait_for_background(tmp_path, timeout=30.0) < 5.0
    assert "stale compile lock" in capsys.readouterr().out
    live = tmp_path / "jit" / "live.lock"
    live.write_text(str(os.getpid()))
    assert bench._wait_for_background(tmp_path, timeout=1.0) >= 1.0  # a live one is waited for
    assert "still running" in capsys.readouterr().out
