"""Meshes read once per process while their files are unchanged: :func:`mesh_loader`.

A robot's visual and collision geometry mostly read the same mesh files, and a
session loads the same robot many times; reading meshes is most of a load
(0.3-0.6 s for ur5 and panda). :func:`mesh_loader` hands out one process-wide
``coal.CachedMeshLoader`` under a lock; a file whose mtime [ns] or size changed
since starts a new, empty cache (coal compares whole seconds only), and the
cache empties after :data:`MAX_CACHED_FILES` files, which bounds its memory.

>>> with mesh_loader(["link.stl"]) as loader:  # doctest: +SKIP
...     bvh = loader.load("link.stl", np.ones(3))
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterable, Iterator
from contextlib import contextmanager

import coal

__all__ = ["MAX_CACHED_FILES", "clear_mesh_cache", "mesh_loader"]

MAX_CACHED_FILES = 2048
"""Distinct mesh files the process-wide cache holds before it starts again empty."""

_lock = threading.RLock()
_loader = coal.CachedMeshLoader()
_stamps: dict[str, tuple[int, int]] = {}


def _stamp(path: str) -> tuple[int, int]:
    """(mtime [ns], size [bytes]) of ``path``; (-1, -1) when it cannot be read."""
    try:
        st = os.stat(path)
    except OSError:
        return (-1, -1)
    return (st.st_mtime_ns, st.st_size)


def clear_mesh_cache() -> None:
    """Forget every cached mesh (the next load reads each file again)."""
    global _loader
    with _lock:
        _loader = coal.CachedMeshLoader()
        _stamps.clear()


@contextmanager
def mesh_loader(files: Iterable[str | os.PathLike[str]]) -> Iterator[coal.CachedMeshLoader]:
    """Hold the process-wide mesh loader, valid for ``files``, under a lock while in use.

    Parameters
    ----------
    files : iterable of path-like
        The mesh files about to be read (absolute paths, as they will be passed
        to the loader). Other files may be read too; only these are checked for
        changes before the loader is handed out.

    Yields
    ------
    coal.CachedMeshLoader
        A loader that returns a cached mesh for a file read before (same path,
        same scale) and unchanged since; pass it as ``mesh_loader=`` to
        Pinocchio's geometry builders or call its ``load(path, scale)``.
    """
    global _loader
    names = [os.fspath(f) for f in files]
    with _lock:
        now = {name: _stamp(name) for name in names}
        changed = any(name in _stamps and _stamps[name] != s for name, s in now.items())
        if changed or len(_stamps) + len(now) > MAX_CACHED_FILES:
            _loader = coal.CachedMeshLoader()
            _stamps.clear()
        _stamps.update(now)
        yield _loader
