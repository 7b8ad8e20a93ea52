"""C code generation: background compiles never block, land in the cache, and fail loudly once."""

from __future__ import annotations

import json
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


def _assert_loaded_as(found: list[ca.Function] | None, originals: tuple[ca.Function, ...]) -> None:
    """The indexed Functions evaluate as the originals (same IEEE operations: to 1e-15)."""
    assert found is not None and len(found) == len(originals)
    x = np.array([0.3, -1.7])
    for loaded, original in zip(found, originals, strict=True):
        np.testing.assert_allclose(
            np.asarray(loaded(x)), np.asarray(original(x)), rtol=0, atol=1e-15
        )


def test_a_background_compile_is_indexed_for_the_next_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The index is written as the background compile starts and found once it has ended.

    The first run after the compile then loads the libraries without deriving
    the Functions again (before, only a run that found them wrote the index, so
    that run paid the derivation: 0.35 s on ur5). The index names exactly the
    libraries the compile made.
    """
    from youbot_opt.nlp.codegen import compile_functions, load_indexed

    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    f, g = _function(2.25), _function(2.75)
    compiled = compile_functions([f, g], wait=False, index="indexed ahead")
    assert compiled[0] is f and compiled[1] is g  # this run: CasADi's virtual machine
    assert len(list(tmp_path.glob("index_*.json"))) == 1
    _wait_unlocked(tmp_path)
    (index_file,) = tmp_path.glob("index_*.json")
    named = sorted(lib for _, lib in json.loads(index_file.read_text(encoding="utf-8")))
    assert named == sorted(p.name for p in tmp_path.glob("tiny_*.so"))  # what was compiled
    _assert_loaded_as(load_indexed("indexed ahead"), (f, g))


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


def _slow_compiler(tmp_path: Path, seconds: float, marker: Path | None = None) -> str:
    """A compiler wrapper that sleeps ``seconds`` (and touches ``marker``) before gcc."""
    real = find_compiler()
    assert real is not None
    script = tmp_path / "slow" / Path(real).name  # same name: same cache keys
    script.parent.mkdir(exist_ok=True)
    touch = f'touch "{marker}"\n' if marker is not None else ""
    script.write_text(f'#!/bin/sh\n{touch}sleep {seconds}\nexec "{real}" "$@"\n')
    script.chmod(0o755)
    return str(script)


def _fresh_process_state(monkeypatch: pytest.MonkeyPatch) -> None:
    """As in a new run: no cache cleaned, nothing launched or announced yet."""
    from youbot_opt.nlp import codegen

    monkeypatch.setattr(codegen, "_CLEANED", set())
    monkeypatch.setattr(codegen, "_LAUNCHED", set())
    monkeypatch.setattr(codegen, "_LOCKED", set())
    monkeypatch.setattr(codegen, "_ANNOUNCED", set())


@pytest.mark.skipif(os.name != "posix", reason="a shell script stands for the compiler")
@pytest.mark.parametrize("removed", ["source", "folder"])
def test_a_build_folder_removed_under_the_compiler_is_no_failure(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, removed: str
) -> None:
    """Build files removed while the compiler runs: no .failed marker; the next run compiles.

    (Seen in a shared cache: a cleanup removed a compile's folder, the compiler
    failed on its vanished files and the failure was recorded for good, so
    every later run of that arm ran in CasADi's virtual machine.)
    """
    cache = tmp_path / "cache"
    real = find_compiler()
    assert real is not None
    script = tmp_path / "vanish" / Path(real).name  # same name: same cache keys
    script.parent.mkdir()
    target = '"$a"' if removed == "source" else '"$(dirname "$a")"'
    script.write_text(  # removes the source it is given (or its folder), fails as gcc would
        f'#!/bin/sh\nfor a in "$@"; do case "$a" in *.c) rm -rf {target};; esac; done\n'
        'echo "cc1: fatal error: no such file or directory" >&2\nexit 1\n'
    )
    script.chmod(0o755)
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(cache))
    monkeypatch.setenv("CC", str(script))
    flags = compile_flags(real)
    _fresh_process_state(monkeypatch)
    f = _function(6.5)
    assert compile_function(f, wait=False, flags=flags) is f
    _wait_unlocked(cache)
    assert not list(cache.glob("*.failed"))
    assert not list(cache.glob("tiny_*.so"))
    _fresh_process_state(monkeypatch)  # the next run, with a compiler that works
    monkeypatch.setenv("CC", real)
    assert compile_function(f, wait=False, flags=flags) is f
    _wait_unlocked(cache)
    assert len(list(cache.glob("tiny_*.so"))) == 1
    assert compile_function(f, wait=False, flags=flags) is not f


@pytest.mark.skipif(os.name != "posix", reason="process groups and pids are POSIX")
def test_a_killed_compile_leaves_nothing_behind(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Worker and compiler SIGKILLed (or a reboot): the next run removes the lock and build dir."""
    import signal

    cache = tmp_path / "cache"
    real = find_compiler()
    assert real is not None
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(cache))
    monkeypatch.setenv("CC", _slow_compiler(tmp_path, 30))
    flags = compile_flags(real)  # not the wrapper's: it sleeps for that check too
    _fresh_process_state(monkeypatch)
    f = _function(4.5)
    assert compile_function(f, wait=False, flags=flags) is f
    (lock,) = cache.glob("*.lock")
    tic = time.perf_counter()
    while not lock.read_text().strip():  # the worker writes its pid as it starts
        assert time.perf_counter() - tic < 30
        time.sleep(0.05)
    pid = int(lock.read_text().split()[0])
    assert len(list(cache.glob(".build-*"))) == 1
    os.killpg(pid, signal.SIGKILL)  # the worker's session: it and the compiler it started
    os.waitpid(pid, 0)  # reaped (a run's compiler is reaped by init once the run has ended)
    assert lock.exists() and list(cache.glob(".build-*"))  # what a killed compile leaves
    _fresh_process_state(monkeypatch)  # the next run
    monkeypatch.setenv("CC", real)
    assert compile_function(_function(5.5), wait=True) is not None  # any call on this cache
    assert not lock.exists()
    assert not list(cache.glob(".build-*"))


