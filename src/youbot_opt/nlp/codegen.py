"""Compile small CasADi Functions to C with the system compiler, cached on disk.

:func:`compile_functions` generates C for Functions, hashes it with the
compiler command and loads ``<cache>/<name>_<hash>.so`` (``$YOUBOT_OPT_CACHE``,
else ``$XDG_CACHE_HOME/youbot_opt/jit``), compiling the missing libraries in
one batch, now or in one background process (docs/design.md, "Time to first
solve"), for this CPU (:func:`compile_flags`); :func:`compile_function` does
it for one. Without a C compiler the Functions are returned unchanged with a
warning.

>>> fast = compile_function(fn, wait=True)  # doctest: +SKIP
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import casadi as ca

from youbot_opt._cores import usable_cores
from youbot_opt._files import atomic_write_text
from youbot_opt.exceptions import YoubotOptWarning

__all__ = [
    "COMPILE_FLAGS",
    "NATIVE_FLAG",
    "QUICK_FLAGS",
    "cache_dir",
    "compile_flags",
    "compile_function",
    "compile_functions",
    "cpu_fingerprint",
    "estimated_compile_time",
    "find_compiler",
    "load_indexed",
    "lock_path",
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

QUICK_FLAGS: tuple[str, ...] = ("-O0", "-fPIC", "-shared")
"""Flags of the quick build a cold run compiles now and runs while the optimised one compiles in
the background: gcc -O0 builds panda's kernels (3.35 MB of C) in 3.0 s of CPU (2.1 s on 2 cores)
against about 73 s at -O2 with -march=native, and they run 4.3-4.8x faster than CasADi's
virtual machine (4.5x slower than the optimised build; docs/design.md, "Time to first solve")."""

QUICK_SECONDS_PER_MEGABYTE = (
    1.0  # [s/MB] gcc -O0 on CasADi's generated C, panda's kernels: 0.9-0.95
)
QUICK_WAIT_SECONDS = 10.0
"""[s] The longest quick build (:data:`QUICK_FLAGS`, estimated) a cold run waits for; a larger
batch runs in CasADi's virtual machine until the optimised build is ready."""

SECONDS_PER_MEGABYTE = 13.0  # [s/MB] gcc -O2 on CasADi's generated C, measured on ur5's kernels
NATIVE_MULTIPLIER = 1.27  # gcc -O2 -march=native over -O2, ur5 kernels: 19.1 s against 15.0 s
STALE_LOCK = 1800.0  # [s] a background compile older than this is presumed dead
NO_PID_GRACE = 60.0  # [s] a lock still without its compiler's pid is orphaned
FAILED_RETRY = 86400.0
"""[s] A ``<library>.failed`` marker older than this is removed and the library compiled again.
The library's name already hashes its code, the compiler's name, the flags and CasADi's version,
so a marker only outlives what caused it when the compiler was upgraded under the same name, or
the failure was not the code's (a full disk, a killed compiler): retried daily, not every run."""
WAIT_SECONDS = 0.5
"""[s] ``wait=None``: compile now when the batch is estimated to take at most this long (a
two-link arm), else in the background while this run uses CasADi's virtual machine. Measured
(docs/design.md, "Time to first solve"): even the youBot's three kernels (about 1 s estimated,
3.5 s on a loaded 2-core machine) cost a cold ``youbot-opt solve`` more when compiled first than
the virtual machine does until the background compile is ready for the run's later rounds."""

_CLEANED: set[Path] = set()  # caches cleaned of orphans by this process
_LAUNCHED: set[int] = set()  # pids of the background compilers this process started
_LOCKED: set[str] = set()  # the locks this process created for them
_ANNOUNCED: set[frozenset[tuple[str, int | None]]] = set()  # compiles in progress already named

