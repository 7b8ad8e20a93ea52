"""Starts of a cyclic IK multistart, deterministic in the seed and the start's index.

A planar chain's start 0 is the study's zero vector (clipped into the limits),
then ``"feasible"`` (random exact IK solutions within the limits, the default)
or ``"uniform"`` starts (:func:`make_starts`; docs/design.md says why feasible
is the default). Another robot's start 0 is the greedy DLS path, then
``"coherent"`` (greedy from a random in-limit configuration) and/or
``"random"`` starts (:func:`make_starts_3d`). Start ``k`` does not depend
on how many starts are drawn.

>>> x0 = make_starts(problem, n_starts=20, seed=0)  # (20, n s)  # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import casadi as ca
import numpy as np
import numpy.typing as npt

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.dls import greedy_path, random_theta
from youbot_opt.ikpath.geometry import two_link_ik
from youbot_opt.ikpath.methods.ipopt import frame_expression, target_rows
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability.planar import ReachVerdict, theta_ranges
from youbot_opt.sweeps.lazy import LazySequence

__all__ = [
    "check_start_request",
    "CHECKPOINT",
    "IndexedStarts",
    "make_starts_3d",
    "make_starts",
    "PlanarStarts",
    "START_KINDS_3D",
    "Starts3D",
    "START_KINDS",
    "BRANCH_KIND",
    "AUTOMATIC_TIME_BUDGET",
    "BranchStarts",
    "branch_chains",
    "check_time_budget",
    "periodic_joints",
    "start_budget",
    "target_samples",
]

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

    Start ``k`` is drawn from its own generator,
    ``default_rng(SeedSequence(seed, spawn_key=(k,)))`` (the ``k``-th child of
    ``SeedSequence(seed).spawn``, as trajectory seeds), so the first 1000 starts
    of a 2000-start sweep are the 1000-start sweep. Random starts are:

    * ``"uniform"``: every variable uniform in ``[max(l, -pi), min(u, pi)]``;
    * ``"feasible"``: each configuration is a random exact IK solution of its
      target within the limits (first ``n - 2`` angles uniform in their ranges,
      the last two in closed form with a random elbow; redrawn up to 50 times,
      else the reachability witness), and unlimited joints are shifted by
      multiples of 2 pi so that the cyclic sum of squared steps is smallest for
      the drawn configurations.

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    n_starts : int
        Number of starts (>= 1).
    seed : int
        Seed of ``numpy.random.default_rng``.
    kind : {"feasible", "uniform"}
        How random starts are drawn (see above).
    verdicts : sequence of ReachVerdict
        Reachability verdicts; their witnesses are the fallback of ``"feasible"``.

    Raises
    ------
    ParameterError
        If ``n_starts < 1``, or ``kind`` is unknown.
    """
    check_start_request(n_starts, kind, START_KINDS)
    source = PlanarStarts(problem, int(n_starts), seed, kind=kind, verdicts=verdicts)
    return np.array([source[k] for k in range(int(n_starts))]).reshape(
        int(n_starts), problem.n_variables
    )


class IndexedStarts(LazySequence[Array]):
    """Starts drawn when asked for: ``starts[k]`` (negative ``k`` and slices as a list's).

    A subclass sets ``self._n`` and draws start ``j`` (``0 <= j < n``) in
    :meth:`draw`; planar (:class:`PlanarStarts`) and 3-D (:class:`Starts3D`) starts share it.
    """

    _n: int
    noun = "start"

    def __len__(self) -> int:
        return self._n

    def _item(self, j: int) -> Array:
        return self.draw(j)

    def draw(self, j: int) -> Array:
        """Return start ``j`` (``0 <= j < len(self)``), shape ``(s, n)`` or ``(n,)`` [rad]."""
        raise NotImplementedError


