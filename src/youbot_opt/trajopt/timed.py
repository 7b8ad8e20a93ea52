"""A timed trajectory through waypoints at free times (#30 item 3): :func:`solve_through`.

The motion starts at the problem's start, passes through the :class:`Waypoints`
in order and ends at rest at the goal (or back at the first waypoint when
``closed``). Each segment between consecutive visits has its own free step:
the ``dt`` block has one entry per segment, the waypoint knots are pinned by
equality rows, ``T`` and ``W`` sum the segments; objective, bounds and dynamics
are the single-segment NLP's. A solution is then exactly a point of the
ordinary NLP on the grid of its own steps: it is reported, checked and
certified as one (:class:`TimedResult`), and :meth:`TimedSolver.refine` refines
it within its segments with :func:`~youbot_opt.trajopt.refine.refine`'s loop.
Spec and units: docs/timed.md.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import casadi as ca
import numpy as np

from youbot_opt._checks import check_beta, check_bound_scale, check_time_limit
from youbot_opt._typing import Array, JSONDict
from youbot_opt.exceptions import ParameterError
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.trajopt.guess import DEFAULT_GUESS_DURATION, inverse_dynamics
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.refine import Refinement, RefinementBudget, RefinementRound, refine
from youbot_opt.trajopt.result import DEFAULT_FEASIBILITY_TOL, TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.trajectory import Trajectory
from youbot_opt.trajopt.transcription.base import Layout, TranscribedNLP, Transcription
from youbot_opt.trajopt.transcription.hermite_simpson import HermiteSimpsonCollocation
from youbot_opt.trajopt.transcription.path import PathConstraint
from youbot_opt.trajopt.transcription.trapezoidal import TrapezoidalCollocation
from youbot_opt.trajopt.waypoints import Waypoints

__all__ = [
    "DEFAULT_KNOTS_PER_SEGMENT",
    "GUESS_SPEED_FRACTION",
    "TimedResult",
    "TimedSolver",
    "solve_through",
]

DEFAULT_KNOTS_PER_SEGMENT = 20
"""Knots of each segment, its two ends included (19 intervals; with 10 the study arm's
certificate fails on a 1.4 s segment)."""
GUESS_SPEED_FRACTION = 0.5
"""The guess moves each segment at this fraction of the slowest joint's velocity limit."""
_MIN_GUESS_SEGMENT = 0.1  # [s], a segment between equal configurations
_METHODS = ("hermite_simpson", "hermite-simpson", "trapezoidal")


@dataclass(frozen=True, slots=True, kw_only=True)
class _WaypointNLP(TranscribedNLP):
    """A segmented NLP: its ``waypoint_position`` rows equal the pinned configurations."""

    waypoint_q: Array = dataclasses.field(default_factory=lambda: np.zeros((0, 0)))

    def constraint_bounds(
        self, start: BoundaryState, goal: BoundaryState, bounds: Any = None
    ) -> tuple[Array, Array]:
        """``(lbg, ubg)`` of :class:`TranscribedNLP`, the waypoint rows set to the waypoints."""
        lower, upper = TranscribedNLP.constraint_bounds(self, start, goal, bounds)
        block = self.constraints["waypoint_position"]
        rows = slice(block.offset, block.offset + block.size)
        lower[rows] = upper[rows] = np.asarray(self.waypoint_q, dtype=float).ravel()
        return lower, upper