# Compiles a batch of generated C files, ``jobs`` at a time; one process per run. Standard
# library only (it runs detached from the package). In the background it writes its pid into
# the build folder and into each library's lock (who holds them: a dead holder's are cleaned
# up by the next run), lowers its priority (nice 19, and on Linux its session's autogroup's:
# nice acts only within a group), takes this user's compile slot (one batch at a time per user
# and cache), skips a library another process has produced meanwhile, releases each lock as
# soon as its library is in place, and records a failure in ``<library>.failed`` unless its
# build folder or source vanished meanwhile (removed under it: not a compiler error, so the
# next run retries). It prints ``{library: compiler error}`` for the compiles that failed.
_WORKER = r"""
import errno, json, os, shutil, subprocess, sys, time
spec = json.loads(sys.argv[1])
tmp, items, pid, errors = spec["tmp"], spec["items"], os.getpid(), {}
def release(item):
    try:
        with open(item["lock"]) as held:
            mine = held.read().split()[:1] == [str(pid)]
        if mine:
            os.remove(item["lock"])
    except (OSError, KeyError):
        pass
try:
    with open(os.path.join(tmp, "pid"), "w") as out:
        out.write(str(pid))
    if spec["background"]:
        for item in items:
            with open(item["lock"], "w") as out:
                out.write("%d\n%.1f\n" % (pid, item["seconds"]))
        if hasattr(os, "nice"):
            os.nice(19)  # leave the cores to the solve that is running meanwhile
        for attempt in range(3):  # Linux: nice acts within a session's autogroup; lower ours
            try:
                with open("/proc/self/autogroup", "w") as group:
                    group.write("19")
                break
            except OSError as exc:  # none (not Linux, autogroups off) or busy: EAGAIN, retried
                if exc.errno != errno.EAGAIN:
                    break
                time.sleep(0.15)
        slot = open(spec["slot"], "a")
        try:
            import fcntl
            fcntl.flock(slot, fcntl.LOCK_EX)  # one batch at a time per user and cache
        except ImportError:
            pass
    queue, running = list(items), []
    while queue or running:
        while queue and len(running) < spec["jobs"]:
            item = queue.pop(0)
            if os.path.exists(item["library"]):  # another process produced it meanwhile
                release(item)
                continue
            if not os.path.isfile(item["source"]):  # the build folder was removed: no marker
                errors[item["library"]] = "build folder %s removed before the compile" % tmp
                release(item)
                continue
            log = open(item["target"] + ".log", "w+", errors="replace")  # read back through it
            command = [spec["compiler"], *spec["flags"], item["source"], "-o", item["target"]]
            command.append("-lm")
            proc = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=log, stderr=log)
            running.append((item, proc, log))
        time.sleep(0.02)
        for entry in list(running):
            item, proc, log = entry
            if proc.poll() is None:
                continue
            running.remove(entry)
            if proc.returncode == 0:
                try:
                    os.replace(item["target"], item["library"])
                except OSError:
                    if os.path.isdir(tmp) and not os.path.exists(item["library"]):
                        raise
                    if not os.path.exists(item["library"]):
                        errors[item["library"]] = "build folder %s removed before " % tmp
                        errors[item["library"]] += "its library was moved into the cache"
            else:
                log.seek(0)
                text = log.read()[-2000:] or "exit %d" % proc.returncode
                if os.path.isdir(tmp) and os.path.isfile(item["source"]):
                    errors[item["library"]] = text
                    if spec["background"]:
                        with open(item["failed"], "w") as out:
                            out.write(text)
                else:  # the build folder was removed under the compiler: retried next run
                    errors[item["library"]] = "build folder %s removed during the compile; " % tmp
                    errors[item["library"]] += "not recorded as failed: " + text
            log.close()
            release(item)
finally:
    for item in items:
        release(item)
    shutil.rmtree(tmp, ignore_errors=True)
print(json.dumps(errors))
"""


def estimated_compile_time(code: str, flags: tuple[str, ...] = COMPILE_FLAGS) -> float:
    """Rough wall time in [s] to compile generated C ``code`` (-O2: 13 s per MB; native +27 %).

    With ``-O0`` (:data:`QUICK_FLAGS`): 1 s per MB.
    """
    if "-O0" in flags:
        return QUICK_SECONDS_PER_MEGABYTE * len(code) / 1e6
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
    wait: bool | None = True,
    label: str | None = None,
    with_jacobian: bool = False,
) -> ca.Function:
    """Compiled, disk-cached equivalent of ``function`` (or ``function`` itself).

    One Function of :func:`compile_functions`.

    Parameters
    ----------
    function : casadi.Function
        A Function CasADi can generate C code for (SX or MX of SX, no Callbacks).
    flags : tuple of str, optional
        Compiler flags; :func:`compile_flags` of the compiler by default
        (portable flags plus ``-march=native`` where supported).
    wait : bool or None
        If the library is not cached: True compiles it now (can take minutes
        for a 7-dof robot's Hessian kernel); False starts the compiler in a
        detached, lower-priority process and returns ``function`` uncompiled,
        so the caller runs CasADi's virtual machine this time and loads the
        library from the cache next time; None: now if that is estimated to
        take at most :data:`WAIT_SECONDS`, else in the background, with a quick
        build (:data:`QUICK_FLAGS`, compiled now when short) meanwhile.
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
    return compile_functions(
        [function], flags=flags, wait=wait, label=label, with_jacobian=[with_jacobian]
    )[0]


class _Job(NamedTuple):
    """One Function's library: its C code, where it goes, the estimated compile time."""

    function: ca.Function
    code: str
    library: Path
    seconds: float
    portable: Path | None  # the portable library of the same code (native flags only)
    quick: Path | None  # the quick build of the same code (QUICK_FLAGS; None when those are used)


