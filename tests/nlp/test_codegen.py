"""C code generation: background compiles never block, land in the cache, and fail loudly once."""

from __future__ import annotations

import logging
import shutil
import time
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from youbot_opt.exceptions import YoubotOptWarning
from youbot_opt.nlp.codegen import compile_function, find_compiler

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="no C compiler")


def _function(tag: float) -> ca.Function:
    """A tiny Function; ``tag`` changes its code, hence its cache entry."""
    x = ca.SX.sym("x", 2)
    return ca.Function("tiny", [x], [ca.sin(x) * x + tag], ["x"], ["y"])


def _wait_unlocked(cache: Path, timeout: float = 120.0) -> None:
    tic = time.perf_counter()
    while any(cache.glob("*.lock")):
        assert time.perf_counter() - tic < timeout, "background compile did not finish"
        time.sleep(0.1)


def test_background_compile_returns_now_and_caches(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """wait=False returns the Function itself at once; the library appears and is used next."""
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    f = _function(0.5)
    with caplog.at_level(logging.INFO, logger="youbot_opt.nlp.codegen"):
        first = compile_function(f, wait=False, label="tiny's dynamics")
    assert first is f
    assert "tiny's dynamics (tiny) to C in the background" in caplog.text
    _wait_unlocked(tmp_path)
    assert len(list(tmp_path.glob("tiny_*.so"))) == 1
    second = compile_function(f, wait=False)
    assert second is not f
    x = np.array([0.3, -1.7])
    # same IEEE operations in C and in CasADi's VM: equal to rounding (1e-15 on O(1) values)
    np.testing.assert_allclose(np.asarray(second(x)), np.asarray(f(x)), rtol=0, atol=1e-15)


def test_fresh_lock_means_no_second_compile(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A lock held by another process (fresh) starts no second compiler."""
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    f = _function(1.5)
    assert compile_function(f, wait=False) is f
    locks = list(tmp_path.glob("*.lock"))
    assert len(locks) == 1
    _wait_unlocked(tmp_path)
    library = next(tmp_path.glob("tiny_*.so"))
    library.unlink()
    locks[0].touch()  # as if another process were compiling it now
    assert compile_function(f, wait=False) is f
    time.sleep(0.5)
    assert not list(tmp_path.glob("tiny_*.so")) and not list(tmp_path.glob(".build-*"))


def test_failed_background_compile_warns_next_time(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A compiler that fails leaves a .failed file; the next build warns and runs the VM."""
    false = shutil.which("false")
    if false is None:
        pytest.skip("no 'false' executable")
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    monkeypatch.setenv("CC", false)
    f = _function(2.5)
    assert compile_function(f, wait=False) is f
    _wait_unlocked(tmp_path)
    assert len(list(tmp_path.glob("*.failed"))) == 1
    with pytest.warns(YoubotOptWarning, match="failed earlier"):
        assert compile_function(f, wait=False) is f
