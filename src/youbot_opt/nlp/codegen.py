"""Compile small CasADi Functions to C with the system compiler, cached on disk.

:func:`compile_function` generates C for a Function, hashes it with the
compiler command and loads ``<cache>/<name>_<hash>.so`` (``$YOUBOT_OPT_CACHE``,
else ``$XDG_CACHE_HOME/youbot_opt/jit``), compiling a missing library now or
in the background (docs/design.md, "Time to first solve"), for this CPU
(:func:`compile_flags`). Without a C compiler the Function is returned
unchanged with a warning.

>>> fast = compile_function(fn, wait=True)  # doctest: +SKIP
"""

from __future__ import annotations

import functools
import hashlib
import logging
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import casadi as ca

from youbot_opt.exceptions import YoubotOptWarning

__all__ = [
    "COMPILE_FLAGS",
    "NATIVE_FLAG",
    "cache_dir",
    "compile_flags",
    "compile_function",
    "cpu_fingerprint",
    "estimated_compile_time",
    "find_compiler",
]

_log = logging.getLogger(__name__)

COMPILE_FLAGS: tuple[str, ...] = ("-O2", "-fPIC", "-shared")
"""Portable compiler flags (``-O2``: benchmarks/bench_first_solve.py measures compile and run
times); :func:`compile_flags` adds :data:`NATIVE_FLAG` where the compiler takes it."""

NATIVE_FLAG = "-march=native"
"""Compile for the CPU at hand (its vector units and fused multiply-add). The weighted-Hessian
kernel of panda runs 2.4x faster (4.49 -> 1.90 ms for 80 points), ur5's 1.4x, the youBot's
1.1x; gcc takes about a quarter longer. The library is then tied to this CPU model, so its
cache name includes :func:`cpu_fingerprint`. ``YOUBOT_OPT_NATIVE=0`` turns it off."""

SECONDS_PER_MEGABYTE = 13.0  # [s/MB] gcc -O2 on CasADi's generated C, measured on ur5's kernels
NATIVE_MULTIPLIER = 1.27  # gcc -O2 -march=native over -O2, ur5 kernels: 19.1 s against 15.0 s
STALE_LOCK = 1800.0  # [s] a background compile older than this is presumed dead

_BACKGROUND_SCRIPT = """
import os, shutil, subprocess, sys
compiler, source, target, library, lock, failed, tmp, *flags = sys.argv[1:]
try:
    with open(lock, "w") as out:
        out.write(str(os.getpid()))  # who holds the lock: a dead holder's lock is reclaimed
    if hasattr(os, "nice"):
        os.nice(19)  # leave the cores to the solve that is running meanwhile
    slot = open(os.path.join(os.path.dirname(library), ".compile-slot"), "w")
    try:
        import fcntl
        fcntl.flock(slot, fcntl.LOCK_EX)  # one background compile at a time per cache
    except ImportError:
        pass
    done = subprocess.run(
        [compiler, *flags, source, "-o", target, "-lm"], capture_output=True, text=True
    )
    if done.returncode == 0:
        os.replace(target, library)
    else:
        with open(failed, "w") as out:
            out.write(done.stderr[-2000:])
finally:
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        os.remove(lock)
    except OSError:
        pass
"""


def estimated_compile_time(code: str, flags: tuple[str, ...] = COMPILE_FLAGS) -> float:
    """Rough wall time in [s] to compile generated C ``code`` (-O2: 13 s per MB; native +27 %)."""
    native = NATIVE_MULTIPLIER if NATIVE_FLAG in flags else 1.0
    return SECONDS_PER_MEGABYTE * native * len(code) / 1e6


