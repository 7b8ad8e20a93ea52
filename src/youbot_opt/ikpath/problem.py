r"""The cyclic IK-path problem of study 2 (spec ``ikpath.md``, "The problem").

Visit targets ``p_1 .. p_s`` in order and return to ``p_1`` with the least
total joint motion, :math:`E(Q) = \tfrac12 \sum_j \lVert q_{j+1} - q_j \rVert^2`
with :math:`q_{s+1} \equiv q_1`, subject to :math:`F(q_j) = p_j` and the joint
limits. :class:`CyclicIKProblem` is a pure specification: it evaluates E, the
constraints and their derivatives (from Pinocchio) but holds no solver state.

>>> chain = PlanarChain(lengths=[3, 2, 2])  # doctest: +SKIP
>>> problem = CyclicIKProblem(chain=chain, targets=[(-1, 5), (-3, 3), (3, 2)])  # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Protocol

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from youbot_opt._checks import check_shape
from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.planar import PlanarChain

__all__ = [
    "ALProblem",
    "CyclicIKProblem",
    "Evaluation",
    "path_configurations",
    "require_within_limits",
]


class Evaluation(NamedTuple):
    """Objective, constraints and their derivatives at one point.

    Attributes
    ----------
    objective : float
        ``E`` in [rad^2].
    gradient : ndarray, shape (s * n,)
        ``dE/dx`` in [rad].
    constraints : ndarray, shape (m * s,)
        ``c(x)`` stacked per target, in [m] (planar: ``F(q_j) - p_j``, ``m = 2``;
        spatial problems: ``m`` rows per target, see :mod:`youbot_opt.ikpath.spatial`).
    jacobian_blocks : ndarray, shape (s, m, n)
        ``dc_j/dq_j`` in [m/rad]; ``dc/dx`` is block diagonal with these blocks.
    """

    objective: float
    gradient: Array
    constraints: Array
    jacobian_blocks: Array


class ALProblem(Protocol):
    """What the augmented Lagrangian needs of a problem (planar and spatial alike).

    ``s`` targets, ``n`` joints, ``m`` constraint rows per target; ``x`` is the
    row-major flattening of the (s, n) configurations in [rad].
    """

    @property
    def n_targets(self) -> int:
        """Number of targets ``s``."""
        ...

    @property
    def n_constraints(self) -> int:
        """Number of constraint rows ``m s``."""
        ...

    @property
    def lower(self) -> Array:
        """Lower bounds of ``x`` in [rad]."""
        ...

    @property
    def upper(self) -> Array:
        """Upper bounds of ``x`` in [rad]."""
        ...

    @property
    def bounded(self) -> bool:
        """Whether finite bounds are constraints."""
        ...

    def create_data(self) -> pin.Data:
        """Return a fresh ``pinocchio.Data``."""
        ...

    def evaluate(self, x: ArrayLike, data: pin.Data | None = None) -> Evaluation:
        """Objective, constraints and their derivatives at ``x``."""
        ...

    def objective(self, x: ArrayLike) -> float:
        """``E`` at ``x`` in [rad^2]."""
        ...

    def constraints(self, x: ArrayLike, data: pin.Data | None = None) -> Array:
        """Constraint rows ``c(x)``."""
        ...


def require_within_limits(
    x: Array, lower: Array, upper: Array, joint_labels: list[str], unit: str = ""
) -> None:
    """Raise ParameterError naming the first entry of the start ``x`` outside its limits.

    Parameters
    ----------
    x : ndarray, shape (n s,)
        A start, configuration-major.
    lower, upper : ndarray, shape (n s,)
        The limits in [rad] (or [m] for prismatic joints).
    joint_labels : list of str
        How each of the ``n`` joints is named in the message.
    unit : str
        Unit appended to the quoted numbers (``" rad"`` or ``""``).
    """
    bad = np.flatnonzero((x < lower) | (x > upper))
    if bad.size:
        k = int(bad[0])
        j, i = divmod(k, len(joint_labels))
        raise ParameterError(
            f"the start x0 violates the joint limits: configuration {j}, joint "
            f"{joint_labels[i]} is {x[k]:.6g}{unit}, expected within "
            f"[{lower[k]:.6g}, {upper[k]:.6g}]{unit}",
            name="x0",
            value=x[k],
        )


def path_configurations(x: ArrayLike, n_targets: int, n_joints: int, name: str = "x") -> Array:
    """Return a path ``x`` (shape (n s,) or (s, n)) as a finite (s, n) array in [rad].

    Parameters
    ----------
    x : array_like, shape (n s,) or (s, n)
        Joint angles of the ``s`` path points in [rad].
    n_targets : int
        Number ``s`` of path points (targets).
    n_joints : int
        Number ``n`` of joints (active angles) per point.
    name : str, optional
        Name of ``x`` in error messages.

    Raises
    ------
    ParameterError
        If the size is not ``n s`` or an entry is not finite.
    """
    arr = np.array(x, dtype=float)
    if arr.size != n_targets * n_joints or arr.ndim not in (1, 2):
        raise ParameterError(
            f"{name} must have shape ({n_targets * n_joints},) or "
            f"({n_targets}, {n_joints}), got {arr.shape}",
            name=name,
            value=arr.shape,
        )
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must be finite", name=name, value=arr)
    return arr.reshape(n_targets, n_joints)


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class CyclicIKProblem:
    r"""Minimum-motion cyclic joint path through tip targets.

    .. math::

        \min_{Q} \; E(Q) = \tfrac12 \sum_{j=1}^{s} \lVert q_{j+1} - q_j \rVert^2,
        \quad q_{s+1} \equiv q_1, \qquad
        \text{s.t.}\; F(q_j) = p_j,\; \ell \le q_j \le u \;(j = 1..s).

    ``Q`` is the ``(s, n)`` array of configurations; solvers work on its
    row-major flattening ``x = Q.ravel()`` (``n s`` unknowns) and the ``2 s``
    equality constraints ``c(x) = (F(q_1) - p_1, ..., F(q_s) - p_s)``
    (``F`` and ``dF/dq`` from Pinocchio).

    Attributes
    ----------
    chain : PlanarChain
        The arm (its ``q_lower``/``q_upper`` are the joint limits).
    targets : ndarray, shape (s, 2)
        Tip targets in [m], visited in order and cyclically; ``s >= 2``.
    use_limits : bool
        Whether the chain's joint limits are constraints of the problem.
    """

    chain: PlanarChain
    targets: Array
    use_limits: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.chain, PlanarChain):
            raise ParameterError(
                f"chain must be a PlanarChain, got {type(self.chain).__name__}",
                name="chain",
                value=self.chain,
            )
        targets = check_shape(self.targets, ("s", 2), "targets")
        if targets.shape[0] < 2:
            raise ParameterError(
                f"a cyclic path needs at least 2 targets, got {targets.shape[0]}",
                name="targets",
                value=targets.shape[0],
            )
        targets.setflags(write=False)
        object.__setattr__(self, "targets", targets)
        object.__setattr__(self, "use_limits", bool(self.use_limits))

    @property
    def n_targets(self) -> int:
        """Number of targets ``s``."""
        return int(self.targets.shape[0])

    @property
    def n_joints(self) -> int:
        """Number of joints ``n``."""
        return self.chain.n

    @property
    def n_variables(self) -> int:
        """Number of unknowns ``n s``."""
        return self.n_targets * self.n_joints

    @property
    def n_constraints(self) -> int:
        """Number of equality constraints ``2 s``."""
        return 2 * self.n_targets

    def create_data(self) -> pin.Data:
        """Return a fresh ``pinocchio.Data`` of the chain."""
        return self.chain.create_data()

    @property
    def bounded(self) -> bool:
        """Whether finite joint limits are constraints of this problem."""
        return self.use_limits and self.chain.bounded

    @property
    def lower(self) -> Array:
        """Lower bound on ``x`` in [rad], shape (n s,); -inf where unlimited."""
        if not self.use_limits:
            return np.full(self.n_variables, -np.inf)
        return np.tile(self.chain.q_lower, self.n_targets)

    @property
    def upper(self) -> Array:
        """Upper bound on ``x`` in [rad], shape (n s,); +inf where unlimited."""
        if not self.use_limits:
            return np.full(self.n_variables, np.inf)
        return np.tile(self.chain.q_upper, self.n_targets)

    def as_configurations(self, x: ArrayLike, name: str = "x") -> Array:
        """Return ``x`` as a finite (s, n) array in [rad] (:func:`path_configurations`)."""
        return path_configurations(x, self.n_targets, self.n_joints, name)

    def objective(self, x: ArrayLike) -> float:
        """``E = 1/2 sum_j |q_{j+1} - q_j|^2`` (cyclic) in [rad^2]."""
        q = self.as_configurations(x)
        return 0.5 * float(np.sum((np.roll(q, -1, axis=0) - q) ** 2))

    def objective_gradient(self, x: ArrayLike) -> Array:
        """``dE/dx`` in [rad], shape (n s,): ``2 q_j - q_{j-1} - q_{j+1}`` per block."""
        q = self.as_configurations(x)
        return (2.0 * q - np.roll(q, 1, axis=0) - np.roll(q, -1, axis=0)).ravel()

    def tip_positions(self, x: ArrayLike, data: pin.Data | None = None) -> Array:
        """Tip positions ``F(q_j)`` in [m], shape (s, 2), by Pinocchio."""
        q = self.as_configurations(x)
        data = self.chain.create_data() if data is None else data
        return np.array([self.chain.tip_position(qj, data) for qj in q])

    def constraints(self, x: ArrayLike, data: pin.Data | None = None) -> Array:
        """``c(x) = F(q_j) - p_j`` stacked, shape (2 s,), in [m]."""
        return (self.tip_positions(x, data) - self.targets).ravel()

    def residuals(self, x: ArrayLike, data: pin.Data | None = None) -> Array:
        """Per-target residual ``|F(q_j) - p_j|`` in [m], shape (s,)."""
        return np.linalg.norm(self.tip_positions(x, data) - self.targets, axis=1)

    def limit_violation(self, x: ArrayLike) -> float:
        """Largest joint-limit violation in [rad] (0 when within limits or unlimited)."""
        xv = self.as_configurations(x).ravel()
        over = np.maximum(self.lower - xv, xv - self.upper)
        return float(max(0.0, np.max(over)))

    def evaluate(self, x: ArrayLike, data: pin.Data | None = None) -> Evaluation:
        """Objective, gradient, constraints and constraint Jacobian blocks at ``x``."""
        q = self.as_configurations(x)
        data = self.chain.create_data() if data is None else data
        s, n = q.shape
        c = np.empty((s, 2))
        blocks = np.empty((s, 2, n))
        model, fid = self.chain.model, self.chain.tip_frame_id
        frame = pin.LOCAL_WORLD_ALIGNED
        for j in range(s):  # hot loop: Pinocchio directly (q[j] is validated above)
            jac = pin.computeFrameJacobian(model, data, q[j], fid, frame)
            blocks[j] = np.reshape(jac, (6, n))[:2]  # a 1-joint model returns shape (6,)
            c[j] = data.oMf[fid].translation[:2] - self.targets[j]
        nxt = q[np.r_[1:s, 0]]
        prv = q[np.r_[s - 1, 0 : s - 1]]
        diff = nxt - q
        grad = (2.0 * q - prv - nxt).ravel()
        return Evaluation(0.5 * float(np.sum(diff * diff)), grad, c.ravel(), blocks)

    def default_start(self) -> Array:
        """Return the study's start: the zero vector clipped into the limits, shape (n s,)."""
        return np.clip(np.zeros(self.n_variables), self.lower, self.upper)

    def check_start(self, x0: ArrayLike | None) -> Array:
        """Validate an initial guess (``None`` = :meth:`default_start`), shape (n s,).

        Raises
        ------
        ParameterError
            If ``x0`` has the wrong size, is not finite, or lies outside the limits.
        """
        if x0 is None:
            return self.default_start()
        x = self.as_configurations(x0, name="x0").ravel().copy()
        labels = [str(i) for i in range(self.n_joints)]
        require_within_limits(x, self.lower, self.upper, labels, unit=" rad")
        return x
