"""The output folder of a CLI run: where summaries, figures, replays and results go.

Every ``youbot-opt`` command that produces results writes them to one folder
per run and prints where it is. With ``--out DIR`` the folder is ``DIR``
(re-running a sweep with the same ``DIR`` resumes it); without, a new folder
``youbot_opt_runs/<command>-<UTC date>-<UTC time>`` under the current
directory, never one that already exists.

Layout (each file is optional; a command writes what it has)::

    summary.json     one JSON object: the printed summary, machine readable
    result.npz       the saved result (``youbot_opt.trajopt.io``) or ``results/`` for sweeps
    *.png            figures
    replay.html      standalone meshcat replay (opens offline in any browser)
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np

from youbot_opt.sweeps.store import atomic_write_bytes

__all__ = [
    "DEFAULT_ROOT",
    "run_folder",
    "json_ready",
    "write_summary",
    "save_figure",
    "print_outputs",
]

DEFAULT_ROOT = Path("youbot_opt_runs")
"""Parent of the per-run folders made when no ``--out`` is given (relative to the cwd)."""


def run_folder(
    command: str, out: str | Path | None = None, *, root: str | Path | None = None
) -> Path:
    """Create (if needed) and return the output folder of one run.

    Parameters
    ----------
    command
        Sub-command name, used in the default folder name (e.g. ``"solve"``).
    out
        Folder chosen by the user (``--out``); created with its parents and
        reused if it exists (sweeps resume from it).
    root
        Parent of default folders; ``youbot_opt_runs`` in the cwd when omitted.

    Returns
    -------
    Path
        The folder, which exists on return.
    """
    if out is not None:
        folder = Path(out)
        if folder.exists() and not folder.is_dir():
            raise NotADirectoryError(f"--out {folder}: exists and is not a directory")
        folder.mkdir(parents=True, exist_ok=True)
        return folder
    parent = Path(root) if root is not None else DEFAULT_ROOT
    stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%d-%H%M%S")
    base = parent / f"{command}-{stamp}"
    for n in range(1, 1000):
        folder = base if n == 1 else base.with_name(f"{base.name}-{n}")
        try:
            folder.mkdir(parents=True, exist_ok=False)
        except FileExistsError:
            continue
        return folder
    raise FileExistsError(f"could not create a new run folder next to {base}")  # pragma: no cover


def json_ready(value: Any) -> Any:
    """Convert numpy scalars/arrays, paths and non-finite floats to plain JSON values.

    Non-finite floats become ``None`` (JSON has no NaN); arrays become lists.
    """
    if isinstance(value, Mapping):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if isinstance(value, np.ndarray):
        return [json_ready(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        return json_ready(value.item())
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Path):
        return str(value)
    if hasattr(value, "value") and hasattr(value, "name") and not isinstance(value, (int, str)):
        return json_ready(value.value)  # enums
    return value


def write_summary(
    folder: str | Path, summary: Mapping[str, Any], name: str = "summary.json"
) -> Path:
    """Write ``summary`` as indented JSON to ``folder/name`` atomically; return the path."""
    path = Path(folder) / name
    atomic_write_bytes(path, (json.dumps(json_ready(summary), indent=2) + "\n").encode())
    return path


def save_figure(fig: Any, folder: str | Path, name: str, *, dpi: int = 120) -> Path:
    """Save a matplotlib figure as ``folder/name`` (PNG unless a suffix is given); close it."""
    import matplotlib.pyplot as plt

    path = Path(folder) / (name if Path(name).suffix else f"{name}.png")
    fig.savefig(path, dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return path


def print_outputs(
    folder: str | Path, files: Iterable[str | Path] = (), stream: IO[str] | None = None
) -> None:
    """Print the run folder and the files written in it.

    Goes to stderr by default, so that ``--json`` keeps stdout one JSON object.
    """
    out = sys.stderr if stream is None else stream
    folder = Path(folder)
    print(f"output folder: {folder.resolve()}", file=out)
    for f in files:
        p = Path(f)
        try:
            shown = p.relative_to(folder)
        except ValueError:
            shown = p
        print(f"  {shown}", file=out)