class _Segmented(Transcription):
    """A collocation scheme with one free step per segment and pinned waypoint knots.

    Segment ``s`` has ``counts[s]`` intervals; interval ``k`` of segment ``s``
    lasts ``r_k dt[s]``, the ratios ``r`` of the grid's ``fractions`` within
    each segment (mean 1 a segment: ``dt[s]`` is its mean step). Built only by
    :class:`TimedSolver` (uniform segments) and by refinement (split ones).
    """

    plain: ClassVar[type[Transcription]]

    def __init__(self, counts: Any, pinned: Array, fractions: Any = None) -> None:
        counts = np.asarray(counts, dtype=np.intp)
        total = int(counts.sum())
        super().__init__(np.ones(total) if fractions is None else fractions)
        assert self.fractions is not None and self.fractions.size == total
        self.counts = counts
        self.segments = int(counts.size)
        self.ends = np.concatenate(([0], np.cumsum(counts)))  # knot of each segment end
        self.segment = np.repeat(np.arange(self.segments), counts)  # segment of each interval
        share = np.bincount(self.segment, weights=self.fractions) / counts  # mean per segment
        self.step_ratios = self.fractions / share[self.segment]  # r_k, mean 1 a segment
        self.uniform_segments = fractions is None
        select = np.zeros((total, self.segments))
        select[np.arange(total), self.segment] = self.step_ratios
        self.select = ca.DM(select)  # (M, S)
        self.pinned = np.asarray(pinned, dtype=float)  # (S - 1, nv), the inner segment ends
        self.initial_values: dict[str, Array] = {}

    def __repr__(self) -> str:
        return f"{type(self).__name__}(counts={self.counts.tolist()})"

    def with_fractions(self, fractions: Any) -> Transcription:
        """Return the plain scheme on a grid: a segmented solution is a point of its NLP."""
        return self.plain(fractions)

    def split(self, fractions: Any, boundaries: Array) -> _Segmented:
        """Return the same segments on a finer grid whose knots include the segment ends.

        ``fractions`` are the new grid's interval fractions of ``T``, ``boundaries``
        the inner segment ends as fractions of ``T`` on that grid (what
        :func:`~youbot_opt.trajopt.mesh.split_grid` keeps: it splits intervals,
        never moves a knot).
        """
        f = np.asarray(fractions, dtype=float)
        edges = np.cumsum(f / f.sum())
        knots = np.searchsorted(edges, np.asarray(boundaries) - 1e-9) + 1
        if knots.size and (
            np.any(np.abs(edges[knots - 1] - boundaries) > 1e-9) or np.any(np.diff(knots) < 1)
        ):
            raise ParameterError("the new grid does not keep the waypoint knots", name="fractions")
        counts = np.diff(np.concatenate(([0], knots, [f.size])))
        return type(self)(counts, self.pinned, f)

    def steps_value(self, dt: Array) -> Array:
        """Interval steps [s] of the per-segment steps ``dt`` [s] (numbers)."""
        return self.step_ratios * np.asarray(dt, dtype=float).ravel()[self.segment]

    def variable_blocks(self, nv: int, n_knots: int) -> list[tuple[str, int, int]]:
        """Return the plain scheme's blocks, ``dt`` with one step [s] per segment."""
        blocks = self.plain.variable_blocks(self, nv, n_knots)
        return [(name, self.segments, 1) if name == "dt" else (name, w, c) for name, w, c in blocks]

    def steps_of(self, dt: Any) -> Any:
        """Interval steps ``h_k = r_k dt[s_k]`` as a ``1 x M`` row."""
        return ca.mtimes(self.select, dt).T

    def per_interval(self, expr: Any, dt: Any) -> Any:
        """``expr`` (``nv x M``) with column ``k`` times its step."""
        return expr * ca.repmat(self.steps_of(dt), expr.size1(), 1)

    def time_and_work(self, sym: dict[str, Any], n_knots: int) -> tuple[Any, Any]:
        """``T = sum_s counts_s dt_s`` and ``W = sum_k h_k Q_k`` (``Q_k``: interval quadrature)."""
        h = self.steps_of(sym["dt"])
        p = ca.sum1(sym["tau"] ** 2)
        if "tau_mid" in sym:  # Simpson
            inner = (p[:, :-1] + 4 * ca.sum1(sym["tau_mid"] ** 2) + p[:, 1:]) / 6
        else:  # trapezoid
            inner = (p[:, :-1] + p[:, 1:]) / 2
        if self.uniform_segments:  # the unrefined NLP, expression for expression
            total = int(self.counts[0]) * ca.sum1(sym["dt"])
        else:
            total = ca.mtimes(ca.DM(self.counts.astype(float)).T, sym["dt"])
        return total, ca.sum2(h * inner)

    def expressions(
        self,
        problem: TrajOptProblem,
        sym: dict[str, Any],
        accel: dict[str, Any],
        beta: Any,
        paths: tuple[PathConstraint, ...] = (),
        path_values: Any = None,
    ) -> Any:
        """Return the plain expressions plus the ``waypoint_position`` rows (inner ends)."""
        parts = super().expressions(problem, sym, accel, beta, paths, path_values)
        knots = [int(k) for k in self.ends[1:-1]]
        pinned = ca.horzcat(*[sym["q"][:, k] for k in knots])
        blocks = [(b.name, b.width, b.count) for b in parts.constraints.blocks.values()]
        return parts._replace(
            g=ca.vertcat(parts.g, ca.vec(pinned)),
            constraints=Layout([*blocks, ("waypoint_position", problem.nv, len(knots))]),
        )

    def build(
        self,
        problem: TrajOptProblem,
        forward_dynamics: ca.Function,
        paths: tuple[PathConstraint, ...] = (),
    ) -> TranscribedNLP:
        """Build the plain NLP, knowing the waypoint rows' values."""
        nlp = super().build(problem, forward_dynamics, paths)
        fields = {f.name: getattr(nlp, f.name) for f in dataclasses.fields(TranscribedNLP)}
        return _WaypointNLP(**fields, waypoint_q=self.pinned)

    def knot_guess(self, guess: Trajectory, n_knots: int) -> dict[str, Array]:
        """Return the piecewise-linear guess :class:`TimedSolver` set, else ``guess`` here."""
        if self.initial_values:
            return {name: np.array(value) for name, value in self.initial_values.items()}
        values = self.plain(self.fractions).knot_guess(guess, n_knots)  # the mean step as dt
        assert self.fractions is not None
        share = np.bincount(self.segment, weights=self.fractions)  # each segment's part of T
        values["dt"] = guess.duration * share / self.counts
        return values