def compile_functions(
    functions: Sequence[ca.Function],
    *,
    flags: tuple[str, ...] | None = None,
    wait: bool | None = True,
    label: str | None = None,
    with_jacobian: Sequence[bool] | None = None,
    index: str | None = None,
) -> list[ca.Function]:
    """Compiled, disk-cached equivalents of ``functions``, missing ones compiled in one batch.

    Each library is ``<cache>/<name>_<hash>.so`` (:func:`cache_dir`; the hash
    covers the code, the compiler, its flags, CasADi's version and, with
    :data:`NATIVE_FLAG`, :func:`cpu_fingerprint`) and is loaded when it is
    there. The missing ones are compiled by one process, as many at a time as
    there are cores (``YOUBOT_OPT_COMPILE_JOBS`` to change that): now, or in
    the background (``wait``); one log line says which, how long, where, and
    when the compiled code will be used. Where a native library is missing but
    the portable one of the same code is cached, that one is used meanwhile, else
    its quick build (:data:`QUICK_FLAGS`) when cached; a batch that goes to the
    background automatically (``wait=None``) with neither gets its quick build
    compiled now first, when that is estimated to take at most
    :data:`QUICK_WAIT_SECONDS` (panda's kernels: about 2 s).
    Lock files and the compile slot are per user, so one user's compiles never
    queue behind another's in a shared cache; locks and build folders left by
    a dead compiler (killed, or a reboot) are removed by the next call.

    Parameters
    ----------
    functions : sequence of casadi.Function
        Functions CasADi can generate C code for.
    flags, label
        As :func:`compile_function`.
    wait : bool or None
        As :func:`compile_function`; None decides for the whole batch (its
        estimated wall time against :data:`WAIT_SECONDS`; never waits when a
        portable library or a quick build can be used meanwhile).
    with_jacobian : sequence of bool, optional
        Per Function, as :func:`compile_function`'s ``with_jacobian``.
    index : str, optional
        What the caller derived ``functions`` from, deterministically (e.g. the
        serialised Function they differentiate and the deriving code): an index
        file maps it to the batch's libraries (written when they are loaded from
        this cache, or when their background compile starts: read only once
        every library exists), and :func:`load_indexed` then loads them without
        the Functions (whose building and code generation cost more than the
        load; a warm ur5 run's first build 0.35 s more without it).

    Returns
    -------
    list of casadi.Function
        Per Function, the compiled one when its library is available (the
        portable one or the quick build meanwhile, see above), else the Function
        itself.

    Warns
    -----
    YoubotOptWarning
        As :func:`compile_function`.
    """
    functions = list(functions)
    jacobians = list(with_jacobian) if with_jacobian is not None else [False] * len(functions)
    names = ", ".join(f.name() for f in functions)
    what = f"{label} ({names})" if label else names
    compiler = find_compiler()
    if compiler is None:
        warnings.warn(
            f"no C compiler found (set CC or install gcc): {what} runs in "
            "CasADi's virtual machine instead of compiled code (slower, same results)",
            YoubotOptWarning,
            stacklevel=2,
        )
        return functions
    if flags is None:
        flags = compile_flags(compiler)
    directory = cache_dir()
    if directory not in _CLEANED and directory.is_dir():
        _CLEANED.add(directory)  # once per process and cache
        _clean_orphans(directory)
    result = list(functions)
    kinds: list[str | None] = [None] * len(functions)  # what runs meanwhile (_MEANWHILE)
    missing: list[tuple[int, _Job]] = []
    jobs_of: list[_Job] = []
    for i, (function, jacobian) in enumerate(zip(functions, jacobians, strict=True)):
        job = _job(function, jacobian, compiler, flags, directory)
        jobs_of.append(job)
        if job.library.is_file():
            result[i] = ca.external(function.name(), str(job.library))
            continue
        failed = job.library.with_suffix(".failed")
        if failed.is_file() and _expired(failed):
            _log.info(
                "retrying %s, failed more than %.0f h ago", job.library.name, FAILED_RETRY / 3600
            )
            failed.unlink(missing_ok=True)
        if failed.is_file():
            warnings.warn(
                f"compiling {label + ' ' if label else ''}({function.name()}) failed earlier "
                f"({failed}: {failed.read_text(errors='replace').strip()[:300]}); using "
                "CasADi's virtual machine instead (slower, same results); delete that file "
                f"to retry now (retried after {FAILED_RETRY / 3600:.0f} h)",
                YoubotOptWarning,
                stacklevel=2,
            )
            continue
        for kind, path in (("portable", job.portable), ("quick", job.quick)):  # faster first
            if path is not None and path.is_file():
                result[i], kinds[i] = ca.external(function.name(), str(path)), kind
                break
        missing.append((i, job))
    if not missing:
        if index is not None:
            _write_index(directory, index, compiler, flags, functions, jobs_of)
        return result
    directory.mkdir(parents=True, exist_ok=True)
    jobs = [job for _, job in missing]
    batch = _batch_name(label, jobs)
    meanwhile = any(result[i] is not job.function for i, job in missing)
    automatic = wait is None
    if wait is None:
        wait = not meanwhile and _wall_estimate(jobs) <= WAIT_SECONDS
    if not wait:
        if automatic:  # the quick build now, when short; the optimised one starts after it
            _quick_build(missing, result, kinds, compiler, directory)
        meanwhile_text = _meanwhile_text([kinds[i] for i, _ in missing])
        _compile_in_background(jobs, compiler, flags, directory, batch, meanwhile_text)
        if index is not None:  # read once every library exists: the first later run is fast
            _write_index(directory, index, compiler, flags, functions, jobs_of)
        return result
    _log.info(
        "compiling %s to C now (%.0f kB, about %.0f s, %d at a time), cached in %s for later runs",
        batch,
        sum(len(job.code) for job in jobs) / 1e3,
        _wall_estimate(jobs),
        _jobs(len(jobs)),
        directory,
    )
    errors = _run_worker(jobs, compiler, flags, directory)
    if index is not None and all(job.library.is_file() for job in jobs_of):
        _write_index(directory, index, compiler, flags, functions, jobs_of)
    for i, job in missing:
        if job.library.is_file():
            result[i] = ca.external(job.function.name(), str(job.library))
            continue
        detail = errors.get(str(job.library), "no library produced")
        warnings.warn(
            f"compiling {label + ' ' if label else ''}({job.function.name()}) failed "
            f"({detail.strip()[:300]}); using CasADi's virtual machine instead (slower, same "
            "results)",
            YoubotOptWarning,
            stacklevel=2,
        )
    return result


