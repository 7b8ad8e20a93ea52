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

from collections.abc import Mapping
from typing import Any

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.spatial import greedy_path, random_theta
from youbot_opt.ikpath.starts import IndexedStarts, check_start_request

__all__ = ["CHECKPOINT", "SPATIAL_START_KINDS", "SpatialStarts", "make_spatial_starts"]

SPATIAL_START_KINDS: tuple[str, ...] = ("mixed", "coherent", "random")
"""Start kinds: ``mixed`` alternates coherent (odd) and random (even) after the greedy start."""


def make_spatial_starts(
    problem: CyclicIKProblem, n_starts: int, seed: int, *, kind: str = "mixed"
) -> Array:
    """Draw starts (n_starts, n s): the greedy DLS path, then coherent and/or random ones.

    Parameters
    ----------
    problem : CyclicIKProblem
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
        starts[k] = _draw(problem, kind, k, rng)
    return np.clip(starts, problem.lower, problem.upper)


def _coherent(kind: str, k: int) -> bool:
    return kind == "coherent" or (kind == "mixed" and k % 2 == 1)


def _draw(problem: CyclicIKProblem, kind: str, k: int, rng: np.random.Generator) -> Array:
    """Start ``k >= 1`` (unclipped), drawn from ``rng`` where start ``k - 1`` left it."""
    if _coherent(kind, k):
        return greedy_path(problem, random_theta(problem, rng))[0].ravel()
    return np.concatenate([random_theta(problem, rng) for _ in range(problem.n_targets)])


def _skip(problem: CyclicIKProblem, kind: str, k: int, rng: np.random.Generator) -> None:
    """Advance ``rng`` past start ``k`` as :func:`_draw` would (no greedy path solved)."""
    for _ in range(1 if _coherent(kind, k) else problem.n_targets):
        random_theta(problem, rng)


class SpatialStarts(IndexedStarts):
    """The starts of :func:`make_spatial_starts`, each drawn when asked for.

    ``SpatialStarts(problem, n, seed, kind=kind)[k]`` equals
    ``make_spatial_starts(problem, n, seed, kind=kind)[k]``. The draws share one
    generator, so its state is kept every :data:`CHECKPOINT` starts and after
    the last start drawn: asking in increasing order costs one draw per start,
    any other start at most ``CHECKPOINT`` cheap skips (no greedy path is
    solved for a skipped start). Memory: one generator state per ``CHECKPOINT`` starts.
    """

    def __init__(
        self, problem: CyclicIKProblem, n_starts: int, seed: int, *, kind: str = "mixed"
    ) -> None:
        self._n = check_start_request(n_starts, kind, SPATIAL_START_KINDS)
        self._problem, self._kind = problem, kind
        rng = np.random.default_rng(seed)
        self._states: dict[int, Mapping[str, Any]] = {1: rng.bit_generator.state}
        self._cursor: tuple[int, Mapping[str, Any]] = (1, rng.bit_generator.state)

    def draw(self, j: int) -> Array:
        """Return start ``j``: the greedy path's first configuration for 0, else drawn [rad]."""
        problem = self._problem
        if j == 0:
            return np.clip(greedy_path(problem)[0].ravel(), problem.lower, problem.upper)
        at, state = self._cursor  # the generator's state before start `at`
        if not at <= j:
            at = (j - 1) // CHECKPOINT * CHECKPOINT + 1
            state = self._states[at]
        rng = np.random.default_rng()
        rng.bit_generator.state = state
        for i in range(at, j):
            self._remember(i, rng)
            _skip(problem, self._kind, i, rng)
        self._remember(j, rng)
        start = _draw(problem, self._kind, j, rng)
        self._cursor = (j + 1, rng.bit_generator.state)
        return np.clip(start, problem.lower, problem.upper)

    def _remember(self, i: int, rng: np.random.Generator) -> None:
        if (i - 1) % CHECKPOINT == 0 and i not in self._states:
            self._states[i] = rng.bit_generator.state


CHECKPOINT = 1024
"""Starts between two kept generator states of :class:`SpatialStarts`."""