def test_another_users_lock_does_not_block(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """Another user's compile of the same kernel (live) does not hold this user's back.

    Its lock carries its uid in the name, so this user's run starts its own
    compile; and this user's lock naming a pid that now belongs to another
    user (``os.kill`` raises PermissionError: the compiler ended, its pid was
    reused) is taken over at once.
    """
    from youbot_opt.nlp import codegen

    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    _fresh_process_state(monkeypatch)
    f = _function(6.5)
    assert compile_function(f, wait=True) is not f
    library = next(tmp_path.glob("tiny_*.so"))
    library.unlink()
    other = library.with_name(f"{library.stem}.u{os.getuid() + 1}.lock")
    other.write_text(f"{os.getpid()}\n30.0\n")  # another user's live compile
    with caplog.at_level(logging.INFO, logger="youbot_opt.nlp.codegen"):
        assert compile_function(f, wait=False) is f
    assert "to C in the background" in caplog.text
    _wait_unlocked_mine(tmp_path)
    assert library.is_file() and other.is_file()  # not this user's to remove
    library.unlink()
    mine = lock_path(library)
    mine.write_text(f"{os.getpid()}\n30.0\n")
    real_kill = os.kill

    def kill(pid: int, sig: int) -> None:
        if pid == os.getpid() and sig == 0:
            raise PermissionError(1, "Operation not permitted")
        real_kill(pid, sig)

    monkeypatch.setattr(codegen.os, "kill", kill)
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="youbot_opt.nlp.codegen"):
        assert compile_function(f, wait=False) is f
    assert "to C in the background" in caplog.text
    assert "another process" not in caplog.text
    monkeypatch.setattr(codegen.os, "kill", real_kill)
    _wait_unlocked_mine(tmp_path)
    assert library.is_file()


def _wait_worker_done(cache: Path, timeout: float = 120.0) -> None:
    """Wait for the build folders to go: the worker releases a library's lock when the
    library is done and removes its build folder last, as it ends."""
    tic = time.perf_counter()
    while any(cache.glob(".build-*")):
        assert time.perf_counter() - tic < timeout, "background compile did not end"
        time.sleep(0.1)


def _wait_unlocked_mine(cache: Path, timeout: float = 120.0) -> None:
    tic = time.perf_counter()
    while any(cache.glob(f"*.u{os.getuid()}.lock")):
        assert time.perf_counter() - tic < timeout, "background compile did not finish"
        time.sleep(0.1)