def _cache_key(text: str, compiler: str, flags: tuple[str, ...]) -> str:
    """Hash ``text`` with the compiler, its flags, CasADi's version and (native) the CPU."""
    return hashlib.sha256(
        "\0".join(
            [
                text,
                Path(compiler).name,
                *flags,
                str(getattr(ca, "__version__", "unknown")),
                *([cpu_fingerprint()] if NATIVE_FLAG in flags else []),
            ]
        ).encode()
    ).hexdigest()[:20]


def _index_path(directory: Path, index: str, compiler: str, flags: tuple[str, ...]) -> Path:
    """``<cache>/index_<hash>.json``: the hash covers what a library name's hash does but code."""
    return directory / f"index_{_cache_key(index, compiler, flags)}.json"


def _write_index(
    directory: Path,
    index: str,
    compiler: str,
    flags: tuple[str, ...],
    functions: Sequence[ca.Function],
    jobs: Sequence[_Job],
) -> None:
    """Record which libraries hold the batch derived from ``index`` (best effort)."""
    doc = [[f.name(), job.library.name] for f, job in zip(functions, jobs, strict=True)]
    path = _index_path(directory, index, compiler, flags)
    try:
        if json.loads(path.read_text(encoding="utf-8")) == doc:
            return
    except (OSError, ValueError):  # missing or malformed: written below
        pass
    try:
        atomic_write_text(path, json.dumps(doc))
    except OSError as exc:  # a read-only cache costs time only
        _log.debug("cannot write the kernel index %s: %s", path, exc)


