"""Starts of the spatial cyclic IK multistart: greedy, coherent and random.

Start 0 is the greedy DLS path from the default configuration (the common
practice, :func:`~youbot_opt.ikpath.spatial.greedy_path`). A *coherent* start
is the greedy DLS path from a random in-limit configuration: each target solved
from the previous one, so neighbouring configurations are close (the 3-D
analogue of the planar feasible starts). A *random* start draws every
configuration uniformly in the limits (clipped to ``[-pi, pi]``). All starts
are deterministic in the seed; start ``k`` of a seed does not depend on how
many starts are drawn after it.
"""

from __future__ import annotations

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.ikpath.spatial import SpatialIKProblem, greedy_path, random_theta
from youbot_opt.ikpath.starts import check_start_request

__all__ = ["SPATIAL_START_KINDS", "make_spatial_starts"]

SPATIAL_START_KINDS: tuple[str, ...] = ("mixed", "coherent", "random")
"""Start kinds: ``mixed`` alternates coherent (odd) and random (even) after the greedy start."""


def make_spatial_starts(
    problem: SpatialIKProblem, n_starts: int, seed: int, *, kind: str = "mixed"
) -> Array:
    """Draw starts (n_starts, n s): the greedy DLS path, then coherent and/or random ones.

    Parameters
    ----------
    problem : SpatialIKProblem
        The problem (limits, targets).
    n_starts : int
        Number of starts (>= 1); start 0 is always the greedy path.
    seed : int
        Seed of the draws (deterministic).
    kind : {"mixed", "coherent", "random"}
        ``mixed``: odd starts coherent, even starts random (the default);
        ``coherent``: all coherent; ``random``: all random (after start 0).

    Returns
    -------
    ndarray, shape (n_starts, n s)
        Stacked joint angles [rad] within the limits.

    Raises
    ------
    ParameterError
        If ``n_starts < 1`` or ``kind`` is unknown
        (:func:`~youbot_opt.ikpath.starts.check_start_request`).
    """
    n = check_start_request(n_starts, kind, SPATIAL_START_KINDS)
    rng = np.random.default_rng(seed)
    starts = np.empty((n, problem.n_variables))
    starts[0] = greedy_path(problem)[0].ravel()
    for k in range(1, n):
        coherent = kind == "coherent" or (kind == "mixed" and k % 2 == 1)
        if coherent:
            starts[k] = greedy_path(problem, random_theta(problem, rng))[0].ravel()
        else:
            starts[k] = np.concatenate(
                [random_theta(problem, rng) for _ in range(problem.n_targets)]
            )
    return np.clip(starts, problem.lower, problem.upper)