class _SegmentedHermiteSimpson(_Segmented, HermiteSimpsonCollocation):
    plain = HermiteSimpsonCollocation


class _SegmentedTrapezoidal(_Segmented, TrapezoidalCollocation):
    plain = TrapezoidalCollocation


class _SegmentSolver(TrajOptSolver):
    """A :class:`TrajOptSolver` of a segmented NLP reporting on its solution's grid.

    :meth:`on_grid` keeps the segments (refinement splits intervals within
    them); ``grids`` (shared by the solvers it makes) maps a knot count to its
    segmented scheme, so a refined result's waypoint knots can be found.
    """

    method: _Segmented
    grids: dict[int, _Segmented]
    _boundaries: Array  # inner segment ends of the last solution, as fractions of T

    def on_grid(self, fractions: Any, *, max_wall_time: float | None = None) -> TrajOptSolver:
        """Return the segmented NLP on a finer grid of the last solution (``split``)."""
        tic = time.perf_counter()
        return self._copy(self.method.split(fractions, self._boundaries), max_wall_time, tic)

    def with_method(self, method: str, *, max_wall_time: float | None = None) -> TrajOptSolver:
        """Return the segmented NLP of another scheme on the same grid and segments."""
        tic = time.perf_counter()
        segments = self.method
        cls = _SegmentedTrapezoidal if method == "trapezoidal" else _SegmentedHermiteSimpson
        fractions = None if segments.uniform_segments else segments.fractions
        return self._copy(cls(segments.counts, segments.pinned, fractions), max_wall_time, tic)

    def _copy(self, method: _Segmented, max_wall_time: float | None, tic: float) -> TrajOptSolver:
        new = copy.copy(self)  # shares problem spec, options, dynamics and kernels
        new.method = method
        new.problem = dataclasses.replace(self.problem, n_knots=int(method.ends[-1]) + 1)
        if max_wall_time is not None:
            check_time_limit(max_wall_time, "max_wall_time")
            own = self.options.max_wall_time
            cap = float(max_wall_time) if own is None else min(own, float(max_wall_time))
            new.options = dataclasses.replace(self.options, max_wall_time=cap)
        new._build(tic)
        self.grids[new.problem.n_knots] = method
        return new

    def _result(
        self,
        x: Array,
        lam_x: Array,
        lam_g: Array,
        stats: dict[str, Any],
        error: str,
        note: str = "",
        **kw: Any,
    ) -> TrajOptResult:
        method = self.method
        nlp = self.nlp
        values = nlp.variables.unpack(x)
        steps = method.steps_value(values["dt"])
        usable = bool(np.all(np.isfinite(steps)) and np.all(steps > 0.0))
        fractions = steps / steps.sum() if usable else np.ones(steps.size)
        self._boundaries = np.cumsum(fractions)[method.ends[1:-1] - 1]
        plain = TrajOptSolver.on_grid(self, fractions)  # with_fractions: the plain scheme
        values["dt"] = np.array([[steps.mean() if usable else np.nan]])
        x_plain = plain.nlp.variables.pack(values)
        lam = nlp.variables.unpack(lam_x)
        lam["dt"] = np.array([[lam["dt"].sum()]])
        rows = nlp.constraints.unpack(lam_g)
        lam_g_plain = plain.nlp.constraints.pack({k: rows[k] for k in plain.nlp.constraints.blocks})
        joint_bounds = self.problem.bounds(kw["bound_scale"])
        lbx, ubx = plain.nlp.variable_bounds(joint_bounds, self._dt_range())
        lbg, ubg = plain.nlp.constraint_bounds(kw["start"], kw["goal"], joint_bounds)
        kw["bounds"] = (lbx, ubx, lbg, ubg)
        lam_x_plain = plain.nlp.variables.pack(lam)
        result = plain._result(x_plain, lam_x_plain, lam_g_plain, stats, error, note, **kw)
        if np.all(np.isfinite(lam_g)):
            pinned = rows["waypoint_position"]  # kept: refinement warm-starts the next grid
            pinned.setflags(write=False)
            result = dataclasses.replace(
                result, multipliers={**result.multipliers, "waypoint_position": pinned}
            )
        return result


