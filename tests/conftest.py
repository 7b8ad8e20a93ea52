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