class PlanarStarts(IndexedStarts):
    """The per-index starts of :func:`make_starts`, each drawn when asked for (none is held).

    ``PlanarStarts(problem, n, seed, kind=kind)[k]`` equals
    ``make_starts(problem, n, seed, kind=kind)[k]`` (``rng="per-index"``), so a
    sweep of 10^5 starts draws each as its task is made. Parameters as
    :func:`make_starts`; picklable.
    """

    def __init__(
        self,
        problem: CyclicIKProblem,
        n_starts: int,
        seed: int,
        *,
        kind: str = "feasible",
        verdicts: Sequence[ReachVerdict] = (),
    ) -> None:
        self._n = check_start_request(n_starts, kind, START_KINDS)
        self._problem, self._seed, self._kind = problem, int(seed), kind
        self._verdicts = tuple(verdicts)
        lo = np.maximum(problem.lower, -np.pi)
        hi = np.minimum(problem.upper, np.pi)
        self._lo, self._hi = np.minimum(lo, hi), np.maximum(lo, hi)

    def draw(self, j: int) -> Array:
        """Return start ``j``: the zero/default start for 0, else from its own seed [rad]."""
        problem = self._problem
        if j == 0:
            return problem.default_start()
        gen = np.random.default_rng(np.random.SeedSequence(self._seed, spawn_key=(j,)))
        start = gen.uniform(self._lo, self._hi)
        if self._kind == "feasible":
            start = _feasible_start(problem, gen, start, self._verdicts)
        return np.clip(start, problem.lower, problem.upper)


def check_start_request(n_starts: int, kind: str, kinds: Sequence[str]) -> int:
    """Check the number of starts and the start kind of a multistart (planar or 3-D).

    Parameters
    ----------
    n_starts : int
        Number of starts; integral floats such as ``2.0`` are accepted.
    kind : str
        How the random starts are drawn.
    kinds : sequence of str
        The valid kinds (:data:`START_KINDS`, or the 3-D ones).

    Returns
    -------
    int
        ``n_starts``.

    Raises
    ------
    ParameterError
        If ``n_starts`` is not an integer >= 1 (``name="n_starts"``), or ``kind``
        is not one of ``kinds`` (``name="starts"``, the message lists them).
    """
    if int(n_starts) != n_starts or n_starts < 1:
        raise ParameterError(
            f"n_starts must be an integer >= 1, got {n_starts!r}", name="n_starts", value=n_starts
        )
    _check_choice(kind, kinds, what="start kind", name="starts")
    return int(n_starts)


def _check_choice(value: str, choices: Sequence[str], *, what: str, name: str) -> None:
    if value not in choices:
        raise ParameterError(
            f"unknown {what} {value!r}; choose one of {', '.join(choices)}",
            name=name,
            value=value,
        )


def _feasible_start(
    problem: CyclicIKProblem,
    rng: np.random.Generator,
    fallback: Array,
    verdicts: Sequence[ReachVerdict],
) -> Array:
    """One start made of random exact IK solutions, unwrapped across configurations."""
    chain = problem.planar_chain
    n = chain.n
    ranges = theta_ranges(chain, problem.use_limits) or [
        (-np.pi + o, 2 * np.pi) for o in chain.angle_offset
    ]
    q = fallback.reshape(problem.n_targets, n).copy()
    lengths = chain.lengths
    for j, p in enumerate(problem.target_points):
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


START_KINDS_3D: tuple[str, ...] = ("mixed", "coherent", "random")
"""Start kinds: ``mixed`` alternates coherent (odd) and random (even) after the greedy start."""


