"""Strip the outputs of the project's notebooks, or check that they are stripped.

Committed notebooks carry no outputs: CI executes them (``tests/test_notebooks.py``),
so outputs in git would only be stale copies of what the code produces, and large
(a meshcat replay is about a megabyte). A notebook is *stripped* when

* no code cell has outputs and every ``execution_count`` is ``null``;
* no cell carries transient metadata (``execution``, ``ExecuteTime``,
  ``collapsed``, ``scrolled``);
* the notebook metadata holds no widget state (``widgets``) and no ``signature``.

Usage::

    python scripts/strip_notebooks.py              # strip notebooks/*.ipynb in place
    python scripts/strip_notebooks.py A.ipynb ...  # strip the given files
    python scripts/strip_notebooks.py --check      # list unstripped notebooks, exit 1 if any

Only ``nbformat`` is needed (installed with the ``test`` extra).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import nbformat

__all__ = ["NOTEBOOK_DIR", "notebook_paths", "problems", "strip", "strip_file", "main"]

NOTEBOOK_DIR = Path(__file__).resolve().parent.parent / "notebooks"
"""The repository's notebook folder."""

TRANSIENT_CELL_METADATA = ("execution", "ExecuteTime", "collapsed", "scrolled")
"""Cell metadata keys written by running or viewing a notebook."""

TRANSIENT_NOTEBOOK_METADATA = ("widgets", "signature")
"""Notebook metadata keys holding widget state or a trust signature."""


def notebook_paths(paths: Sequence[str | Path] = ()) -> list[Path]:
    """Return the notebooks to process: ``paths``, or every ``notebooks/*.ipynb``.

    Parameters
    ----------
    paths : sequence of str or Path
        Notebook files; empty for the repository's notebook folder.

    Returns
    -------
    list of Path
        The files, sorted when taken from the folder.
    """
    if paths:
        return [Path(p) for p in paths]
    return sorted(NOTEBOOK_DIR.glob("*.ipynb"))


def problems(nb: Any) -> list[str]:
    """List what is not stripped in a notebook (empty when it is stripped).

    Parameters
    ----------
    nb : nbformat.NotebookNode
        The notebook, as read by ``nbformat.read(..., as_version=4)``.

    Returns
    -------
    list of str
        One message per offending cell or metadata key, e.g.
        ``"cell 3: 2 outputs"``.
    """
    found = []
    for key in TRANSIENT_NOTEBOOK_METADATA:
        if key in nb.metadata:
            found.append(f"notebook metadata: {key!r}")
    for index, cell in enumerate(nb.cells):
        if cell.cell_type == "code":
            if cell.get("outputs"):
                found.append(f"cell {index}: {len(cell.outputs)} outputs")
            if cell.get("execution_count") is not None:
                found.append(f"cell {index}: execution_count {cell.execution_count}")
        for key in TRANSIENT_CELL_METADATA:
            if key in cell.get("metadata", {}):
                found.append(f"cell {index}: metadata {key!r}")
    return found


def strip(nb: Any) -> Any:
    """Strip a notebook in memory (see the module docstring) and return it.

    Parameters
    ----------
    nb : nbformat.NotebookNode
        The notebook; modified in place.

    Returns
    -------
    nbformat.NotebookNode
        The same notebook.
    """
    for key in TRANSIENT_NOTEBOOK_METADATA:
        nb.metadata.pop(key, None)
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs = []
            cell.execution_count = None
        for key in TRANSIENT_CELL_METADATA:
            cell.get("metadata", {}).pop(key, None)
    return nb


def strip_file(path: str | Path) -> bool:
    """Strip one notebook file in place.

    Parameters
    ----------
    path : str or Path
        The ``.ipynb`` file.

    Returns
    -------
    bool
        True if the file changed (it was not stripped).
    """
    path = Path(path)
    nb = nbformat.read(path, as_version=4)
    if not problems(nb):
        return False
    nbformat.write(strip(nb), path)
    return True


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (1: ``--check`` found unstripped files)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("paths", nargs="*", help="notebooks (default: notebooks/*.ipynb)")
    parser.add_argument(
        "--check", action="store_true", help="only list unstripped notebooks; exit 1 if any"
    )
    args = parser.parse_args(argv)
    paths = notebook_paths(args.paths)
    if not paths:
        print(f"no notebooks found in {NOTEBOOK_DIR}", file=sys.stderr)
        return 1
    if args.check:
        bad = 0
        for path in paths:
            found = problems(nbformat.read(path, as_version=4))
            if found:
                bad += 1
                print(f"{path}: not stripped ({'; '.join(found)})")
        return 1 if bad else 0
    for path in paths:
        if strip_file(path):
            print(f"stripped {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
