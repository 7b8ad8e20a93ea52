"""Shared pytest fixtures.

Module-specific fixtures live in the test modules; only fixtures used by several
test modules belong here.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture()
def rng() -> np.random.Generator:
    """A freshly seeded generator, so each test's random draws are reproducible."""
    return np.random.default_rng(0)


@pytest.fixture()
def faults(monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    """``faults(crash=keys, hang=keys, once_dir=None)``: sweep tasks that fail in pool workers.

    See ``tests/_faults.py``; calling it again replaces the earlier faults.
    """
    from _faults import inject

    def set_faults(**kwargs):  # type: ignore[no-untyped-def]
        inject(monkeypatch, **kwargs)

    return set_faults