def make_starts_3d(
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
    n = check_start_request(n_starts, kind, START_KINDS_3D)
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


class Starts3D(IndexedStarts):
    """The starts of :func:`make_starts_3d`, each drawn when asked for.

    ``Starts3D(problem, n, seed, kind=kind)[k]`` equals
    ``make_starts_3d(problem, n, seed, kind=kind)[k]``. The draws share one
    generator, so its state is kept every :data:`CHECKPOINT` starts and after
    the last start drawn: asking in increasing order costs one draw per start,
    any other start at most ``CHECKPOINT`` cheap skips (no greedy path is
    solved for a skipped start). Memory: one generator state per ``CHECKPOINT`` starts.
    """

    def __init__(
        self, problem: CyclicIKProblem, n_starts: int, seed: int, *, kind: str = "mixed"
    ) -> None:
        self._n = check_start_request(n_starts, kind, START_KINDS_3D)
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
"""Starts between two kept generator states of :class:`Starts3D`."""


# ------------------------------------------------------------------ branch starts
def target_samples(
    problem: CyclicIKProblem,
    j: int,
    n_samples: int,
    rng: np.random.Generator,
    *,
    iterations: int = 80,
) -> Array:
    """Solve target ``j`` alone from ``n_samples`` random seeds: (k, n) solutions [rad], k <= n.

    Damped least squares on the target's rows (CasADi, all seeds at once: see
    :func:`~youbot_opt.ikpath.methods.ipopt.target_rows`), projected on the joint box;
    only the seeds that meet the target (its tolerances, by Pinocchio) are kept. Joints
    that do not move the target's rows at any kept solution (a wrist turning about the
    tool axis for a position) are set to their clipped zero: any value meets the target,
    and one value costs no motion.
    """
    fn = _rows_function(problem, j).map(int(n_samples))
    n = problem.n_joints
    lo, hi = problem.lower[:n], problem.upper[:n]
    draw_lo, draw_hi = np.maximum(lo, -np.pi), np.minimum(hi, np.pi)
    theta = rng.uniform(np.minimum(draw_lo, draw_hi), np.maximum(draw_lo, draw_hi), (n_samples, n))
    lam = np.full(n_samples, 1e-2)

    def rows(t: Array) -> tuple[Array, Array]:
        out = fn(t.T)
        c = np.asarray(out[0], dtype=float).T  # (k, m)
        jac = np.asarray(out[1], dtype=float).reshape(c.shape[1], n_samples, n)
        return c, jac.transpose(1, 0, 2)

    c, jac = rows(theta)
    cost = np.einsum("km,km->k", c, c)
    eye = np.eye(c.shape[1])
    for _ in range(iterations):
        if np.all(cost <= 1e-24):
            break
        gram = jac @ jac.transpose(0, 2, 1) + lam[:, None, None] ** 2 * eye
        step = np.einsum("kmn,km->kn", jac, np.linalg.solve(gram, c[..., None])[..., 0])
        trial = np.clip(theta - step, lo, hi)
        c_t, jac_t = rows(trial)
        cost_t = np.einsum("km,km->k", c_t, c_t)
        better = cost_t < cost
        theta[better], c[better], jac[better], cost[better] = (
            trial[better], c_t[better], jac_t[better], cost_t[better]
        )  # fmt: skip
        lam = np.where(better, np.maximum(lam / 10.0, 1e-9), np.minimum(lam * 10.0, 1e6))
    data = problem.create_data()
    target = problem.targets[j]
    kept = [k for k in range(n_samples) if target.met(problem.placement(theta[k], data))]
    out = theta[kept]
    if out.size:
        moves = np.max(np.abs(jac[kept]), axis=(0, 1))
        free = moves < 1e-9
        out[:, free] = np.clip(0.0, lo, hi)[free]
    return out


def _rows_function(problem: CyclicIKProblem, j: int) -> ca.Function:
    """``theta -> (c_j, dc_j/dtheta)``: target ``j``'s equality rows and their Jacobian."""
    theta = ca.SX.sym("theta", problem.n_joints)
    eq = target_rows(problem, j, *frame_expression(problem, theta))[0]
    return ca.Function("rows", [theta], [eq, ca.jacobian(eq, theta)])


def periodic_joints(problem: CyclicIKProblem) -> npt.NDArray[np.bool_]:
    """Joints whose angle may wrap: revolute with limits at least 4 pi apart (or none), (n,)."""
    n = problem.n_joints
    revolute = np.array(
        [
            not problem.model.joints[int(j)].shortname().startswith("JointModelP")
            for j in problem.active
        ]
    )
    span = problem.upper[:n] - problem.lower[:n]
    return revolute & (~problem.use_limits | (span >= 4 * np.pi - 1e-9) | ~np.isfinite(span))


def branch_chains(
    problem: CyclicIKProblem,
    samples: Sequence[Array],
    n_chains: int,
) -> tuple[Array, Array]:
    """Return the cheapest cyclic chains of per-target solutions: (k, n s) starts and their E.

    Dynamic programming over the cycle (min-plus products of the per-leg cost matrices):
    for every solution of target 0, the chain of one solution per target that closes the
    cycle with the least ``E`` (angles of :func:`periodic_joints` compared modulo 2 pi,
    then unwound along the chain with the fewest turns, :func:`_best_windings`). Distinct
    chains, cheapest first, at most ``n_chains``; ``E`` in [rad^2] of each unwound chain.
    """
    periodic = periodic_joints(problem)
    w = problem.weights
    cands = [np.where(periodic, (np.asarray(c) + np.pi) % (2 * np.pi) - np.pi, c) for c in samples]
    s = len(cands)

    def legs(a: Array, b: Array) -> Array:
        d = b[None, :, :] - a[:, None, :]
        d = np.where(periodic, (d + np.pi) % (2 * np.pi) - np.pi, d)
        return 0.5 * np.einsum("abn,n->ab", d * d, w)

    value = legs(cands[0], cands[1])  # (K0, K1): cheapest from a at 0 to b at 1
    back = []
    for j in range(1, s - 1):
        total = value[:, :, None] + legs(cands[j], cands[j + 1])[None, :, :]
        arg = np.argmin(total, axis=1)
        back.append(arg)
        value = np.take_along_axis(total, arg[:, None, :], axis=1)[:, 0, :]
    closing = value + legs(cands[s - 1], cands[0]).T  # (K0, K_{s-1})
    last = np.argmin(closing, axis=1)
    cost = closing[np.arange(len(last)), last]
    seen: set[tuple[tuple[int, int], ...]] = set()
    chains, energies = [], []
    for a in np.argsort(cost, kind="stable"):
        idx = [int(a)] * s
        idx[s - 1] = int(last[a])
        for j in range(s - 2, 0, -1):
            idx[j] = int(back[j - 1][a, idx[j + 1]])
        key = tuple(sorted((j, i) for j, i in enumerate(idx)))
        if key in seen:
            continue
        seen.add(key)
        x = _unwound(problem, np.array([cands[j][i] for j, i in enumerate(idx)]))
        chains.append(x)
        energies.append(problem.objective(x))
        if len(chains) >= n_chains:
            break
    return np.array(chains).reshape(-1, problem.n_variables), np.array(energies)


BRANCH_KIND = "branches"
"""Start kind of automatic starts: witnesses, then coherent IK branches (:class:`BranchStarts`)."""

BRANCH_SAMPLES = 100
"""Random seeds per target whose IK solutions the branch chains are made of."""

PRUNE_RATIO = 2.0
"""A chain whose own E exceeds this multiple of the cheapest chain's is not solved.

Local solves from a feasible chain ended at 0.8-0.95 of its E (ur5, 4 and 6 targets):
a chain more than twice as long as the cheapest is not expected to end below it.
"""


def start_budget(problem: CyclicIKProblem) -> int:
    """Return the most starts an automatic multistart solves: ``2 s n`` within [16, 64]."""
    return int(min(64, max(16, 2 * problem.n_targets * problem.n_joints)))


AUTOMATIC_TIME_BUDGET = 20.0  # [s]
"""Wall time after which an automatic multistart begins no new start (the default).

The automatic starts of ur5 with 4 and 6 position targets reach their best paths in
about 4 s on 2 cores (IPOPT; the AL 11.7 s), so 20 s does not cut them, while 16
stalled starts of a target only the straight arm reaches no longer take a minute.
"""


def check_time_budget(time_budget: float) -> float:
    """Return ``time_budget`` in [s] as a float if it is positive and finite.

    Raises
    ------
    ParameterError
        Otherwise (``name="time_budget"``; the message names the value).
    """
    try:
        value = float(time_budget)
    except (TypeError, ValueError):
        value = math.nan
    if isinstance(time_budget, bool) or not (math.isfinite(value) and value > 0):
        raise ParameterError(
            f"time_budget must be a positive, finite time in [s], got {time_budget!r}",
            name="time_budget",
            value=time_budget,
        )
    return value


class BranchStarts(IndexedStarts):
    """Starts that find the best paths without being asked: witnesses and coherent branches.

    Start 0 is the usual one (planar: the zero vector; else the greedy DLS path);
    start 1 the reachability witnesses of the targets as one path (when every
    target has one; unwound along the cycle); then the cheapest cyclic chains of
    per-target IK solutions (:func:`target_samples`, :func:`branch_chains`), at
    most ``n_starts``, without those whose own ``E`` exceeds :data:`PRUNE_RATIO`
    times the cheapest chain's. Beyond them (an explicit larger ``n_starts``)
    the robot kind's random starts (planar ``feasible``, else ``mixed``) of the
    same seed. Deterministic in the problem and the seed; picklable.

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    n_starts : int or None
        Number of starts; ``None``: start 0, the witnesses and the chains kept,
        at most :func:`start_budget`.
    seed : int
        Seed of the IK samples and of the random starts beyond the chains.
    verdicts : sequence
        Reachability verdicts (planar or 3-D); their witnesses make start 1.
    planar : bool
        Whether start 0 and the random starts are the planar methods'.
    """

    def __init__(
        self,
        problem: CyclicIKProblem,
        n_starts: int | None,
        seed: int,
        *,
        verdicts: Sequence[object] = (),
        planar: bool = False,
    ) -> None:
        budget = start_budget(problem) if n_starts is None else int(n_starts)
        witnesses = [getattr(v, "witness", None) for v in verdicts]
        fixed: list[Array] = [
            problem.default_start() if planar else greedy_path(problem)[0].ravel()
        ]
        if len(witnesses) == problem.n_targets and all(w is not None for w in witnesses):
            fixed.append(_unwound(problem, np.array(witnesses, dtype=float)))
        rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(2**31,)))
        samples = []
        for j in range(problem.n_targets):
            found = target_samples(problem, j, BRANCH_SAMPLES, rng)
            w = witnesses[j] if j < len(witnesses) else None
            if w is not None:
                found = np.vstack([found, np.asarray(w, dtype=float)[None, :]])
            samples.append(found)
        chains = np.empty((0, problem.n_variables))
        self.chain_energies = np.empty(0)
        if all(len(c) for c in samples):
            chains, energies = branch_chains(problem, samples, max(budget - len(fixed), 0))
            keep = energies <= PRUNE_RATIO * float(np.min(energies, initial=np.inf))
            chains, self.chain_energies = chains[keep], energies[keep]
        self._fixed = np.array([*fixed, *chains]).reshape(-1, problem.n_variables)
        self._fixed = np.clip(self._fixed, problem.lower, problem.upper)
        self._n = (
            min(len(self._fixed), budget)
            if n_starts is None
            else check_start_request(n_starts, BRANCH_KIND, (BRANCH_KIND,))
        )
        self._rest: IndexedStarts = (
            PlanarStarts(problem, self._n, seed, kind="feasible", verdicts=verdicts)  # type: ignore[arg-type]
            if planar
            else Starts3D(problem, self._n, seed, kind="mixed")
        )

    def draw(self, j: int) -> Array:
        """Return start ``j``: a fixed start (0, witnesses, chains), else a random one [rad]."""
        return self._fixed[j].copy() if j < len(self._fixed) else self._rest[j]


def _unwound(problem: CyclicIKProblem, q: Array) -> Array:
    """Return the (s, n) path ``q`` with periodic joints unwound along the cycle, as (n s,)."""
    q = q.copy()
    for i in np.flatnonzero(periodic_joints(problem)):
        q[:, i] = _best_windings(q[:, i])
        lo, hi = problem.lower[i], problem.upper[i]
        mid = 0.5 * (lo + hi) if problem.use_limits and np.isfinite(lo + hi) else 0.0
        col_mid = 0.5 * (q[:, i].min() + q[:, i].max())
        q[:, i] += 2 * np.pi * np.round((mid - col_mid) / (2 * np.pi))
    return np.clip(q.ravel(), problem.lower, problem.upper)