def load_indexed(index: str) -> list[ca.Function] | None:
    """Return the compiled Functions a batch derived from ``index`` was, or None.

    None unless a C compiler is found, :func:`compile_functions` recorded the
    batch with this ``index`` for this compiler, its flags, CasADi's version
    (and, with :data:`NATIVE_FLAG`, this CPU), and every library it names is
    in the cache; a malformed index file reads as missing. Each Function
    comes with its compiled Jacobian when its library has one.
    """
    compiler = find_compiler()
    if compiler is None:
        return None
    directory = cache_dir()
    path = _index_path(directory, index, compiler, compile_flags(compiler))
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        entries = [(str(name), directory / str(lib)) for name, lib in doc]
    except (OSError, ValueError, TypeError):
        return None
    if not entries or not all(lib.is_file() and lib.parent == directory for _, lib in entries):
        return None
    try:
        return [ca.external(name, str(lib)) for name, lib in entries]
    except RuntimeError as exc:  # a library that does not load: build the Functions again
        _log.debug("cannot load the kernels of index %s: %s", path, exc)
        return None


def _expired(failed: Path) -> bool:
    """Whether the ``.failed`` marker is older than :data:`FAILED_RETRY`."""
    try:
        return time.time() - failed.stat().st_mtime > FAILED_RETRY
    except FileNotFoundError:
        return False


def _job(
    function: ca.Function, jacobian: bool, compiler: str, flags: tuple[str, ...], directory: Path
) -> _Job:
    """Generate ``function``'s C code and name its library (and its portable twin)."""
    name = function.name()
    gen = ca.CodeGenerator(name, {"with_header": False})
    gen.add(function)
    if jacobian:
        gen.add(function.jacobian())  # named jac_<name>: external() loads it as the Jacobian

    code = gen.dump()

    def library(options: tuple[str, ...]) -> Path:
        return directory / f"{name}_{_cache_key(code, compiler, options)}.so"

    portable = None
    if NATIVE_FLAG in flags:
        portable = library(tuple(flag for flag in flags if flag != NATIVE_FLAG))
    quick = None if flags == QUICK_FLAGS else library(QUICK_FLAGS)
    seconds = estimated_compile_time(code, flags)
    return _Job(function, code, library(flags), seconds, portable, quick)


_MEANWHILE = {
    "portable": "the portable compiled code of this cache",
    "quick": "the quick build (-O0) of this cache",
    "quick now": "code compiled just now without optimisation (-O0: about 4x faster than "
    "CasADi's virtual machine)",
}


def _meanwhile_text(kinds: Sequence[str | None]) -> str:
    """Say what a run uses while its libraries compile: ``kinds`` per missing one (None: the VM)."""
    used = [_MEANWHILE[kind] for kind in dict.fromkeys(kinds) if kind is not None]
    if not used:
        return "CasADi's virtual machine"
    vm = " and CasADi's virtual machine" if None in kinds else ""
    return " and ".join(used) + vm + " meanwhile"


def _quick_build(
    missing: Sequence[tuple[int, _Job]],
    result: list[ca.Function],
    kinds: list[str | None],
    compiler: str,
    directory: Path,
) -> None:
    """Compile now, with :data:`QUICK_FLAGS`, the missing libraries that would run in the VM.

    Only when the batch is estimated to take at most :data:`QUICK_WAIT_SECONDS`;
    each one built replaces its Function in ``result`` (``kinds``: ``"quick now"``).
    A failed quick build leaves the VM (the optimised build reports its own errors).
    """
    todo = [(i, job, job.quick) for i, job in missing if kinds[i] is None and job.quick]
    builds = [
        job._replace(
            library=quick,
            seconds=estimated_compile_time(job.code, QUICK_FLAGS),
            portable=None,
            quick=None,
        )
        for _, job, quick in todo
    ]
    if not builds or _wall_estimate(builds) > QUICK_WAIT_SECONDS:
        return
    # every core: this run waits for them, and the optimised build starts after
    errors = _run_worker(builds, compiler, QUICK_FLAGS, directory, parallel=usable_cores())
    for (i, job, _), build in zip(todo, builds, strict=True):
        if build.library.is_file():
            result[i], kinds[i] = ca.external(job.function.name(), str(build.library)), "quick now"
        else:
            _log.debug(
                "quick build of %s failed: %s",
                job.function.name(),
                errors.get(str(build.library), "no library produced")[:300],
            )


