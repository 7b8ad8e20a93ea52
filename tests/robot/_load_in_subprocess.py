"""Load URDF files with the strict loader, each in its own capped child process.

Run as ``python tests/robot/_load_in_subprocess.py < jobs.json``, or with
``--stream`` to read one job per line and answer each at once (the fuzz tests
keep one helper running). ``jobs.json`` is a
JSON list of jobs ``{"id": str, "path": str, "package_dirs": [str, ...]}``,
optionally with ``"timeout"`` in [s] and ``"memory"`` in [bytes] overriding the
defaults (20 s, 2 GiB), or with ``"selftest": "allocate" | "sleep"`` instead of
a path, to prove that the caps are enforced.

This process imports the loader once (without running ``youbot_opt/__init__``,
so the children stay light) and then forks one child per job: each file is
loaded in a fresh process, with ``RLIMIT_AS`` (memory) and ``RLIMIT_CPU`` set in
the child and a wall-clock time-out enforced here (SIGKILL). One JSON line per
job is printed on stdout: ``{"id", "outcome", "error_class", "message",
"seconds", "nq"}`` with ``outcome`` in ``ok``, ``error``, ``timeout``,
``killed`` (signal, e.g. the CPU limit), ``crashed`` (no report). An error
report also carries the error's ``path``, ``element``, ``line`` and ``rule``
attributes (``error_path`` ...; None for errors without them) and the class
of its ``__cause__`` (``cause_class``). A loaded model's report carries
``finite_dynamics``: RNEA, CRBA and ABA finite at the neutral configuration
and at three seeded random states (computed here, apart from the loader).
"""

from __future__ import annotations

import importlib.util
import json
import os
import resource
import select
import signal
import sys
import time
import types

DEFAULT_TIMEOUT = 20.0  # [s] wall clock per file
DEFAULT_MEMORY = 2 * 2**30  # [bytes] address space per child


def _import_loader() -> types.ModuleType:
    """Import youbot_opt.robot.urdf_check.loader without running the package's __init__."""
    spec = importlib.util.find_spec("youbot_opt")
    assert spec is not None and spec.submodule_search_locations is not None
    package = types.ModuleType("youbot_opt")
    package.__path__ = list(spec.submodule_search_locations)
    package.__spec__ = spec
    sys.modules["youbot_opt"] = package
    import youbot_opt.robot.urdf_check.loader as loader

    return loader


def _run_job(loader: types.ModuleType, job: dict) -> dict:
    if job.get("selftest") == "allocate":
        block = bytearray(2**33)  # 8 GiB at once: must hit RLIMIT_AS
        return {"outcome": "ok", "nq": len(block)}
    if job.get("selftest") == "sleep":
        time.sleep(3600)
    try:
        loaded = loader.load_urdf_strict(job["path"], job["package_dirs"])
    except Exception as e:  # report every error class, the test decides
        report = {"outcome": "error", "error_class": type(e).__name__, "message": str(e)}
        for attr in ("path", "element", "line", "rule"):  # URDFError's site, if any
            report[f"error_{attr}"] = getattr(e, attr, None)
        cause = e.__cause__
        report["cause_class"] = type(cause).__name__ if cause is not None else None
        return report
    return {"outcome": "ok", "nq": loaded.model.nq, "finite_dynamics": _finite(loaded.model)}


def _finite(model: object) -> bool:
    """RNEA, CRBA and ABA finite at neutral and three seeded random states."""
    import numpy as np
    import pinocchio as pin

    data, rng = model.createData(), np.random.default_rng(1)
    neutral = pin.neutral(model)
    for k in range(4):
        q = neutral if k == 0 else pin.integrate(model, neutral, rng.uniform(-3, 3, model.nv))
        v, a = rng.uniform(-1, 1, model.nv), rng.uniform(-1, 1, model.nv)
        tau = pin.rnea(model, data, q, v, a)
        results = [tau, pin.crba(model, data, q)]
        if not any("Mimic" in j.shortname() for j in model.joints):
            results.append(pin.aba(model, data, q, v, tau))
        if not all(np.all(np.isfinite(r)) for r in results):
            return False
    return True


def _child(loader: types.ModuleType, job: dict, write_fd: int) -> None:
    memory = int(job.get("memory", DEFAULT_MEMORY))
    cpu = int(job.get("timeout", DEFAULT_TIMEOUT)) + 1
    resource.setrlimit(resource.RLIMIT_AS, (memory, memory))
    resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu))
    try:
        report = _run_job(loader, job)
    except MemoryError:
        report = {"outcome": "error", "error_class": "MemoryError", "message": "RLIMIT_AS hit"}
    with os.fdopen(write_fd, "w") as out:
        out.write(json.dumps(report))


def _supervise(loader: types.ModuleType, job: dict) -> dict:
    timeout = float(job.get("timeout", DEFAULT_TIMEOUT))
    read_fd, write_fd = os.pipe()
    start = time.monotonic()
    pid = os.fork()
    if pid == 0:  # child
        os.close(read_fd)
        code = 0
        try:
            _child(loader, job, write_fd)
        except BaseException:
            code = 1
        os._exit(code)
    os.close(write_fd)
    chunks: list[bytes] = []
    timed_out = False
    while True:
        left = timeout - (time.monotonic() - start)
        if left <= 0:
            timed_out = True
            break
        ready, _, _ = select.select([read_fd], [], [], left)
        if ready:
            chunk = os.read(read_fd, 65536)
            if not chunk:
                break
            chunks.append(chunk)
    if timed_out:
        os.kill(pid, signal.SIGKILL)
    _, status = os.waitpid(pid, 0)
    os.close(read_fd)
    seconds = time.monotonic() - start
    if timed_out:
        report = {"outcome": "timeout"}
    elif os.WIFSIGNALED(status):
        report = {"outcome": "killed", "message": f"signal {os.WTERMSIG(status)}"}
    elif not chunks:
        report = {"outcome": "crashed", "message": f"exit status {os.WEXITSTATUS(status)}"}
    else:
        report = json.loads(b"".join(chunks))
    return {"id": job["id"], "seconds": round(seconds, 4), **report}


def main() -> int:
    """Read the jobs from stdin and print one JSON report line per job."""
    loader = _import_loader()
    if "--stream" in sys.argv[1:]:
        for line in sys.stdin:
            if line.strip():
                print(json.dumps(_supervise(loader, json.loads(line))), flush=True)
        return 0
    jobs = json.load(sys.stdin)
    for job in jobs:
        print(json.dumps(_supervise(loader, job)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