_RUN = """
import logging, sys, casadi as ca
from youbot_opt.nlp import codegen
from youbot_opt.trajopt.transcription.derivatives import Kernels, compile_kernels
logging.basicConfig(stream=sys.stderr, level=logging.WARNING, format="youbot-opt: %(message)s")
logging.getLogger("youbot_opt.nlp.codegen").setLevel(logging.INFO)
x = ca.SX.sym("x", 2)
tag = float(sys.argv[1])
codegen.WAIT_SECONDS = 0.0  # as for a robot whose kernels take long to compile
codegen.QUICK_WAIT_SECONDS = 0.0  # and too long for a quick build: the virtual machine
kernels = Kernels(*(ca.Function(n, [x], [ca.sin(x) * x + tag + i]) for i, n in
                    enumerate(("fd_value", "fd_jacobian", "fd_hessian"))))
for _ in range(3):  # three refinement rounds, three solver builds
    compiled = compile_kernels(kernels, wait=None, label="tiny's dynamics")
print(compiled is kernels)
"""


@pytest.mark.skipif(os.name != "posix", reason="a shell-script compiler")
def test_one_line_per_run_and_the_next_run_is_told_how_long(tmp_path: Path) -> None:
    """A run that starts compiles says so in one stderr line, whatever it builds.

    Three kernels in one background process; a run started while they compile
    says how long they have been running and about how long is left; a run
    after they finish uses them and says nothing.
    """
    cache = tmp_path / "cache"
    env = {
        **os.environ,
        "YOUBOT_OPT_CACHE": str(cache),
        "CC": _slow_compiler(tmp_path, 3),
        "YOUBOT_OPT_NATIVE": "0",  # no flag check (the wrapper sleeps for it too)
        "PYTHONPATH": os.pathsep.join(sys.path),
    }

    def run() -> tuple[str, list[str]]:
        done = subprocess.run(  # noqa: S603
            [sys.executable, "-c", _RUN, "7.5"], env=env, capture_output=True, text=True
        )
        assert done.returncode == 0, done.stderr
        return done.stdout.strip(), [line for line in done.stderr.splitlines() if line]

    out, lines = run()
    assert out == "True"  # the virtual machine this time
    assert len(lines) == 1, lines
    assert "compiling tiny's dynamics (fd_value, fd_jacobian, fd_hessian) to C in the " in lines[0]
    assert f"cached in {cache}" in lines[0]
    assert "a run started after it has finished uses the compiled code" in lines[0]
    time.sleep(1.0)
    out, lines = run()
    assert out == "True"
    assert len(lines) == 1, lines
    assert "being compiled by another process (running " in lines[0]
    assert " s left" in lines[0]
    _wait_unlocked_mine(cache)
    out, lines = run()
    assert out == "False" and lines == []  # compiled code, nothing to say
    assert len(list(cache.glob("fd_*.so"))) == 3