def _batch_name(label: str | None, jobs: Sequence[_Job]) -> str:
    """``"ur5's dynamics (fd_value, fd_hessian)"``: what the log line names."""
    names = ", ".join(job.function.name() for job in jobs)
    return f"{label} ({names})" if label else names


def _jobs(count: int) -> int:
    """Return how many compilers run at once (at most ``count``): the idle cores.

    ``YOUBOT_OPT_COMPILE_JOBS`` if set, else the cores less the load average
    (rounded), at least 1: on 2 cores with a load average of 12 the xArm7's
    kernels were ready after 347 s one at a time and 367 s two at a time.
    """
    env = os.environ.get("YOUBOT_OPT_COMPILE_JOBS", "").strip()
    if env.isdigit() and int(env) > 0:
        return max(1, min(count, int(env)))
    cores = usable_cores()
    try:
        idle = cores - round(os.getloadavg()[0])
    except (AttributeError, OSError):  # no load average (Windows)
        idle = cores
    return max(1, min(count, idle))


def _wall_estimate(jobs: Sequence[_Job]) -> float:
    """Estimated wall time [s] of the batch: the longest first, each to the least busy core."""
    busy = [0.0] * _jobs(len(jobs))
    for seconds in sorted((job.seconds for job in jobs), reverse=True):
        busy[busy.index(min(busy))] += seconds
    return max(busy, default=0.0)


def _user_tag() -> str:
    """``u<uid>``: names this user's lock and slot files in a cache other users may share."""
    if hasattr(os, "getuid"):
        return f"u{os.getuid()}"
    name = os.environ.get("USERNAME") or os.environ.get("USER") or ""
    return "u" + "".join(c if c.isalnum() else "_" for c in name)


def lock_path(library: Path) -> Path:
    """Return this user's lock of a background compile of ``library`` (``<stem>.u<uid>.lock``)."""
    return library.with_name(f"{library.stem}.{_user_tag()}.lock")


def _pid_alive(pid: int) -> bool | None:
    """Whether process ``pid`` runs as this user; None if unknown (not POSIX).

    A pid that belongs to another user's process (``PermissionError``) is not
    this user's compiler: the number was reused after that compiler ended.
    """
    if os.name != "posix":  # os.kill(pid, 0) signals on Windows
        return None
    try:
        os.kill(pid, 0)
    except (ProcessLookupError, PermissionError):
        return False
    except (OSError, OverflowError):
        return None
    return True


def _holder(lock: Path) -> tuple[int | None, float, float | None] | None:
    """Return the live holder of this user's ``lock``: (pid, age [s], estimate [s]) or None.

    A lock whose compiler has ended (or whose pid is another user's process),
    one still without a pid after :data:`NO_PID_GRACE`, and one older than
    :data:`STALE_LOCK` without a known holder are removed: free.
    """
    try:
        fields = lock.read_text(errors="replace").split()
        age = time.time() - lock.stat().st_mtime
    except FileNotFoundError:
        return None
    pid = int(fields[0]) if fields and fields[0].isdigit() else None
    try:
        estimate: float | None = float(fields[1]) if len(fields) > 1 else None
    except ValueError:
        estimate = None
    alive = _pid_alive(pid) if pid is not None else None
    grace = NO_PID_GRACE if pid is None and os.name == "posix" else STALE_LOCK
    if alive is False or (alive is None and age > grace):
        try:
            lock.unlink()
        except FileNotFoundError:
            pass
        return None
    return pid, age, estimate


def _clean_orphans(directory: Path) -> None:
    """Remove this user's locks and ``.build-*`` folders whose compiler is dead."""
    uid = os.getuid() if hasattr(os, "getuid") else None
    now = time.time()
    for lock in directory.glob("*.lock"):
        try:
            if uid is not None and lock.stat().st_uid != uid:
                continue  # another user's: not for this user to judge
        except FileNotFoundError:
            continue
        _holder(lock)
    for build in directory.glob(".build-*"):
        try:
            stat = build.stat()
        except OSError:
            continue
        if uid is not None and stat.st_uid != uid:
            continue
        if _build_dead(build, now - stat.st_mtime):
            _log.debug("removing %s, left by a compile that ended", build)
            shutil.rmtree(build, ignore_errors=True)


