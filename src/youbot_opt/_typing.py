"""Shared type aliases (internal)."""

from __future__ import annotations

from typing import TypeAlias

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
"""A float64 numpy array; shapes are given in each docstring."""

JSONDict: TypeAlias = dict[str, object]
"""A JSON-like document being built (a summary, a JSON Lines row): ``_files.json_ready`` makes
its values JSON (numbers, strings, lists, dicts, NumPy values, paths, enums)."""
