"""The CPU cores this process may run on (a plain helper of layer L0).

One count for the compiler's parallel jobs (:mod:`youbot_opt.nlp.codegen`) and the
sweeps' default number of workers (:func:`youbot_opt.sweeps.pool.default_workers`).

>>> usable_cores() >= 1
True
"""

from __future__ import annotations

import os

__all__ = ["usable_cores"]


def usable_cores() -> int:
    """Return how many CPU cores this process may run on (its affinity where known; >= 1)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)