def _read_pid(path: Path) -> int | None:
    """Return the process id written in ``path``, or None (no file, empty, not a number)."""
    try:
        text = path.read_text(errors="replace").strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def _runs_worker_of(pid: int, build: Path) -> bool | None:
    """Whether process ``pid`` is the worker compiling in ``build``; None if unknown.

    The worker's command line holds its spec, which names the build folder; a
    live process whose command line does not (Linux ``/proc``) is another
    program that got the number after the worker ended. An empty command line
    (seen right after ``Popen`` returns, before the exec shows) says nothing.
    """
    try:
        command = Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace")
    except OSError:
        return None
    if not command:  # still being started (between fork and exec), or a zombie
        return None
    return str(build) in command or json.dumps(str(build))[1:-1] in command


def _build_dead(build: Path, age: float) -> bool:
    """Whether the compile of build folder ``build`` (its last change ``age`` [s] ago) has ended.

    A folder whose worker (``pid``) runs is never removed, however long its
    compile takes or waits for this user's compile slot (a removal under a
    running compiler is what once recorded spurious ``.failed`` markers); a
    worker pid that now names another program (pid reuse) or no process means
    ended; a live one whose command line is empty (between fork and exec, the
    moment the caller has written its pid; or a zombie) counts as running for
    up to :data:`STALE_LOCK`. Before the worker's pid is in, the process that made the folder
    (``owner``) vouches for it (a foreground compile's caller, or a background
    one's until it has written the worker's pid) for up to :data:`STALE_LOCK`;
    a folder with neither (an older version's, or written between ``mkdtemp``
    and the owner file) ends after :data:`STALE_LOCK` too: an orphaned folder
    costs disk space only, a removed live one a compile.
    """
    worker = _read_pid(build / "pid")
    if worker is not None:
        alive = _pid_alive(worker)
        if alive is None:  # not POSIX: no way to tell
            return age > STALE_LOCK
        if not alive:
            return True
        runs = _runs_worker_of(worker, build)
        return runs is False or (runs is None and age > STALE_LOCK)
    owner = _read_pid(build / "owner")
    if owner is not None and _pid_alive(owner) is False:
        return True
    return age > STALE_LOCK


def _prepare(
    jobs: Sequence[_Job],
    compiler: str,
    flags: tuple[str, ...],
    directory: Path,
    *,
    background: bool,
    parallel: int | None = None,
) -> tuple[Path, str]:
    """Write the sources into a new build folder; return it and the worker's spec (JSON).

    ``parallel``: compilers at a time (default :func:`_jobs`, the idle cores).
    """
    tmp = Path(tempfile.mkdtemp(dir=directory, prefix=f".build-{_user_tag()}-"))
    (tmp / "owner").write_text(str(os.getpid()))  # vouches for the folder until the worker's pid
    items = []
    for job in sorted(jobs, key=lambda job: -job.seconds):  # the longest first (the Hessian)
        source = tmp / f"{job.library.stem}.c"
        source.write_text(job.code)
        items.append(
            {
                "source": str(source),
                "target": str(tmp / job.library.name),
                "library": str(job.library),
                "lock": str(lock_path(job.library)),
                "failed": str(job.library.with_suffix(".failed")),
                "seconds": job.seconds,
            }
        )
    spec = {
        "compiler": compiler,
        "flags": list(flags),
        "jobs": _jobs(len(jobs)) if parallel is None else max(1, min(parallel, len(jobs))),
        "tmp": str(tmp),
        "slot": str(directory / f".compile-slot-{_user_tag()}"),
        "background": background,
        "items": items,
    }
    return tmp, json.dumps(spec)


def _write_pid(tmp: Path, pid: int) -> None:
    """Write the worker's ``pid`` into its build folder (it does too, as it starts).

    Written by the caller as well, so that no run's orphan cleaning sees the
    folder without a live pid while the worker's interpreter is still starting
    (seconds on a loaded machine) after a background compile's caller has ended.
    """
    try:
        (tmp / "pid").write_text(str(pid))
    except OSError:  # the worker has finished and removed the folder already
        pass