@dataclass(frozen=True, slots=True, kw_only=True)
class TimedResult:
    """A timed trajectory through waypoints.

    Attributes
    ----------
    result : TrajOptResult
        The solution as a point of the ordinary NLP on its own grid: ``duration``
        ``T`` [s], ``work`` ``W`` [N^2 m^2 s], status, trajectory, the
        independent check; :func:`~youbot_opt.trajopt.certify.certify` takes it.
    waypoints : Waypoints
        The waypoints passed through.
    waypoint_knots : tuple of int
        Knot at which each waypoint row is first reached (0 when the first row is the start).
    waypoint_times : ndarray, shape (k,)
        Time [s] at which each waypoint row is first reached.
    segment_durations : ndarray, shape (S,)
        Duration [s] of each segment; they sum to ``T``.
    waypoint_error : float
        Largest ``|q(t_i) - w_i|`` [rad] over the waypoints (the trajectory
        evaluated at its own times; also the return to the first row when closed).
    refinement : Refinement or None
        The record of :meth:`TimedSolver.refine` (its rounds, verdict and
        reason); None when solved once on the starting grid.
    """

    result: TrajOptResult
    waypoints: Waypoints
    waypoint_knots: tuple[int, ...]
    waypoint_times: Array
    segment_durations: Array
    waypoint_error: float
    refinement: Refinement | None = None

    @property
    def duration(self) -> float:
        """Total duration ``T`` [s]."""
        return float(self.result.duration)

    @property
    def work(self) -> float:
        """Work ``W`` [N^2 m^2 s] (the study's torque-squared integral)."""
        return float(self.result.work)

    @property
    def success(self) -> bool:
        """The solve succeeded and every waypoint is hit within ``feasibility_tol``."""
        return bool(self.result.success) and self.waypoint_error <= self.result.feasibility_tol

    @property
    def certified(self) -> bool:
        """:attr:`success` and a refinement that ended certified (False when not refined)."""
        return self.success and self.refinement is not None and self.refinement.certified

    def summary(self) -> JSONDict:
        """JSON-ready figures: waypoint times [s], T [s], W, status, waypoint error [rad].

        With a refinement also ``"refinement"`` (:meth:`Refinement.summary`: its rounds).
        """
        doc: JSONDict = {
            "waypoint_times_s": [float(t) for t in self.waypoint_times],
            "segment_durations_s": [float(d) for d in self.segment_durations],
            "closed": self.waypoints.closed,
            "duration_s": self.duration,
            "work": self.work,
            "status": str(self.result.status.value),
            "success": self.success,
            "waypoint_error_rad": self.waypoint_error,
        }
        if self.refinement is not None:
            doc["refinement"] = self.refinement.summary()
        return doc


