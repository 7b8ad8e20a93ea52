"""C code generation: background compiles never block, land in the cache, and fail loudly once."""

from __future__ import annotations

import logging
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from youbot_opt.exceptions import YoubotOptWarning
from youbot_opt.nlp.codegen import (
    COMPILE_FLAGS,
    NATIVE_FLAG,
    compile_flags,
    compile_function,
    find_compiler,
    lock_path,
)

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


@pytest.mark.skipif(os.name != "posix", reason="the lock's holder is checked on POSIX")
def test_lock_of_a_dead_compile_is_reclaimed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """A lock naming a process that has ended (a killed compile) is taken over at once.

    A lock naming a live process still starts no second compiler; the log says
    when the compiled code will be used.
    """
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    f = _function(3.5)
    assert compile_function(f, wait=False) is f
    _wait_unlocked(tmp_path)
    library = next(tmp_path.glob("tiny_*.so"))
    library.unlink()
    lock = lock_path(library)
    lock.write_text(str(os.getpid()))  # alive: this process
    with caplog.at_level(logging.INFO, logger="youbot_opt.nlp.codegen"):
        assert compile_function(f, wait=False) is f
    assert "being compiled by another process" in caplog.text
    assert "a run started after that compile has finished" in caplog.text
    time.sleep(0.5)
    assert not list(tmp_path.glob("tiny_*.so"))
    dead = subprocess.Popen([sys.executable, "-c", "pass"])  # noqa: S603
    dead.wait()
    lock.write_text(str(dead.pid))  # a compile killed long before STALE_LOCK
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="youbot_opt.nlp.codegen"):
        assert compile_function(f, wait=False) is f
    assert "goes on after this command returns" in caplog.text
    _wait_unlocked(tmp_path)
    assert library.is_file()


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


def test_native_flag_is_used_where_the_compiler_takes_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """-march=native after -O2 by default; off with YOUBOT_OPT_NATIVE=0 or a refusing compiler."""
    compiler = find_compiler()
    assert compiler is not None
    monkeypatch.delenv("YOUBOT_OPT_NATIVE", raising=False)
    gcc_like = Path(compiler).name in {"gcc", "cc", "clang"}
    if gcc_like:  # gcc and clang on x86-64 and arm64 Linux take it
        assert compile_flags(compiler) == ("-O2", NATIVE_FLAG, "-fPIC", "-shared")
    monkeypatch.setenv("YOUBOT_OPT_NATIVE", "0")
    assert compile_flags(compiler) == COMPILE_FLAGS
    monkeypatch.delenv("YOUBOT_OPT_NATIVE")
    false = shutil.which("false")
    if false is not None:  # exits 1 for any arguments: the flag counts as refused
        assert compile_flags(false) == COMPILE_FLAGS


def test_a_native_library_is_cached_per_cpu(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Another CPU model gets its own library; portable flags do not depend on the CPU."""
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    f = _function(3.5)
    native = ("-O2", NATIVE_FLAG, "-fPIC", "-shared")
    for cpu in ("cpu A", "cpu B"):
        monkeypatch.setattr("youbot_opt.nlp.codegen.cpu_fingerprint", lambda cpu=cpu: cpu)
        assert compile_function(f, wait=True, flags=native) is not f
        assert compile_function(f, wait=True, flags=COMPILE_FLAGS) is not f
    assert len(list(tmp_path.glob("tiny_*.so"))) == 3  # two native, one portable


def test_native_and_portable_kernels_agree(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The youBot's weighted-Hessian kernel, compiled both ways, at random points.

    Same expression graph, only the instructions differ (vector units, fused
    multiply-add, which rounds once where the portable code rounds twice):
    the results agree to a few ulps times the graph's depth, far inside 1e-9
    relative of the Hessian's largest entry.
    """
    from youbot_opt.dynamics import build_dynamics
    from youbot_opt.robot.load import load_model
    from youbot_opt.trajopt.transcription.derivatives import dynamics_kernels

    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    robot = load_model("youbot")
    kernel = dynamics_kernels(build_dynamics(robot, "symbolic", damping=True).forward_dynamics)
    native = compile_function(kernel.hessian, flags=("-O2", NATIVE_FLAG, "-fPIC", "-shared"))
    portable = compile_function(kernel.hessian, flags=COMPILE_FLAGS)
    assert native is not kernel.hessian and portable is not kernel.hessian
    rng = np.random.default_rng(20261125)
    for _ in range(20):
        q, v, tau, w = (rng.uniform(-2.0, 2.0, robot.nv) for _ in range(4))
        a, b = np.asarray(native(q, v, tau, w)), np.asarray(portable(q, v, tau, w))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * np.abs(b).max())