@functools.cache
def _accepts_native(compiler: str) -> bool:
    """Whether ``compiler`` accepts :data:`NATIVE_FLAG` (preprocesses an empty file with it)."""
    try:
        done = subprocess.run(  # noqa: S603 - the compiler found on PATH or in $CC
            [compiler, NATIVE_FLAG, "-x", "c", "-E", os.devnull],
            capture_output=True,
            timeout=60,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return False
    return done.returncode == 0


def compile_flags(compiler: str) -> tuple[str, ...]:
    """Return the flags :func:`compile_function` uses by default with ``compiler``.

    :data:`COMPILE_FLAGS` with :data:`NATIVE_FLAG` after ``-O2``, unless the
    environment variable ``YOUBOT_OPT_NATIVE`` is ``0`` or the compiler
    rejects the flag (checked once per compiler and process).

    Parameters
    ----------
    compiler : str
        The compiler command (:func:`find_compiler`).

    Returns
    -------
    tuple of str
        Compiler flags.
    """
    if os.environ.get("YOUBOT_OPT_NATIVE", "").strip() == "0" or not _accepts_native(compiler):
        return COMPILE_FLAGS
    return (COMPILE_FLAGS[0], NATIVE_FLAG, *COMPILE_FLAGS[1:])


@functools.cache
def cpu_fingerprint() -> str:
    """Describe the CPU that :data:`NATIVE_FLAG` compiles for: model and feature flags.

    From ``/proc/cpuinfo`` where there is one (the distinct ``model name`` and
    ``flags`` lines on x86, ``CPU implementer``/``CPU part``/``Features`` on
    ARM), else :func:`platform.machine` and :func:`platform.processor`. Part of
    a native library's cache name, so that a cache shared by different
    machines (a cluster's home folder) never loads code built for another CPU.
    """
    keys = {"model name", "flags", "Features", "CPU implementer", "CPU part"}
    try:
        text = Path("/proc/cpuinfo").read_text(errors="replace")
    except OSError:
        text = ""
    lines = {line.strip() for line in text.splitlines() if line.split(":")[0].strip() in keys}
    return "\n".join(sorted(lines)) or f"{platform.machine()} {platform.processor()}"


def cache_dir() -> Path:
    """Directory of compiled libraries (created on demand)."""
    env = os.environ.get("YOUBOT_OPT_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "youbot_opt" / "jit"


def find_compiler() -> str | None:
    """Path of the C compiler to use, or None if there is none."""
    candidates = [os.environ["CC"]] if os.environ.get("CC") else ["gcc", "cc", "clang"]
    for name in candidates:
        path = shutil.which(name)
        if path:
            return path
    return None


def compile_function(
    function: ca.Function,
    *,
    flags: tuple[str, ...] | None = None,
    wait: bool = True,
    label: str | None = None,
    with_jacobian: bool = False,
) -> ca.Function:
    """Compiled, disk-cached equivalent of ``function`` (or ``function`` itself).

    Parameters
    ----------
    function : casadi.Function
        A Function CasADi can generate C code for (SX or MX of SX, no Callbacks).
    flags : tuple of str, optional
        Compiler flags; :func:`compile_flags` of the compiler by default
        (portable flags plus ``-march=native`` where supported).
    wait : bool
        If the library is not cached: True compiles it now (can take minutes
        for a 7-dof robot's Hessian kernel); False starts the compiler in a
        detached, lower-priority process and returns ``function`` uncompiled,
        so the caller runs CasADi's virtual machine this time and loads the
        library from the cache next time.
    label : str, optional
        What the Function belongs to, for the log (e.g. ``"panda's dynamics"``).
    with_jacobian : bool
        Also compile ``function.jacobian()`` into the library (as
        ``jac_<name>``, where ``external`` finds it): the compiled Function then
        has first derivatives, so CasADi can differentiate expressions built on it.

    Returns
    -------
    casadi.Function
        An ``external`` Function with the same name, inputs and outputs when
        the library is (now) available, else ``function``. An external Function
        has no derivatives of its own unless ``with_jacobian`` (first order):
        compile the derivative Functions you need.

    Warns
    -----
    YoubotOptWarning
        If no compiler is found or compilation fails (now, or in an earlier
        background process); ``function`` is returned.
    """
    name = function.name()
    what = f"{label} ({name})" if label else name
    compiler = find_compiler()
    if compiler is None:
        warnings.warn(
            f"no C compiler found (set CC or install gcc): {what} runs in "
            "CasADi's virtual machine instead of compiled code (slower, same results)",
            YoubotOptWarning,
            stacklevel=2,
        )
        return function
    if flags is None:
        flags = compile_flags(compiler)
    gen = ca.CodeGenerator(name, {"with_header": False})
    gen.add(function)
    if with_jacobian:
        gen.add(function.jacobian())  # named jac_<name>: external() loads it as the Jacobian
    code = gen.dump()
    key = hashlib.sha256(
        "\0".join(
            [
                code,
                Path(compiler).name,
                *flags,
                str(getattr(ca, "__version__", "unknown")),
                *([cpu_fingerprint()] if NATIVE_FLAG in flags else []),
            ]
        ).encode()
    ).hexdigest()[:20]
    directory = cache_dir()
    library = directory / f"{name}_{key}.so"
    if library.is_file():
        return ca.external(name, str(library))
    failed = library.with_suffix(".failed")
    if failed.is_file():
        warnings.warn(
            f"compiling {what} failed earlier ({failed}: "
            f"{failed.read_text(errors='replace').strip()[:300]}); using CasADi's virtual "
            "machine instead (slower, same results); delete that file to retry",
            YoubotOptWarning,
            stacklevel=2,
        )
        return function
    seconds = estimated_compile_time(code, flags)
    if not wait:
        _compile_in_background(code, compiler, flags, directory, library, what, seconds)
        return function
    _log.info(
        "compiling %s to C (%.0f kB), about %.0f s, cached in %s for next time",
        what,
        len(code) / 1e3,
        seconds,
        directory,
    )
    try:
        _compile(code, compiler, flags, directory, library)
    except (OSError, subprocess.CalledProcessError) as exc:
        detail = getattr(exc, "stderr", "") or str(exc)
        warnings.warn(
            f"compiling {what} failed ({detail.strip()[:300]}); using CasADi's virtual "
            "machine instead (slower, same results)",
            YoubotOptWarning,
            stacklevel=2,
        )
        return function
    return ca.external(name, str(library))


def _compile_in_background(
    code: str,
    compiler: str,
    flags: tuple[str, ...],
    directory: Path,
    library: Path,
    what: str,
    seconds: float,
) -> None:
    """Start a detached compiler process for ``library`` unless one is already running."""
    directory.mkdir(parents=True, exist_ok=True)
    lock = library.with_suffix(".lock")
    try:
        alive = _holder_alive(lock)
        if alive or (alive is None and time.time() - lock.stat().st_mtime < STALE_LOCK):
            _log.info(
                "%s is being compiled by another process; this solve runs CasADi's virtual "
                "machine, a run started after that compile has finished the compiled code",
                what,
            )
            return
        lock.unlink()  # a dead process's lock
    except FileNotFoundError:
        pass
    queued = sum(1 for other in directory.glob("*.lock") if other != lock)
    try:
        os.close(os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:  # another process got there first
        return
    tmp = Path(tempfile.mkdtemp(dir=directory, prefix=".build-"))
    source = tmp / f"{library.stem}.c"
    source.write_text(code)
    args = [str(source), str(tmp / library.name), str(library), str(lock)]
    args += [str(library.with_suffix(".failed")), str(tmp)]
    subprocess.Popen(  # noqa: S603 - our own script and the compiler found on PATH
        [sys.executable, "-c", _BACKGROUND_SCRIPT, compiler, *args, *flags],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # survives the end of this process
    )
    _log.info(
        "compiling %s to C in the background (%.0f kB, about %.0f s%s); this solve runs "
        "CasADi's virtual machine; the compiler goes on after this command returns, and a run "
        "started after it has finished uses the compiled code (cached in %s)",
        what,
        len(code) / 1e3,
        seconds,
        f", after {queued} other compile(s) of this cache" if queued else "",
        directory,
    )


def _holder_alive(lock: Path) -> bool | None:
    """Whether the process named in ``lock`` is running; None if unknown (no PID, not POSIX).

    Raises
    ------
    FileNotFoundError
        If there is no lock.
    """
    text = lock.read_text(errors="replace").strip()
    if os.name != "posix" or not text.isdigit():  # os.kill(pid, 0) signals on Windows
        return None
    try:
        os.kill(int(text), 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    except (OSError, OverflowError):
        return None
    return True


def _compile(
    code: str, compiler: str, flags: tuple[str, ...], directory: Path, library: Path
) -> None:
    """Compile ``code`` into ``library`` atomically."""
    directory.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=directory, prefix=".build-") as tmp:
        source = Path(tmp) / f"{library.stem}.c"
        source.write_text(code)
        target = Path(tmp) / library.name
        subprocess.run(
            [compiler, *flags, str(source), "-o", str(target), "-lm"],
            check=True,
            capture_output=True,
            text=True,
        )
        os.replace(target, library)
