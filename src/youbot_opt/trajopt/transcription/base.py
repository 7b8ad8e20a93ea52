"""Transcription protocol: how a :class:`TrajOptProblem` becomes a CasADi NLP.

A transcription is a strategy object (:class:`Transcription`): it turns the
plain problem spec plus the robot's CasADi forward dynamics into a
:class:`TranscribedNLP` -- decision vector ``x``, parameter ``p = (beta,)``,
objective ``f`` and constraint vector ``g`` -- together with the named layout
of ``x`` and ``g`` (:class:`Layout`, :class:`Block`) so that solutions and
multipliers can be read back by name and knot. The conventions every
transcription shares (block shapes, where boundary states, bounds and
``beta`` enter): :class:`Transcription`; why: docs/design.md, "Module notes".
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, ClassVar, Generic, NamedTuple, TypeVar

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError, TranscriptionError
from youbot_opt.trajopt.objectives import duration, objective_value
from youbot_opt.trajopt.quadrature import QuadratureRule, grid_weights, quadrature_weights
from youbot_opt.trajopt.trajectory import Interpolation, Trajectory
from youbot_opt.trajopt.transcription.path import PathConstraint, PathRamp

if TYPE_CHECKING:
    from youbot_opt.trajopt.problem import BoundaryState, JointBounds, TrajOptProblem

__all__ = [
    "Block",
    "Layout",
    "TranscribedNLP",
    "Transcription",
    "Expressions",
    "BOUND_NAMES",
    "variable_family",
    "check_fractions",
    "grid_edges",
    "grid_times",
    "step_ratios",
]

_E = TypeVar("_E", ca.SX, ca.MX)  # a CasADi expression: the transcriptions work with both

BOUND_NAMES: dict[str, str] = {
    "q": "position",
    "v": "velocity",
    "tau": "torque",
    "q_mid": "position_mid",
    "v_mid": "velocity_mid",
    "tau_mid": "torque_mid",
    "q_stage1": "position_stage1",
    "v_stage1": "velocity_stage1",
    "tau_stage1": "torque_stage1",
    "q_stage2": "position_stage2",
    "v_stage2": "velocity_stage2",
    "tau_stage2": "torque_stage2",
    "dt": "dt",
}
"""Variable block -> name of its bound family in the multiplier dictionary."""


def variable_family(block: str) -> str:
    """Return the joint quantity a variable block holds: ``"q"``, ``"v"``, ``"tau"``, ``"dt"``.

    ``q_mid`` and ``q_stage1`` are positions, ``tau_stage2`` torques, and so on:
    a block is bounded by its family's joint bounds.
    """
    return block.split("_")[0]


@dataclass(frozen=True, slots=True)
class Block:
    """A named slice of a stacked vector holding ``count`` columns of ``width`` rows."""

    name: str
    offset: int
    width: int
    count: int

    @property
    def size(self) -> int:
        """Number of scalars in the block."""
        return self.width * self.count

    def take(self, vector: Array) -> Array:
        """Return the block of ``vector`` as a knot-major array ``(count, width)`` (a copy)."""
        return np.array(vector[self.offset : self.offset + self.size], dtype=float).reshape(
            self.count, self.width
        )


class Layout:
    """Ordered named blocks of a stacked vector (``x`` or ``g``)."""

    def __init__(self, blocks: list[tuple[str, int, int]]) -> None:
        self.blocks: dict[str, Block] = {}
        offset = 0
        for name, width, count in blocks:
            self.blocks[name] = Block(name, offset, width, count)
            offset += width * count
        self.size = offset

    def __getitem__(self, name: str) -> Block:
        return self.blocks[name]

    def __contains__(self, name: object) -> bool:
        return name in self.blocks

    def unpack(self, vector: Array) -> dict[str, Array]:
        """Every block of ``vector`` as knot-major arrays, by name."""
        vector = np.asarray(vector, dtype=float).ravel()
        if vector.size != self.size:
            raise TranscriptionError(f"vector has {vector.size} entries, layout has {self.size}")
        return {name: block.take(vector) for name, block in self.blocks.items()}

    def pack(self, values: dict[str, Array]) -> Array:
        """Stack knot-major arrays (broadcast to each block's shape) into one vector."""
        out = np.empty(self.size)
        for name, block in self.blocks.items():
            arr = np.broadcast_to(np.asarray(values[name], dtype=float), (block.count, block.width))
            out[block.offset : block.offset + block.size] = arr.ravel()
        return out


@dataclass(frozen=True, slots=True, kw_only=True)
class TranscribedNLP:
    """The NLP of one problem under one transcription (symbolic, not yet solved).

    Attributes
    ----------
    method : str
        Transcription name (``"trapezoidal"``, ``"hermite_simpson"``).
    interpolation : str
        :class:`~youbot_opt.trajopt.trajectory.Trajectory` interpolation of its solutions.
    rule : str
        Quadrature rule of the work term.
    n_knots, nv : int
        Number of knots and of joints.
    x, p, f, g : casadi.MX
        Decision vector, parameter ``(beta,)``, objective and constraints.
    duration, work : casadi.MX
        The objective's terms ``T`` [s] and ``W`` [N^2 m^2 s] as expressions of ``x``.
    variables, constraints : Layout
        Named blocks of ``x`` and ``g``.
    path_bounds : mapping of str to str
        Inequality blocks of ``g`` -> the variable family (``"q"``, ``"v"`` or
        ``"tau"``) whose bounds they must stay within; every other block of
        ``g`` is an equality.
    unbounded : tuple of str
        Variable blocks given no bounds of their own in :meth:`variable_bounds`
        because the path blocks imply them (Hermite-Simpson's ``v_mid``).
    path_limits : mapping of str to (ndarray, ndarray)
        Inequality blocks of ``g`` from :class:`PathConstraint` s (``clearance_knots``,
        ``clearance_midpoints``, ...) -> their ``(lower, upper)`` row bounds, shape
        ``(width,)`` each; empty without path constraints.
    path_ramps : mapping of str to PathRamp
        Path-constraint blocks whose lower bounds ramp from their values at the
        fixed ends (:attr:`PathConstraint.end_window` > 0) -> how
        (:meth:`constraint_bounds` sets them from the start and goal).
    """

    method: str
    interpolation: Interpolation
    rule: QuadratureRule
    n_knots: int
    nv: int
    x: ca.MX
    p: ca.MX
    f: ca.MX
    g: ca.MX
    duration: ca.MX
    work: ca.MX
    variables: Layout
    constraints: Layout
    path_bounds: Mapping[str, str] = field(default_factory=dict)
    unbounded: tuple[str, ...] = ()
    path_limits: Mapping[str, tuple[Array, Array]] = field(default_factory=dict)
    path_ramps: Mapping[str, PathRamp] = field(default_factory=dict)

    @property
    def n_variables(self) -> int:
        """Number of decision variables."""
        return self.variables.size

    @property
    def n_constraints(self) -> int:
        """Number of constraint rows of ``g`` (equalities and path inequalities)."""
        return self.constraints.size

    @property
    def n_inequalities(self) -> int:
        """Number of path-inequality rows of ``g`` (zero for trapezoidal collocation)."""
        names = [*self.path_bounds, *self.path_limits]
        return sum(self.constraints[name].size for name in names)

    @property
    def n_equalities(self) -> int:
        """Number of equality rows of ``g`` (defects and boundary conditions)."""
        return self.n_constraints - self.n_inequalities

    def variable_bounds(
        self, bounds: JointBounds, dt_range: tuple[float, float]
    ) -> tuple[Array, Array]:
        """``(lbx, ubx)`` from joint bounds and the time-step range ``dt_range`` in [s]."""
        lower = {"q": bounds.q_lower, "v": bounds.v_lower, "tau": bounds.tau_lower}
        upper = {"q": bounds.q_upper, "v": bounds.v_upper, "tau": bounds.tau_upper}
        lo: dict[str, Any] = {"dt": dt_range[0]}
        hi: dict[str, Any] = {"dt": dt_range[1]}
        for name in self.variables.blocks:
            if name in self.unbounded:
                lo[name], hi[name] = -np.inf, np.inf
            elif name != "dt":
                family = variable_family(name)
                lo[name], hi[name] = lower[family], upper[family]
        return self.variables.pack(lo), self.variables.pack(hi)

    def constraint_bounds(
        self, start: BoundaryState, goal: BoundaryState, bounds: JointBounds | None = None
    ) -> tuple[Array, Array]:
        """``(lbg, ubg)``: zero defects, the boundary states and the path bounds.

        Parameters
        ----------
        start, goal : BoundaryState
            Boundary states (equalities).
        bounds : JointBounds, optional
            Scaled joint bounds for the path blocks; required when the
            transcription has any (:attr:`path_bounds`).

        Raises
        ------
        TranscriptionError
            If the NLP has path blocks and ``bounds`` is missing.
        """
        values: dict[str, Any] = {name: 0.0 for name in self.constraints.blocks}
        values["start_position"] = start.q
        values["start_velocity"] = start.velocity
        values["goal_position"] = goal.q
        values["goal_velocity"] = goal.velocity
        upper = dict(values)
        for name, (lower_row, upper_row) in self.path_limits.items():
            values[name], upper[name] = lower_row, upper_row
        ends: dict[int, tuple[Array, Array]] = {}  # rows' values at the ends, by Function
        for name, ramp in self.path_ramps.items():
            key = id(ramp.function)
            if key not in ends:
                ends[key] = (
                    np.asarray(ramp.function(start.q, start.velocity), dtype=float).ravel(),
                    np.asarray(ramp.function(goal.q, goal.velocity), dtype=float).ravel(),
                )
            values[name] = ramp.lower(self.path_limits[name][0], *ends[key])
        if not self.path_bounds:
            return self.constraints.pack(values), self.constraints.pack(upper)
        if bounds is None:
            raise TranscriptionError(
                f"the {self.method} NLP has path constraints {sorted(self.path_bounds)}: "
                "constraint_bounds needs the joint bounds (bounds=problem.bounds(scale))"
            )
        for name, family in self.path_bounds.items():
            values[name] = getattr(bounds, f"{family}_lower")
            upper[name] = getattr(bounds, f"{family}_upper")
        return self.constraints.pack(values), self.constraints.pack(upper)


class Transcription(ABC):
    """Strategy turning a :class:`TrajOptProblem` into a :class:`TranscribedNLP`.

    Conventions (shared by every transcription):

    * Every variable block is a CasADi matrix of shape ``(nv, count)``, one column
      per knot (or interval); ``x`` stacks the blocks' columns, so the numpy view
      of a block is knot-major ``(count, nv)``.
    * Boundary conditions are equality rows of ``g`` (blocks ``start_position``,
      ``start_velocity``, ``goal_position``, ``goal_velocity``) whose values enter
      only through ``lbg = ubg``: a new start or goal needs no rebuild.
    * Joint bounds enter only through ``lbx``/``ubx`` -- and, for a scheme whose
      interpolant can leave the bounds between knots, through the ``lbg``/``ubg``
      of its *path* blocks (inequality rows of ``g`` held within a bound family,
      :meth:`path_constraints`) -- the time weight only through ``p``: bound
      scaling and ``beta`` sweeps reuse one NLP.
    * The forward dynamics is evaluated by the per-knot Function mapped over the
      knots (``F.map(N)``).

    Parameters
    ----------
    fractions : array_like, optional
        The grid: interval ``k`` lasts ``fractions[k] * T`` of the free (or
        fixed) duration ``T``; ``N - 1`` positive numbers summing to 1
        (normalised here). ``None`` (default) is the uniform grid, whose NLP is
        the original one expression for expression. The decision variable
        ``dt`` is the *mean* step ``T / (N - 1)`` on any grid, interval ``k``
        lasting ``r_k dt`` with the step ratios ``r = (N - 1) fractions``.
    """

    name: ClassVar[str]
    interpolation: ClassVar[Interpolation]
    rule: ClassVar[QuadratureRule]
    unbounded: ClassVar[tuple[str, ...]] = ()
    """Variable blocks without bounds of their own (implied by path constraints)."""
    interior_points: ClassVar[Mapping[str, float]] = MappingProxyType({})
    """Path-point groups other than ``"knots"`` (:meth:`path_points`) -> where in
    each interval they lie, as a fraction of its length (one column an interval)."""
    mumps_pivot_order: ClassVar[int] = 0
    """MUMPS's fill-reducing ordering of this scheme's KKT matrices when
    :attr:`~youbot_opt.nlp.ipopt.IpoptOptions.fast_kkt` is on and MUMPS solves
    them (IPOPT's ``mumps_pivot_order``: 0 AMD, :data:`~youbot_opt.nlp.ipopt.FAST_KKT`'s;
    2 AMF). ``IpoptOptions.extra`` overrides it; docs/design.md has the measurements."""
    fractions: Array | None = None
    """The grid's interval fractions (``None``: uniform; also for subclasses that
    define their own ``__init__``)."""

    def __init__(self, fractions: ArrayLike | None = None) -> None:
        self.fractions: Array | None = None if fractions is None else check_fractions(fractions)

    def __repr__(self) -> str:
        if self.fractions is None:
            return f"{type(self).__name__}()"
        return f"{type(self).__name__}(fractions=<{self.fractions.size} intervals>)"

    @property
    def uniform(self) -> bool:
        """Whether the grid is uniform (no ``fractions`` given)."""
        return self.fractions is None

    def with_fractions(self, fractions: ArrayLike | None) -> Transcription:
        """Return the same scheme on another grid (``None``: uniform)."""
        return type(self)(fractions)

    def ratios(self, n_knots: int) -> Array:
        """Step ratios ``r_k = h_k / mean(h)``, shape ``(n_knots - 1,)`` (ones if uniform)."""
        return step_ratios(self.fractions, n_knots)

    def steps(self, dt: _E, n_knots: int) -> _E:
        """Interval steps ``h_k = r_k dt`` as a ``1 x (N - 1)`` row (``dt`` itself if uniform)."""
        if self.fractions is None:
            return dt
        return dt * ca.DM(self.ratios(n_knots)).T

    def per_interval(self, expr: _E, dt: _E) -> _E:
        """``expr`` (``nv x (N - 1)``) with column ``k`` times ``h_k = r_k dt``."""
        if self.fractions is None:
            return dt * expr
        return dt * ca.mtimes(expr, ca.diag(ca.DM(self.ratios(expr.size2() + 1))))

    def knot_times(self, guess: Trajectory, n_knots: int) -> tuple[float, Array]:
        """Mean step [s] and the ``n_knots`` grid times spanning ``guess``."""
        if self.fractions is None:
            return uniform_times(guess, n_knots)
        self.ratios(n_knots)  # checks the size
        return grid_times(guess, self.fractions)

    def solution_times(self, dt: float, n_knots: int) -> Array:
        """Knot times [s] of a solution with mean step ``dt`` [s], starting at 0."""
        if self.fractions is None:
            return np.arange(n_knots, dtype=np.float64) * np.float64(dt)
        return np.concatenate(([0.0], np.cumsum(dt * self.ratios(n_knots))))

    def point_times(self, n_knots: int) -> dict[str, Array]:
        """Normalised times in [0, 1] of each :meth:`path_points` group's columns.

        Knot ``k`` at ``sum(fractions[:k])`` (``k / (N - 1)`` on the uniform
        grid), an interior group at :attr:`interior_points` of each interval.
        """
        if self.fractions is None:
            edges = np.linspace(0.0, 1.0, n_knots)
        else:
            self.check_size(n_knots)
            edges = grid_edges(self.fractions)
        left, length = edges[:-1], np.diff(edges)
        times = {"knots": edges}
        times.update({g: left + c * length for g, c in self.interior_points.items()})
        return times

    def check_size(self, n_knots: int) -> None:
        """Raise :class:`TranscriptionError` unless the grid has ``n_knots - 1`` intervals."""
        if self.fractions is not None and self.fractions.size != n_knots - 1:
            raise TranscriptionError(
                f"the grid has {self.fractions.size} intervals but the problem has "
                f"{n_knots} knots ({n_knots - 1} intervals)"
            )

    @abstractmethod
    def variable_blocks(self, nv: int, n_knots: int) -> list[tuple[str, int, int]]:
        """Layout of ``x``: ``(name, width, count)`` per block, ``dt`` last."""

    @abstractmethod
    def dynamics_points(self, sym: dict[str, _E]) -> dict[str, tuple[_E, _E, _E]]:
        """Where the dynamics is evaluated: group name -> ``(q, v, tau)``, each ``(nv, count)``.

        The keys name the accelerations passed to :meth:`collocation`.
        """

    @abstractmethod
    def collocation(self, sym: dict[str, _E], accel: dict[str, _E]) -> list[tuple[str, _E]]:
        """Defect blocks ``(name, expression of shape (nv, count))``.

        Parameters
        ----------
        sym : dict
            Variable blocks by name (CasADi matrices ``(nv, count)``; ``dt`` is 1x1).
        accel : dict
            Accelerations ``(nv, count)`` at each group of :meth:`dynamics_points`;
            the defects must be affine in them (they are, for collocation).
        """

    def path_constraints(
        self, sym: dict[str, _E], accel: dict[str, _E]
    ) -> list[tuple[str, str, _E]]:
        """Inequality blocks that keep the interpolant within the joint bounds between knots.

        Returns
        -------
        list of (name, family, expression)
            Block name, the variable family (``"q"``, ``"v"`` or ``"tau"``) whose
            bounds apply, and an expression of shape ``(nv, count)``, affine in
            ``accel`` like the defects. None by default.
        """
        return []

    @abstractmethod
    def knot_guess(self, guess: Trajectory, n_knots: int) -> dict[str, Array]:
        """Return initial values of every variable block from a guess trajectory."""

    def trajectory(
        self,
        values: dict[str, Array],
        a: Array,
        accel: Callable[[Array, Array, Array], Array] | None = None,
    ) -> Trajectory:
        """Solution trajectory from unpacked variables and knot accelerations ``a``.

        Knots at :meth:`solution_times` of the mean step ``values["dt"]`` [s];
        ``values["tau_mid"]`` [N m] where the method has midpoint torques.
        ``accel(q, v, tau)`` (knot-major arrays -> accelerations [rad/s^2])
        serves methods that need accelerations at other points (Radau's stages).
        """
        dt = float(values["dt"].ravel()[0])
        n = values["q"].shape[0]
        return Trajectory(
            t=self.solution_times(dt, n),
            q=values["q"],
            v=values["v"],
            a=a,
            tau=values["tau"],
            tau_mid=values.get("tau_mid"),
            interpolation=self.interpolation,
        )

    def path_points(self, sym: dict[str, _E]) -> dict[str, tuple[_E, _E]]:
        """Where path constraints are evaluated: group name -> ``(q, v)``, each ``(nv, count)``.

        The dynamics points (knots, Hermite-Simpson's midpoints, Radau's stages)
        by default.
        """
        return {group: (q, v) for group, (q, v, _) in self.dynamics_points(sym).items()}

    def build(
        self,
        problem: TrajOptProblem,
        forward_dynamics: ca.Function,
        paths: tuple[PathConstraint, ...] = (),
    ) -> TranscribedNLP:
        """Transcribe ``problem`` with the per-knot dynamics ``forward_dynamics``.

        Parameters
        ----------
        problem : TrajOptProblem
            The problem spec.
        forward_dynamics : casadi.Function
            ``(q[nv], v[nv], tau[nv]) -> a[nv]`` in [rad/s^2].
        paths : tuple of PathConstraint
            Path constraints held at every :meth:`path_points` group (none by
            default: the NLP of a problem without them).

        Returns
        -------
        TranscribedNLP
            The symbolic NLP and its layouts.

        Raises
        ------
        TranscriptionError
            If the dynamics Function does not match the robot's size.
        """
        nv, n = problem.nv, problem.n_knots
        self.check_size(n)
        if forward_dynamics.n_in() != 3 or any(
            forward_dynamics.size1_in(i) != nv for i in range(3)
        ):
            raise TranscriptionError(
                f"forward dynamics must map (q[{nv}], v[{nv}], tau[{nv}]) -> a[{nv}], got "
                f"{forward_dynamics}"
            )
        blocks = self.variable_blocks(nv, n)
        sym = {name: ca.MX.sym(name, width, count) for name, width, count in blocks}
        x = ca.vertcat(*[ca.vec(sym[name]) for name, _, _ in blocks])
        accel = {
            group: forward_dynamics.map(q.size2())(q, v, tau)
            for group, (q, v, tau) in self.dynamics_points(sym).items()
        }
        beta = ca.MX.sym("beta")
        parts = self.expressions(problem, sym, accel, beta, paths)
        return TranscribedNLP(
            method=self.name,
            interpolation=self.interpolation,
            rule=self.rule,
            n_knots=n,
            nv=nv,
            x=x,
            p=beta,
            f=parts.f,
            g=parts.g,
            duration=parts.duration,
            work=parts.work,
            variables=Layout(blocks),
            constraints=parts.constraints,
            path_bounds=dict(parts.path_bounds),
            unbounded=tuple(self.unbounded),
            path_limits=dict(parts.path_limits),
            path_ramps=self.path_ramps(n, paths),
        )

    def path_ramps(self, n_knots: int, paths: tuple[PathConstraint, ...]) -> dict[str, PathRamp]:
        """Return the :class:`PathRamp` of each block of a path constraint with an end window."""
        ramps: dict[str, PathRamp] = {}
        times = self.point_times(n_knots) if any(c.end_window > 0 for c in paths) else {}
        for constraint in paths:
            if constraint.end_window > 0:
                for group, s in times.items():
                    ramps[f"{constraint.name}_{group}"] = PathRamp(
                        function=constraint.function, window=constraint.end_window, times=s
                    )
        return ramps

    def expressions(
        self,
        problem: TrajOptProblem,
        sym: dict[str, _E],
        accel: dict[str, _E],
        beta: _E,
        paths: tuple[PathConstraint, ...] = (),
        path_values: Mapping[str, _E] | None = None,
    ) -> Expressions[_E]:
        """Objective, constraints and their terms from variables and accelerations.

        Works with SX and MX alike; :meth:`build` passes the mapped dynamics as
        ``accel``, :mod:`youbot_opt.trajopt.transcription.derivatives` passes free symbols,
        and as ``path_values`` free symbols for path-constraint blocks (``<name>_<group>``
        -> ``(m, count)``) it evaluates itself; the other blocks evaluate ``paths``.
        """
        n = problem.n_knots
        q, v = sym["q"], sym["v"]
        defects = self.collocation(sym, accel)
        boundary = [
            ("start_position", q[:, 0]),
            ("start_velocity", v[:, 0]),
            ("goal_position", q[:, n - 1]),
            ("goal_velocity", v[:, n - 1]),
        ]
        path = self.path_constraints(sym, accel)
        g_blocks = defects + boundary + [(name, expr) for name, _, expr in path]
        limits: dict[str, tuple[Array, Array]] = {}
        points = self.path_points(sym) if paths else {}
        for constraint in paths:
            for group, (qp, vp) in points.items():
                name = f"{constraint.name}_{group}"
                if path_values is not None and name in path_values:
                    g_blocks.append((name, path_values[name]))
                else:
                    g_blocks.append((name, constraint.evaluate(qp, vp)))
                limits[name] = (constraint.lower, constraint.upper)
        g = ca.vertcat(*[ca.vec(expr) for _, expr in g_blocks])
        constraints = Layout([(name, expr.size1(), expr.size2()) for name, expr in g_blocks])
        total_time, work = self.time_and_work(sym, n)
        f = objective_value(total_time, work, beta)
        return Expressions(
            f=f,
            g=g,
            duration=total_time,
            work=work,
            constraints=constraints,
            path_bounds={name: family for name, family, _ in path},
            path_limits=limits,
        )

    def time_and_work(self, sym: dict[str, _E], n_knots: int) -> tuple[_E, _E]:
        """Return the objective's terms ``(T, W)`` in [s] and [N^2 m^2 s] from the variables.

        ``T = (N - 1) dt`` and ``W = dt sum_blocks w . (tau . tau)``
        (:meth:`work_weights`); a scheme with one step per segment
        (:mod:`youbot_opt.trajopt.timed`) sums its segments instead.
        """
        dt = sym["dt"]
        terms = [
            ca.mtimes(ca.sum1(sym[name] ** 2), ca.DM(w)) for name, w in self.work_weights(n_knots)
        ]
        work = terms[0]
        for term in terms[1:]:
            work += term
        work = dt * work
        return duration(dt, n_knots), work

    def work_weights(self, n_knots: int) -> list[tuple[str, Array]]:
        """Torque blocks and their weights: ``W = dt sum_blocks w . (tau . tau)`` per column.

        From :meth:`quadrature`: the knot torques and, where the method has
        them, the mid-interval ones (Simpson).
        """
        w_knots, w_mid = self.quadrature(n_knots)
        return [("tau", w_knots)] + ([] if w_mid is None else [("tau_mid", w_mid)])

    def quadrature(self, n_knots: int) -> tuple[Array, Array | None]:
        """Work weights ``(w_knots, w_mid)`` with ``W = dt (w_knots . p + w_mid . p_mid)``.

        The uniform grid uses :func:`~youbot_opt.trajopt.quadrature.quadrature_weights`;
        another grid weights each interval by its step ratio ``r_k``.
        """
        if self.fractions is None:
            return quadrature_weights(self.rule, n_knots)
        return grid_weights(self.rule, self.ratios(n_knots))


def check_fractions(fractions: ArrayLike) -> Array:
    """Validate a grid: positive finite interval fractions, normalised to sum 1.

    Raises
    ------
    ParameterError
        If ``fractions`` is not a 1-D array of at least one positive finite number.
    """
    arr = np.array(fractions, dtype=float).ravel()
    if arr.size < 1 or not np.all(np.isfinite(arr)) or not np.all(arr > 0.0):
        raise ParameterError(
            "fractions must be one or more finite numbers > 0 (each interval's share of T), "
            f"got {np.array2string(arr, threshold=8)}",
            name="fractions",
        )
    arr = arr / arr.sum()
    arr.setflags(write=False)
    return arr


def step_ratios(fractions: Array | None, n_knots: int) -> Array:
    """Step ratios ``r = (N - 1) fractions`` (ones for the uniform grid ``None``)."""
    if fractions is None:
        return np.ones(n_knots - 1)
    if fractions.size != n_knots - 1:
        raise TranscriptionError(
            f"the grid has {fractions.size} intervals but there are {n_knots} knots"
        )
    return (n_knots - 1) * np.asarray(fractions, dtype=float)


def grid_times(guess: Trajectory, fractions: Array) -> tuple[float, Array]:
    """Mean step [s] and the grid times ``t_0 + T * cumsum(fractions)`` spanning ``guess``."""
    total = guess.duration
    if not math.isfinite(total) or total <= 0.0:
        raise TranscriptionError(f"guess duration must be > 0 [s], got {total}")
    return total / fractions.size, guess.t[0] + total * grid_edges(fractions)


def grid_edges(fractions: Array) -> Array:
    """Knots of a grid in normalised time: ``0, cumsum(fractions)``, the last exactly 1."""
    edges = np.concatenate(([0.0], np.cumsum(fractions)))
    edges[-1] = 1.0
    return edges


class Expressions(NamedTuple, Generic[_E]):
    """Symbolic pieces of a transcription (:meth:`Transcription.expressions`): all SX or all MX."""

    f: _E
    g: _E
    duration: _E
    work: _E
    constraints: Layout
    path_bounds: Mapping[str, str] = MappingProxyType({})
    """Inequality blocks of ``g`` -> bound family (see :attr:`TranscribedNLP.path_bounds`)."""
    path_limits: Mapping[str, tuple[Array, Array]] = MappingProxyType({})
    """Path-constraint blocks of ``g`` -> row bounds (see :attr:`TranscribedNLP.path_limits`)."""


def uniform_times(guess: Trajectory, n_knots: int) -> tuple[float, Array]:
    """Time step [s] and ``n_knots`` uniform times spanning ``guess``."""
    dt = guess.duration / (n_knots - 1)
    if not math.isfinite(dt) or dt <= 0.0:
        raise TranscriptionError(f"guess duration must be > 0 [s], got {guess.duration}")
    return dt, guess.t[0] + dt * np.arange(n_knots)