def test_a_short_compile_is_done_now(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """wait=None: compiled now when estimated within WAIT_SECONDS, else in the background."""
    from youbot_opt.nlp import codegen

    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    _fresh_process_state(monkeypatch)
    f, g = _function(8.5), _function(9.5)
    with caplog.at_level(logging.INFO, logger="youbot_opt.nlp.codegen"):
        assert compile_function(f, wait=None) is not f
    assert "to C now" in caplog.text
    monkeypatch.setattr(codegen, "WAIT_SECONDS", 0.0)
    monkeypatch.setattr(codegen, "QUICK_WAIT_SECONDS", 0.0)  # no quick build: the VM
    assert compile_function(g, wait=None) is g
    _wait_unlocked_mine(tmp_path)
    assert compile_function(g, wait=None) is not g


def _runs_meanwhile(
    f: ca.Function, flags: tuple[str, ...], caplog: pytest.LogCaptureFixture, says: str
) -> None:
    """``wait=None`` on a missing library returns other compiled code meanwhile, saying which.

    Its values are ``f``'s to 1e-15 (the same operations, compiled otherwise).
    """
    with caplog.at_level(logging.INFO, logger="youbot_opt.nlp.codegen"):
        meanwhile = compile_function(f, wait=None, flags=flags)
    assert meanwhile is not f
    assert f"this solve runs {says}" in caplog.text
    x = np.array([0.3, -1.7])
    np.testing.assert_allclose(np.asarray(meanwhile(x)), np.asarray(f(x)), rtol=0, atol=1e-15)


def test_a_batch_sent_to_the_background_runs_its_quick_build_meanwhile(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """wait=None, too long to wait for: the quick build (-O0) is compiled now and runs meanwhile.

    It gives the virtual machine's values (1e-15: the same operations, unoptimised),
    the log line says what runs, and once the optimised library has arrived the next
    call loads that one (it still works with the quick library deleted). A cached
    quick build is used by a later call without compiling again; ``wait=False`` and a
    quick build estimated over QUICK_WAIT_SECONDS leave the virtual machine.
    """
    from youbot_opt.nlp import codegen

    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    _fresh_process_state(monkeypatch)
    monkeypatch.setattr(codegen, "WAIT_SECONDS", 0.0)
    f = _function(11.5)
    _runs_meanwhile(f, COMPILE_FLAGS, caplog, "code compiled just now without optimisation (-O0")
    _wait_unlocked_mine(tmp_path)
    libraries = sorted(tmp_path.glob("tiny_*.so"))
    assert len(libraries) == 2  # the quick build and the optimised one
    quick = [
        lib
        for lib in libraries
        if lib.name
        == codegen._job(  # noqa: SLF001
            f, False, find_compiler() or "", codegen.QUICK_FLAGS, tmp_path
        ).library.name
    ]
    assert len(quick) == 1
    quick[0].unlink()
    assert compile_function(f, wait=None, flags=COMPILE_FLAGS) is not f  # the optimised one

    g = _function(12.5)
    assert compile_function(g, wait=True, flags=codegen.QUICK_FLAGS) is not g
    monkeypatch.setattr(codegen, "QUICK_WAIT_SECONDS", 0.0)  # cannot build one now
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="youbot_opt.nlp.codegen"):
        assert compile_function(g, wait=None, flags=COMPILE_FLAGS) is not g
    assert "this solve runs the quick build (-O0) of this cache meanwhile" in caplog.text
    _wait_unlocked_mine(tmp_path)

    h = _function(13.5)
    assert compile_function(h, wait=None, flags=COMPILE_FLAGS) is h  # estimated too long
    monkeypatch.setattr(codegen, "QUICK_WAIT_SECONDS", 10.0)
    k = _function(14.5)
    assert compile_function(k, wait=False, flags=COMPILE_FLAGS) is k  # asked not to wait
    _wait_unlocked_mine(tmp_path)


def test_the_portable_library_is_used_while_the_native_one_compiles(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """The native library missing, the portable one cached: it runs meanwhile (not the VM)."""
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    _fresh_process_state(monkeypatch)
    f = _function(10.5)
    native = ("-O2", NATIVE_FLAG, "-fPIC", "-shared")
    portable = compile_function(f, wait=True, flags=COMPILE_FLAGS)
    assert portable is not f
    _runs_meanwhile(f, native, caplog, "the portable compiled code of this cache meanwhile")
    _wait_unlocked_mine(tmp_path)
    assert len(list(tmp_path.glob("tiny_*.so"))) == 2  # the native one arrived


@pytest.mark.skipif(os.name != "posix", reason="flock and a shell-script compiler")
def test_a_queued_compile_of_a_library_made_meanwhile_exits_without_compiling(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Queued behind this user's slot, a compile whose library appeared meanwhile is skipped."""
    import fcntl

    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    _fresh_process_state(monkeypatch)
    f = _function(11.5)
    assert compile_function(f, wait=True) is not f
    library = next(tmp_path.glob("tiny_*.so"))
    built = tmp_path / "built.so"
    library.rename(built)
    marker = tmp_path / "compiler-ran"
    flags = compile_flags(find_compiler() or "gcc")
    monkeypatch.setenv("CC", _slow_compiler(tmp_path, 0, marker))
    slot = open(tmp_path / f".compile-slot-u{os.getuid()}", "a")  # noqa: SIM115
    fcntl.flock(slot, fcntl.LOCK_EX)  # another batch of this user is compiling
    try:
        assert compile_function(f, wait=False, flags=flags) is f
        time.sleep(0.5)
    finally:
        built.rename(library)  # produced meanwhile by another process
        fcntl.flock(slot, fcntl.LOCK_UN)
        slot.close()
    _wait_unlocked_mine(tmp_path)
    _wait_worker_done(tmp_path)  # the folder is removed after the lock (its end)
    assert not marker.exists()


def test_compilers_run_side_by_side_only_on_idle_cores(monkeypatch: pytest.MonkeyPatch) -> None:
    """One compiler per idle core (at least one); YOUBOT_OPT_COMPILE_JOBS overrides."""
    from youbot_opt.nlp import codegen

    monkeypatch.delenv("YOUBOT_OPT_COMPILE_JOBS", raising=False)
    monkeypatch.setattr(codegen.os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    monkeypatch.setattr(codegen.os, "getloadavg", lambda: (0.2, 0.2, 0.2))
    assert codegen._jobs(3) == 2 and codegen._jobs(1) == 1
    monkeypatch.setattr(codegen.os, "getloadavg", lambda: (12.0, 12.0, 12.0))
    assert codegen._jobs(3) == 1  # measured: no faster side by side on a loaded machine
    monkeypatch.setenv("YOUBOT_OPT_COMPILE_JOBS", "3")
    assert codegen._jobs(3) == 3 and codegen._jobs(2) == 2


def _wait_for_worker(cache: Path, timeout: float = 30.0) -> Path:
    """The build folder of the background compile just started, once its worker has its pid."""
    tic = time.perf_counter()
    while True:
        builds = [b for b in cache.glob(".build-*") if (b / "pid").is_file()]
        locks = list(cache.glob("*.lock"))
        if builds and locks and all(lock.read_text().strip() for lock in locks):
            return builds[0]
        assert time.perf_counter() - tic < timeout, "the worker did not start"
        time.sleep(0.05)


@pytest.mark.skipif(os.name != "posix", reason="a shell-script compiler")
def test_a_build_folder_removed_under_the_compiler_records_no_failure(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Its files vanishing is not a compiler error: no .failed marker, the next run compiles."""
    cache = tmp_path / "cache"
    real = find_compiler()
    assert real is not None
    flags = compile_flags(real)
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(cache))
    monkeypatch.setenv("CC", _slow_compiler(tmp_path, 2))
    _fresh_process_state(monkeypatch)
    f = _function(12.5)
    assert compile_function(f, wait=False, flags=flags) is f
    build = _wait_for_worker(cache)
    shutil.rmtree(build)  # what an orphan cleaning once did to a live compile
    _wait_unlocked(cache)
    assert not list(cache.glob("*.failed"))
    assert not list(cache.glob("tiny_*.so"))
    _fresh_process_state(monkeypatch)  # the next run retries
    monkeypatch.setenv("CC", real)
    assert compile_function(f, wait=True, flags=flags) is not f
    assert len(list(cache.glob("tiny_*.so"))) == 1


def test_a_genuine_compiler_error_is_still_recorded(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The real compiler rejecting its command line leaves a .failed marker with its message."""
    real = find_compiler()
    assert real is not None
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    _fresh_process_state(monkeypatch)
    f = _function(13.5)
    flags = (*COMPILE_FLAGS, "-fno-such-option-youbot-opt")
    assert compile_function(f, wait=False, flags=flags) is f
    _wait_unlocked(tmp_path)
    _wait_worker_done(tmp_path)  # the folder is removed after the lock (its end)
    (failed,) = tmp_path.glob("*.failed")
    assert "no-such-option-youbot-opt" in failed.read_text()
    with pytest.warns(YoubotOptWarning, match="failed earlier"):
        assert compile_function(f, wait=False, flags=flags) is f


@pytest.mark.skipif(os.name != "posix", reason="pids and a shell-script compiler")
def test_orphan_cleaning_spares_a_live_compile_however_old(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A build folder older than STALE_LOCK whose worker runs is kept; its library lands.

    A folder naming a live process that is not its worker (pid reuse), or a
    dead owner and no worker, is removed; one whose owner lives is kept.
    """
    from youbot_opt.nlp import codegen

    cache = tmp_path / "cache"
    real = find_compiler()
    assert real is not None
    flags = compile_flags(real)
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(cache))
    monkeypatch.setenv("CC", _slow_compiler(tmp_path, 3))
    _fresh_process_state(monkeypatch)
    f = _function(14.5)
    assert compile_function(f, wait=False, flags=flags) is f
    build = _wait_for_worker(cache)
    old = time.time() - codegen.STALE_LOCK - 10
    os.utime(build, (old, old))  # a compile queued or running for longer than STALE_LOCK
    reused = cache / ".build-reused"
    reused.mkdir()
    (reused / "pid").write_text(str(os.getpid()))  # alive, but not a worker of this folder
    dead_owner = cache / ".build-dead-owner"
    dead_owner.mkdir()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])  # noqa: S603
    dead.wait()
    (dead_owner / "owner").write_text(str(dead.pid))
    live_owner = cache / ".build-live-owner"
    live_owner.mkdir()
    (live_owner / "owner").write_text(str(os.getpid()))
    past_grace = time.time() - codegen.NO_PID_GRACE - 10
    os.utime(live_owner, (past_grace, past_grace))
    _fresh_process_state(monkeypatch)  # the next run cleans the cache
    codegen._clean_orphans(cache)
    assert build.is_dir() and live_owner.is_dir()
    if Path("/proc/self/cmdline").is_file():
        assert not reused.exists()
    assert not dead_owner.exists()
    _wait_unlocked(cache)
    assert not list(cache.glob("*.failed"))
    assert len(list(cache.glob("tiny_*.so"))) == 1


def test_an_old_failed_marker_is_retried(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A .failed marker older than FAILED_RETRY is removed and the library compiled again."""
    from youbot_opt.nlp import codegen

    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    _fresh_process_state(monkeypatch)
    f = _function(15.5)
    assert compile_function(f, wait=True) is not f
    (library,) = tmp_path.glob("tiny_*.so")
    library.unlink()
    failed = library.with_suffix(".failed")
    failed.write_text("cc1: a failure of long ago")
    with pytest.warns(YoubotOptWarning, match="failed earlier"):
        assert compile_function(f, wait=True) is f  # a recent marker holds
    old = time.time() - codegen.FAILED_RETRY - 10
    os.utime(failed, (old, old))
    assert compile_function(f, wait=True) is not f
    assert library.is_file() and not failed.exists()


def test_an_indexed_batch_loads_without_its_functions(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``index=`` records the batch once its libraries are there; ``load_indexed`` finds them.

    The loaded Functions evaluate as the originals (and the first, compiled with
    its Jacobian, differentiates); another index, a library removed, a malformed
    index file or other flags (no ``-march=native``) find nothing.
    """
    from youbot_opt.nlp.codegen import compile_functions, load_indexed

    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    f, g = _function(0.25), _function(0.75)
    assert load_indexed("two tiny ones") is None
    compiled = compile_functions(
        [f, g], wait=True, with_jacobian=[True, False], index="two tiny ones"
    )
    assert all(c is not o for c, o in zip(compiled, (f, g), strict=True))
    found = load_indexed("two tiny ones")
    _assert_loaded_as(found, (f, g))
    assert found is not None
    x = np.array([0.3, -1.7])
    xs = ca.MX.sym("x", 2)
    jac = ca.Function("j", [xs], [ca.jacobian(found[0](xs), xs)])
    np.testing.assert_allclose(np.diag(np.asarray(jac(x))), np.sin(x) + x * np.cos(x), atol=1e-12)
    assert load_indexed("another batch") is None
    compiler = find_compiler()
    assert compiler is not None
    native = NATIVE_FLAG in compile_flags(compiler)
    monkeypatch.setenv("YOUBOT_OPT_NATIVE", "0")
    if native:  # the index names the flags: the portable build was never recorded
        assert load_indexed("two tiny ones") is None
    monkeypatch.delenv("YOUBOT_OPT_NATIVE")
    (index_file,) = tmp_path.glob("index_*.json")
    index_file.write_text("{not json", encoding="utf-8")
    assert load_indexed("two tiny ones") is None
    compile_functions([f, g], wait=True, with_jacobian=[True, False], index="two tiny ones")
    assert load_indexed("two tiny ones") is not None  # the libraries were there: rewritten
    first_library = json.loads(index_file.read_text(encoding="utf-8"))[0][1]
    (tmp_path / first_library).unlink()
    assert load_indexed("two tiny ones") is None


@pytest.mark.skipif(not hasattr(os, "getpriority"), reason="POSIX priorities")
def test_the_background_compiler_yields_in_its_own_session_and_autogroup(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The background worker runs in a session of its own at nice 19, and (Linux with
    autogroups) so does its session's group: nice acts only inside a group, so without
    it the compiler took a full share of the cores from the run that started it."""
    cache = tmp_path / "cache"
    real = find_compiler()
    assert real is not None
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(cache))
    monkeypatch.setenv("CC", _slow_compiler(tmp_path, 3))
    _fresh_process_state(monkeypatch)
    f = _function(15.5)
    assert compile_function(f, wait=False, flags=compile_flags(real)) is f
    pid = int((_wait_for_worker(cache) / "pid").read_text())
    group = Path(f"/proc/{pid}/autogroup")
    tic = time.perf_counter()
    while True:  # the worker lowers its priority just after writing its pid
        nice = os.getpriority(os.PRIO_PROCESS, pid)
        grouped = not group.is_file() or group.read_text().split()[-1] == "19"
        if nice == 19 and grouped:
            break
        assert time.perf_counter() - tic < 2.5, (nice, group.read_text() if group.is_file() else "")
        time.sleep(0.02)
    assert os.getsid(pid) != os.getsid(0)
    _wait_unlocked(cache)