def _run_worker(
    jobs: Sequence[_Job],
    compiler: str,
    flags: tuple[str, ...],
    directory: Path,
    parallel: int | None = None,
) -> dict[str, str]:
    """Compile ``jobs`` now (``parallel`` as :func:`_prepare`); return ``{library: error}``."""
    tmp, spec = _prepare(jobs, compiler, flags, directory, background=False, parallel=parallel)
    try:
        with subprocess.Popen(  # noqa: S603 - our own script and the compiler found on PATH
            [sys.executable, "-c", _WORKER, spec],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        ) as proc:
            _write_pid(tmp, proc.pid)
            stdout, stderr = proc.communicate()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    try:
        errors = json.loads(stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        errors = {str(job.library): stderr[-2000:] for job in jobs}
    return {str(k): str(v) for k, v in errors.items()}


def _compile_in_background(
    jobs: Sequence[_Job],
    compiler: str,
    flags: tuple[str, ...],
    directory: Path,
    batch: str,
    meanwhile_text: str,
) -> None:
    """Start one detached compiler process for the libraries nobody is compiling; log one line.

    ``meanwhile_text`` says what the run uses until they are ready (:func:`_meanwhile_text`).
    """
    mine: list[_Job] = []
    others: dict[str, tuple[int | None, float, float | None]] = {}
    starting: set[str] = set()
    for job in jobs:
        lock = lock_path(job.library)
        holder = _holder(lock)
        if holder is None:
            try:
                os.close(os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
            except FileExistsError:  # another process got there first
                holder = _holder(lock) or (None, 0.0, job.seconds)
        if holder is None:
            mine.append(job)
        else:
            others[job.function.name()] = holder
            if holder[0] is None and str(lock) in _LOCKED:  # our worker, its pid not written yet
                starting.add(job.function.name())
    ours = {str(lock_path(job.library)) for job in mine}
    queued = sum(
        1 for lock in directory.glob(f"*.{_user_tag()}.lock") if str(lock) not in ours
    ) - len(others)
    pid: int | None = None
    if mine:
        tmp, spec = _prepare(mine, compiler, flags, directory, background=True)
        try:
            proc = subprocess.Popen(  # noqa: S603 - our own script and the compiler found on PATH
                [sys.executable, "-c", _WORKER, spec],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                start_new_session=True,  # survives the end of this process
            )
        except OSError as exc:
            shutil.rmtree(tmp, ignore_errors=True)
            for job in mine:
                lock_path(job.library).unlink(missing_ok=True)
            _log.warning("could not start the compiler for %s (%s)", batch, exc)
            return
        pid = proc.pid
        _write_pid(tmp, pid)
        _LAUNCHED.add(pid)
        _LOCKED.update(str(lock_path(job.library)) for job in mine)
    text = []
    if mine:
        label = batch.split(" (")[0] if " (" in batch else ""
        text.append(
            f"compiling {_batch_name(label or None, mine)} to C in the background "
            f"({sum(len(job.code) for job in mine) / 1e3:.0f} kB, about "
            f"{_wall_estimate(mine):.0f} s, {_jobs(len(mine))} at a time"
            f"{f', after {queued} other compile(s) of this cache' if queued > 0 else ''}; "
            f"cached in {directory}); this solve runs {meanwhile_text}; the compiler goes on "
            "after this command returns, and a run started after it has finished uses the "
            "compiled code (so do this run's later builds)"
        )
    if others:
        running = max(age for _, age, _ in others.values())
        left = max(
            (max(0.0, (est if est is not None else 0.0) - age) for _, age, est in others.values()),
            default=0.0,
        )
        names = ", ".join(others)
        if mine:
            text.append(
                f"{names} already being compiled by another process (running {running:.0f} s, "
                f"about {left:.0f} s left)"
            )
        else:
            text.append(
                f"{batch} is being compiled by another process (running {running:.0f} s, "
                f"about {left:.0f} s left; cached in {directory}); this solve runs "
                f"{meanwhile_text}, a run started after that compile has finished uses the "
                "compiled code"
            )
    holders = {(name, holder[0]) for name, holder in others.items()}
    key = frozenset(holders | {(job.function.name(), pid) for job in mine})
    own = not mine and all(
        holder[0] in _LAUNCHED or name in starting for name, holder in others.items()
    )
    level = logging.DEBUG if own or key in _ANNOUNCED else logging.INFO
    _ANNOUNCED.add(key)
    _log.log(level, "; ".join(text))
