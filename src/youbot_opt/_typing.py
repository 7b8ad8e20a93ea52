"""Shared type aliases (internal)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
"""A float64 numpy array; shapes are given in each docstring."""