class TimedSolver:
    """The segmented NLP of a problem through waypoints, built once.

    Parameters
    ----------
    problem : TrajOptProblem
        Robot, start (and goal, unless ``waypoints.closed``), bounds; its
        ``n_knots`` is not used (``knots_per_segment`` is) and its duration
        must be free.
    waypoints : Waypoints
        The configurations passed through, in order. A first row equal to the
        start is the start itself (the cyclic IK path's first configuration).
    method : str
        ``"hermite_simpson"`` (default) or ``"trapezoidal"``.
    knots_per_segment : int
        Knots of each segment, its ends included (>= 2).
    options, backend, feasibility_tol, compile
        As :class:`~youbot_opt.trajopt.solver.TrajOptSolver`.

    :meth:`solve` solves on ``knots_per_segment`` knots a segment;
    :meth:`refine` then splits intervals within their segments until the plan
    is certified (:func:`~youbot_opt.trajopt.refine.refine`'s loop and budget).

    Raises
    ------
    ParameterError
        A fixed duration, an unknown method, bad ``knots_per_segment``,
        waypoints that do not fit the robot (row and joint named).
    """

    def __init__(
        self,
        problem: TrajOptProblem,
        waypoints: Waypoints,
        method: str = "hermite_simpson",
        *,
        knots_per_segment: int = DEFAULT_KNOTS_PER_SEGMENT,
        options: IpoptOptions | None = None,
        backend: str = "symbolic",
        feasibility_tol: float = DEFAULT_FEASIBILITY_TOL,
        compile: bool | str = True,
    ) -> None:
        if not isinstance(problem, TrajOptProblem):
            raise ParameterError(
                f"problem must be a TrajOptProblem, got {type(problem).__name__}", name="problem"
            )
        if not isinstance(waypoints, Waypoints):
            raise ParameterError(
                f"waypoints must be a Waypoints, got {type(waypoints).__name__}", name="waypoints"
            )
        if problem.duration is not None:
            raise ParameterError(
                f"a trajectory through waypoints has free segment durations; got a fixed "
                f"duration = {problem.duration} s",
                name="duration",
                value=problem.duration,
            )
        if method not in _METHODS:
            raise ParameterError(
                f"method through waypoints must be one of {list(_METHODS)}, got {method!r}",
                name="method",
                value=method,
            )
        if (
            isinstance(knots_per_segment, bool)
            or not isinstance(knots_per_segment, int | np.integer)
            or knots_per_segment < 2
        ):
            raise ParameterError(
                f"knots_per_segment must be an int >= 2, got {knots_per_segment!r}",
                name="knots_per_segment",
                value=knots_per_segment,
            )
        waypoints.check(problem.bounds(), robot_name=problem.robot.name)
        self.waypoints = waypoints
        visits = waypoints.visits
        skip = int(np.array_equal(visits[0], problem.start.q))  # the first row is the start
        self._skip = skip
        ends = visits[skip:] if waypoints.closed else np.vstack([visits[skip:], problem.goal.q])
        if waypoints.closed and ends.shape[0] < 2:  # from the start straight back to it
            raise ParameterError(
                "nothing to time: the only waypoint is the start and the cycle is closed",
                name="waypoints",
            )
        segments, m = int(ends.shape[0]), int(knots_per_segment) - 1
        self.intervals = m
        goal = BoundaryState(q=ends[-1]) if waypoints.closed else problem.goal
        plain = dataclasses.replace(problem, n_knots=segments * m + 1, goal=goal)
        cls = _SegmentedTrapezoidal if method == "trapezoidal" else _SegmentedHermiteSimpson
        self.method = cls(np.full(segments, m), ends[:-1])
        self.waypoint_knots, self.closing_knot = self._knots(self.method)
        self.points = np.vstack([problem.start.q, ends])  # (S + 1, nv)
        self._segments = _SegmentSolver(
            plain, self.method, options, backend, feasibility_tol=feasibility_tol, compile=compile
        )
        self._segments.grids = {plain.n_knots: self.method}
        self.problem = self._segments.problem

    def _knots(self, method: _Segmented) -> tuple[tuple[int, ...], int | None]:
        """Return the knot of each waypoint row (0: the start) and of the return (or None)."""
        ends = [int(k) for k in method.ends]
        rows = self.waypoints.count
        closing = ends[-1] if self.waypoints.closed else None
        return tuple(ends[r + 1 - self._skip] for r in range(rows)), closing

    def guess_durations(self, bound_scale: float = 1.0) -> Array:
        """Segment durations [s] of the initial guess.

        Each joint covers its distance at :data:`GUESS_SPEED_FRACTION` of its
        velocity limit; the slowest joint sets the segment's duration (at least
        0.1 s). Stretched, in proportion, to the point-to-point solve's default
        guess duration :data:`~youbot_opt.trajopt.guess.DEFAULT_GUESS_DURATION`
        when shorter in total: one segment is then that solve's straight line.
        """
        b = self.problem.bounds(bound_scale)
        speed = GUESS_SPEED_FRACTION * np.minimum(np.abs(b.v_lower), np.abs(b.v_upper))
        dq = np.abs(np.diff(self.points, axis=0))
        with np.errstate(divide="ignore", invalid="ignore"):
            times = np.where(dq > 0.0, dq / speed, 0.0)
        durations = np.maximum(np.max(times, axis=1), _MIN_GUESS_SEGMENT)
        return durations * max(1.0, DEFAULT_GUESS_DURATION / float(durations.sum()))

    def _initial_values(self, bound_scale: float) -> dict[str, Array]:
        """Piecewise-linear positions, constant velocity a segment, inverse-dynamics torques.

        As the straight-line guess, the end velocities are the segments' (the NLP
        imposes rest there).
        """
        durations = self.guess_durations(bound_scale)
        m, pts = self.intervals, self.points
        s = np.repeat(np.arange(durations.size), m)  # segment of each interval
        local = np.tile(np.arange(m), durations.size)  # interval within the segment
        vel = np.diff(pts, axis=0) / durations[:, None]  # (S, nv)

        def at(frac: Array) -> Array:
            return pts[s] + ((local + frac) / m)[:, None] * (pts[s + 1] - pts[s])

        q = np.vstack([at(np.zeros(s.size)), pts[-1:]])
        v = np.vstack([vel[s], vel[-1:]])
        v[m::m][:-1] = 0.5 * (vel[:-1] + vel[1:])  # shared segment ends: the mean
        zeros = np.zeros_like(q)
        values = {"q": q, "v": v, "tau": inverse_dynamics(self.problem, q, v, zeros)}
        if isinstance(self.method, HermiteSimpsonCollocation):
            qm, vm = at(np.full(s.size, 0.5)), vel[s]
            values.update(
                q_mid=qm, v_mid=vm, tau_mid=inverse_dynamics(self.problem, qm, vm, zeros[:-1])
            )
        values["dt"] = durations / m
        return values

    def solve(self, beta: float = 0.5, bound_scale: float = 1.0) -> TimedResult:
        """Solve from the piecewise-linear guess.

        Parameters
        ----------
        beta : float
            Time weight in [0, 1] of ``beta T + (1 - beta) W``.
        bound_scale : float
            Factor > 0 on the problem's scaled bound families.

        Returns
        -------
        TimedResult
            Check ``success`` (the solve's status and every waypoint hit).
        """
        beta, bound_scale = check_beta(beta), check_bound_scale(bound_scale)
        self.waypoints.check(self.problem.bounds(bound_scale), robot_name=self.problem.robot.name)
        self.method.initial_values = self._initial_values(bound_scale)
        result = self._segments.solve(beta=beta, bound_scale=bound_scale, warm_start=False)
        return self._timed(result)

    def refine(
        self,
        beta: float = 0.5,
        bound_scale: float = 1.0,
        *,
        budget: RefinementBudget | None = None,
        progress: Callable[[RefinementRound], None] | None = None,
        first: TimedResult | None = None,
        processes: int = 1,
    ) -> TimedResult:
        """Solve, then refine within the segments until certified or the budget runs out.

        :func:`~youbot_opt.trajopt.refine.refine`'s rounds on the segmented NLP:
        each round estimates every interval's collocation error on the result
        (an ordinary one on its own grid), certifies it, splits the worst
        intervals (equal pieces, so the waypoint knots stay segment ends and
        each segment keeps its own step) and re-solves warm-started from the
        previous solution (primal, bound and defect multipliers, and the
        waypoint rows' own). A Hermite-Simpson torque overshoot no grid removes
        switches it to the trapezoidal scheme on the same segments (``budget.fallback``).

        Parameters
        ----------
        beta, bound_scale
            As :meth:`solve` (taken from ``first`` when given).
        budget : RefinementBudget, optional
            Tolerance and limits (its defaults when None).
        progress : callable, optional
            Called with each :class:`~youbot_opt.trajopt.refine.RefinementRound`.
        first : TimedResult, optional
            This solver's :meth:`solve` result, refined instead of solving again.
        processes : int, optional
            Processes each certificate's simulations may use (as
            :func:`~youbot_opt.trajopt.refine.refine`'s; 1 by default).

        Returns
        -------
        TimedResult
            The last round's plan with its :attr:`TimedResult.refinement` record
            (:attr:`TimedResult.certified`; otherwise the record's reason says why).
        """
        if first is None:
            first = self.solve(beta=beta, bound_scale=bound_scale)
        elif first.result.problem.n_knots != self.problem.n_knots:
            raise ParameterError("first must be this solver's solve() result", name="first")
        refined = refine(
            self._segments, first=first.result, budget=budget, progress=progress,
            processes=processes,
        )  # fmt: skip
        return dataclasses.replace(self._timed(refined.result), refinement=refined.refinement)

    def _timed(self, result: TrajOptResult) -> TimedResult:
        traj = result.trajectory
        method = self._segments.grids[result.problem.n_knots]
        knots, closing = self._knots(method)
        rows = self.waypoints.count
        if traj is None:
            nan = np.full(rows, np.nan)
            return TimedResult(
                result=result, waypoints=self.waypoints, waypoint_knots=knots,
                waypoint_times=nan, segment_durations=np.full(method.segments, np.nan),
                waypoint_error=math.inf,
            )  # fmt: skip
        t = np.asarray(traj.t, dtype=float)
        times = t[list(knots)]
        hits = [(times, self.waypoints.q)]
        if closing is not None:
            hits.append((t[[closing]], self.waypoints.q[:1]))
        error = max(float(np.max(np.abs(traj(ts) - w))) for ts, w in hits)
        return TimedResult(
            result=result,
            waypoints=self.waypoints,
            waypoint_knots=knots,
            waypoint_times=times,
            segment_durations=np.diff(t[method.ends]),
            waypoint_error=error,
        )


def solve_through(
    problem: TrajOptProblem,
    waypoints: Waypoints,
    *,
    method: str = "hermite_simpson",
    knots_per_segment: int = DEFAULT_KNOTS_PER_SEGMENT,
    beta: float = 0.5,
    bound_scale: float = 1.0,
    options: IpoptOptions | None = None,
    backend: str = "symbolic",
) -> TimedResult:
    """Build a :class:`TimedSolver` and solve once (see its parameters).

    >>> timed = solve_through(problem, Waypoints(q=[[0.5, 1.0, -1.0]]))  # doctest: +SKIP
    >>> timed.waypoint_times, timed.duration  # doctest: +SKIP
    """
    solver = TimedSolver(
        problem, waypoints, method, knots_per_segment=knots_per_segment, options=options,
        backend=backend,
    )  # fmt: skip
    return solver.solve(beta=beta, bound_scale=bound_scale)
