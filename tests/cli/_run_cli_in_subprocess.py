"""Run ``youbot-opt`` command lines, each in a forked, capped child (the CLI fuzz tests).

Run as ``python tests/cli/_run_cli_in_subprocess.py``; each stdin line is a job
``{"argv": [...], "cwd": str, "timeout": s}`` and each answer one JSON line
``{"code", "signal", "timeout", "stdout", "stderr", "seconds"}``. This process
imports the CLI and the heavy libraries once; each job forks a child in its own
process group with ``RLIMIT_AS`` (4 GiB) and ``RLIMIT_CPU`` set, its standard
streams sent to files, and the whole group killed at the wall-clock time-out.
An exception escaping ``main`` is printed as a traceback (exit code 70), which
the tests refuse.
"""

from __future__ import annotations

import json
import os
import resource
import signal
import sys
import tempfile
import time
import traceback

MEMORY = 4 * 2**30  # [bytes] address space per child


def _child(job: dict, out_fd: int, err_fd: int) -> None:
    os.setpgid(0, 0)
    os.dup2(out_fd, 1)
    os.dup2(err_fd, 2)
    os.chdir(job["cwd"])
    cpu = int(job["timeout"]) + 2
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY, MEMORY))
    resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu))
    from youbot_opt.cli import main

    try:
        code = main(job["argv"])
    except SystemExit as e:  # argparse: 0 for --help, 2 for a bad argument
        code = e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
    except BaseException:
        traceback.print_exc()
        code = 70
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def _run(job: dict) -> dict:
    start = time.monotonic()
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        pid = os.fork()
        if pid == 0:
            try:
                _child(job, out.fileno(), err.fileno())
            finally:
                os._exit(71)
        timed_out, status = False, 0
        while True:
            done, status = os.waitpid(pid, os.WNOHANG)
            if done:
                break
            if time.monotonic() - start > job["timeout"]:
                timed_out = True
                os.killpg(pid, signal.SIGKILL)
                _, status = os.waitpid(pid, 0)
                break
            time.sleep(0.02)
        try:  # workers the child started, still in its group
            os.killpg(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        out.seek(0)
        err.seek(0)
        return {
            "code": os.WEXITSTATUS(status) if os.WIFEXITED(status) else None,
            "signal": os.WTERMSIG(status) if os.WIFSIGNALED(status) and not timed_out else None,
            "timeout": timed_out,
            "stdout": out.read()[-4000:].decode("utf-8", "replace"),
            "stderr": err.read()[-8000:].decode("utf-8", "replace"),
            "seconds": round(time.monotonic() - start, 3),
        }


def main() -> int:
    """Answer one JSON line per job line on stdin."""
    import youbot_opt.cli
    import youbot_opt.ikpath.multistart
    import youbot_opt.reproduction.study1
    import youbot_opt.trajopt.solver  # noqa: F401  (imported once, before the forks)

    youbot_opt.cli.build_parser()
    for line in sys.stdin:
        if line.strip():
            print(json.dumps(_run(json.loads(line))), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
