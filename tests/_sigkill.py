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


def count_payloads(out: Path) -> int:
    """Item payload files in the sweep folder ``out`` (``items/<hh>/<key><suffix>``).

    A payload is written as its item finishes, before the group commit that
    records it in the journal, so counting payloads (not records) lets a kill
    land while the items finished just before it still wait for their group:
    a sweep's last items are not all committed, and the process gone, before
    the kill can come (which counting records allowed on a fast machine).
    """
    return sum(1 for f in (out / "items").glob("??/*") if not f.name.startswith("."))


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


def kill_repeatedly(cmd: list[str], out: Path, n_kills: int, seed: int) -> dict:  # type: ignore[type-arg]
    """Start ``cmd`` ``n_kills`` times, SIGKILL it at seeded random points, then let it finish.

    Returns the final run's JSON summary, after checking that every kill landed while
    work was left and that no pool worker outlived a killed sweep.
    """
    rng = np.random.default_rng(seed)
    kills = 0
    for _ in range(n_kills):
        before = count_payloads(out)
        target = before + int(rng.integers(1, 4))  # kill after 1-3 more finished items ...
        delay = float(rng.uniform(0.0, 0.01))  # ... plus 0-10 ms, to land anywhere in a write
        proc = subprocess.Popen(
            cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
        )
        try:
            deadline = time.monotonic() + 120.0
            while (
                count_payloads(out) < target and proc.poll() is None and time.monotonic() < deadline
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
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    summary: dict = json.loads(done.stdout)  # type: ignore[type-arg]
    return summary
