"""SIGKILL a sweep command at seeded random moments (shared by the kill-and-resume tests).

The command runs in its own session; after each kill the helpers check that no
worker outlived it, and the last run is let finish and its JSON summary returned.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np

ITEM_SLEEP = 0.05
"""[s] added to every item of a killed sweep: at 2 workers at most 40 items/s,
so a group commit (at most 0.1 s) holds at most ~4 items and each kill (after
1-3 committed items, plus 0-30 ms) takes at most ~8 items of a 33-60-item
sweep, whatever the machine's speed."""


def count_records(out: Path) -> int:
    """Items with a record in the sweep folder ``out`` (journal or flat record files)."""
    from youbot_opt.sweeps.store import stored_records

    return len({r.key for r in stored_records(out)})


def session_pids(sid: int) -> list[int]:
    """Live processes of session ``sid`` (the CLI and its pool workers)."""
    pids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] != "Z":
            pids.append(int(stat.parent.name))
    return pids


def slowed(cmd: list[str], item_sleep: float) -> tuple[list[str], dict[str, str]]:
    """``cmd`` (``python -m youbot_opt ...``) with every sweep item sleeping ``item_sleep`` [s].

    The solves of a short sweep take milliseconds, and the store commits items
    in groups (up to 0.1 s), so on a fast machine a whole sweep can finish inside
    the window a kill needs; a fixed sleep per item makes the sweep last the
    same on every machine. Returns the command and its environment.
    """
    assert cmd[1:3] == ["-m", "youbot_opt"], cmd
    tests = Path(__file__).resolve().parent
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(tests), env.get("PYTHONPATH")]))
    return [cmd[0], str(tests / "_slow_cli.py"), repr(item_sleep), *cmd[3:]], env


def kill_repeatedly(
    cmd: list[str], out: Path, n_kills: int, seed: int, *, item_sleep: float | None = None
) -> dict:  # type: ignore[type-arg]
    """Start ``cmd`` ``n_kills`` times, SIGKILL it at seeded random points, then let it finish.

    ``item_sleep`` [s]: every sweep item of ``cmd`` (``python -m youbot_opt ...``)
    sleeps this long first (see :func:`slowed`). Returns the final run's JSON
    summary, after checking that every kill landed while work was left and that
    no pool worker outlived a killed sweep.
    """
    env = None
    if item_sleep is not None:
        cmd, env = slowed(cmd, item_sleep)
    rng = np.random.default_rng(seed)
    kills = 0
    for _ in range(n_kills):
        before = count_records(out)
        target = before + int(rng.integers(1, 4))  # kill after 1-3 more finished items ...
        delay = float(rng.uniform(0.0, 0.03))  # ... plus 0-30 ms, to land anywhere in a write
        proc = subprocess.Popen(
            cmd,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
            env=env,
        )
        try:
            deadline = time.monotonic() + 120.0
            while (
                count_records(out) < target and proc.poll() is None and time.monotonic() < deadline
            ):
                time.sleep(0.005)
            time.sleep(delay)
            if proc.poll() is None:
                os.kill(proc.pid, signal.SIGKILL)
                kills += 1
            proc.wait(timeout=30)
            # The orphaned pool workers notice the dead parent and exit by themselves.
            deadline = time.monotonic() + 5.0
            while session_pids(proc.pid) and time.monotonic() < deadline:
                time.sleep(0.05)
            assert session_pids(proc.pid) == [], "pool workers outlived the killed sweep"
        finally:
            try:
                os.killpg(proc.pid, signal.SIGKILL)  # only our own session; normally empty by now
            except ProcessLookupError:
                pass
    assert kills == n_kills, "the sweep finished before all kills; make it longer"
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stderr
    summary: dict = json.loads(done.stdout)  # type: ignore[type-arg]
    return summary
