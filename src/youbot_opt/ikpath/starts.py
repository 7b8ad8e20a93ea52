"""Starts of an IK-path multistart: the zero vector, then seeded random ones.

Start 0 is the study's zero vector (clipped into the limits). The others are
drawn in the parent process from ``numpy.random.default_rng(seed)``, so they
do not depend on the executor, in one of two ways:

* ``"uniform"``: every variable uniform in ``[max(l, -pi), min(u, pi)]``;
* ``"feasible"`` (default): each configuration is a random exact IK solution
  of its target within the limits (first ``n - 2`` angles uniform in their
  ranges, the last two in closed form with a random elbow; redrawn up to 50
  times, else the reachability witness), and unlimited joints are shifted by
  multiples of 2 pi so that the cyclic sum of squared steps is smallest
  for the drawn configurations.
  Uniform starts put independent 2 pi windings into the configurations and
  many of them end in minima that differ from a better one only by such
  windings; feasible starts sample the elbow branches and the redundancy
  instead.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.geometry import two_link_ik
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability import ReachVerdict, theta_ranges

__all__ = ["START_KINDS", "make_starts"]

START_KINDS: tuple[str, ...] = ("feasible", "uniform")
"""How random starts can be drawn (``kind`` of :func:`make_starts`)."""


def make_starts(
    problem: CyclicIKProblem,
    n_starts: int,
    seed: int,
    *,
    kind: str = "feasible",
    verdicts: Sequence[ReachVerdict] = (),
) -> Array:
    """Draw the starts: the zero vector (clipped), then seeded random ones; (n_starts, n s).

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    n_starts : int
        Number of starts (>= 1).
    seed : int
        Seed of ``numpy.random.default_rng``.
    kind : {"feasible", "uniform"}
        How random starts are drawn (see the module docstring).
    verdicts : sequence of ReachVerdict
        Reachability verdicts; their witnesses are the fallback of ``"feasible"``.

    Raises
    ------
    ParameterError
        If ``n_starts < 1`` or ``kind`` is unknown.
    """
    if int(n_starts) != n_starts or n_starts < 1:
        raise ParameterError(
            f"n_starts must be an integer >= 1, got {n_starts!r}", name="n_starts", value=n_starts
        )
    if kind not in START_KINDS:
        raise ParameterError(
            f"unknown start kind {kind!r}; choose one of {', '.join(START_KINDS)}",
            name="starts",
            value=kind,
        )
    rng = np.random.default_rng(seed)
    lo = np.maximum(problem.lower, -np.pi)
    hi = np.minimum(problem.upper, np.pi)
    lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
    starts = rng.uniform(lo, hi, size=(int(n_starts), problem.n_variables))
    if kind == "feasible":
        for k in range(1, int(n_starts)):
            starts[k] = _feasible_start(problem, rng, starts[k], verdicts)
    starts = np.clip(starts, problem.lower, problem.upper)
    starts[0] = problem.default_start()
    return starts


def _feasible_start(
    problem: CyclicIKProblem,
    rng: np.random.Generator,
    fallback: Array,
    verdicts: Sequence[ReachVerdict],
) -> Array:
    """One start made of random exact IK solutions, unwrapped across configurations."""
    chain = problem.chain
    n = chain.n
    ranges = theta_ranges(chain, problem.use_limits) or [
        (-np.pi + o, 2 * np.pi) for o in chain.angle_offset
    ]
    q = fallback.reshape(problem.n_targets, n).copy()
    lengths = chain.lengths
    for j, p in enumerate(problem.targets):
        for _ in range(50):
            theta = np.array([r[0] + rng.uniform(0.0, r[1]) for r in ranges])
            if n == 1:  # unique solution; the witness below holds it
                continue
            phi = np.cumsum(theta[: n - 2])
            w = chain.base + np.sum(
                lengths[: n - 2, None] * np.column_stack([np.cos(phi), np.sin(phi)]), axis=0
            )
            psi = float(phi[-1]) if n > 2 else 0.0
            sol = two_link_ik(
                float(p[0]),
                float(p[1]),
                float(w[0]),
                float(w[1]),
                psi,
                float(lengths[n - 2]),
                float(lengths[n - 1]),
                ranges[n - 2],
                ranges[n - 1],
                elbow_first=1.0 if rng.uniform() < 0.5 else -1.0,
            )
            if sol is not None:
                theta[n - 2], theta[n - 1] = sol
                q[j] = theta - chain.angle_offset
                break
        else:
            if j < len(verdicts) and verdicts[j].witness is not None:
                q[j] = verdicts[j].witness
    if problem.use_limits:
        periodic = ~(np.isfinite(chain.q_lower) & np.isfinite(chain.q_upper))
    else:
        periodic = np.ones(n, dtype=bool)
    for i in np.flatnonzero(periodic):
        q[:, i] = _best_windings(q[:, i])
    return q.ravel()


def _best_windings(col: Array) -> Array:
    """Shift entries by multiples of 2 pi to minimise the cyclic sum of squared steps.

    The steps ``d_j`` (closing step included) are taken in ``(-pi, pi]``; they
    must sum to zero, so ``K = sum(d) / 2 pi`` of them move by ``-2 pi sign(K)``:
    the largest ones (smallest for ``K < 0``), which is optimal because the cost
    is convex in each step.
    """
    steps = np.roll(col, -1) - col
    steps = (steps + np.pi) % (2 * np.pi) - np.pi
    turns = int(round(float(np.sum(steps)) / (2 * np.pi)))
    order = np.argsort(steps)
    if turns > 0:
        steps[order[-turns:]] -= 2 * np.pi
    elif turns < 0:
        steps[order[:-turns]] += 2 * np.pi
    return col[0] + np.r_[0.0, np.cumsum(steps[:-1])]
