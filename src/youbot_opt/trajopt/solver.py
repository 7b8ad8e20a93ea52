"""Build the trajectory NLP once, solve it many times: :class:`TrajOptSolver`.

``TrajOptSolver(problem, method, options, backend)`` builds the robot's CasADi
dynamics, transcribes the problem and creates the IPOPT solver once;
:meth:`TrajOptSolver.solve` then takes the sweep parameters (``beta``, the bound
scale, the boundary states), which change only an NLP parameter and numeric
bounds, so sweeps never rebuild. :func:`solve` is the one-off wrapper. How the
derivatives are formed and how each result is checked: :class:`TrajOptSolver`;
why: docs/design.md, "Module notes".

    result = TrajOptSolver(problem, "hermite_simpson").solve(beta=0.5)
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, cast

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from youbot_opt._checks import check_beta, check_bound_scale, check_time_limit
from youbot_opt._typing import Array
from youbot_opt.dynamics.base import Dynamics
from youbot_opt.dynamics.numeric import STIFF_RATIO, damping_rate
from youbot_opt.exceptions import ParameterError
from youbot_opt.nlp.best_iterate import BestIterateRecorder, Iterate, better, violation_of
from youbot_opt.nlp.ipopt import (
    IpoptOptions,
    IpoptValue,
    bound_relaxation,
    check_linear_solver,
    single_threaded_blas,
)
from youbot_opt.trajopt.check import checked
from youbot_opt.trajopt.guess import DEFAULT_GUESS_DURATION, resolve_guess
from youbot_opt.trajopt.objectives import work as work_of
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.result import (
    DEFAULT_FEASIBILITY_TOL,
    BoundStructure,
    PathBlock,
    SolveStats,
    SolveStatus,
    TrajOptResult,
    status_from_ipopt,
)
from youbot_opt.trajopt.trajectory import Trajectory
from youbot_opt.trajopt.transcription import Transcription, get_transcription
from youbot_opt.trajopt.transcription.base import BOUND_NAMES, TranscribedNLP
from youbot_opt.trajopt.transcription.derivatives import (
    Kernels,
    PathKernels,
    cached_kernels,
    cached_path_kernels,
    compile_kernels,
    compile_path_kernels,
    dynamics_kernels,
    path_kernels,
    stencil_of,
    structured_functions,
)
from youbot_opt.trajopt.transcription.path import PathConstraint
from youbot_opt.trajopt.transcription.stencil import IntervalStencil

if TYPE_CHECKING:
    from youbot_opt.collision.exact import ExactChecker

__all__ = [
    "TrajOptSolver",
    "solve",
    "auto_transcription",
    "DEFAULT_FEASIBILITY_TOL",
    "EXPAND_AFTER_SOLVES",
]

_log = logging.getLogger(__name__)

_SECOND_ORDER_BACKENDS = ("symbolic", "pinocchio_casadi")
EXPAND_AFTER_SOLVES = 20
"""Solves after which a solver's NLP functions are expanded to SX (:class:`TrajOptSolver`)."""

BoundaryLike = BoundaryState | tuple[ArrayLike, ArrayLike] | ArrayLike
"""A boundary state: a :class:`BoundaryState`, a ``(q, v)`` pair or a ``q`` vector (at rest)."""
GuessLike = Trajectory | TrajOptResult | None
"""An initial guess, as :func:`youbot_opt.trajopt.guess.resolve_guess` accepts it."""


def _boundary(name: str, value: BoundaryLike | None, default: BoundaryState) -> BoundaryState:
    if value is None:
        return default
    if isinstance(value, BoundaryState):
        return value
    if isinstance(value, tuple) and len(value) == 2:
        # BoundaryState converts and validates the arrays itself.
        return BoundaryState(q=cast(Array, value[0]), v=cast(Array, value[1]))
    try:
        return BoundaryState(q=cast(Array, value))
    except ParameterError as exc:
        raise ParameterError(
            f"{name} must be a BoundaryState, a (q, v) pair or a q vector: {exc}", name=name
        ) from exc


class TrajOptSolver:
    """A transcribed trajectory problem with its IPOPT solver, built once.

    The robot's CasADi dynamics, the transcription and the IPOPT solver are
    built here; :meth:`solve` takes the sweep parameters -- the time weight
    ``beta`` (an NLP parameter), the bound scale and the boundary states (which
    only change the numeric bounds ``lbx``/``ubx``/``lbg``/``ubg``).

    With a twice-differentiable dynamics backend, IPOPT gets exact derivatives
    assembled from three per-point dynamics kernels mapped over the knots
    (:mod:`youbot_opt.trajopt.transcription.derivatives`), compiled to C and
    cached on disk when a compiler exists (:mod:`youbot_opt.nlp.codegen`).
    Other backends (Callbacks) get CasADi's AD of the transcribed MX graph and
    a limited-memory Hessian.

    Each result is checked independently of IPOPT's flag: the constraints are
    re-evaluated at the returned point and compared with their bounds, the
    decision variables with theirs, and everything must be finite; then the
    independent check (:func:`youbot_opt.trajopt.check.checked`, ``pin.aba``
    without the NLP) must agree before a converged solve is reported a success.

    Parameters
    ----------
    problem : TrajOptProblem
        The problem spec.
    method : str or Transcription
        ``"trapezoidal"`` (default, the study's), ``"hermite_simpson"``,
        ``"radau"``, ``"auto"`` (:func:`auto_transcription`: Radau IIA when the
        joint damping is stiff on the problem's grid, else Hermite-Simpson) or
        an instance.
    options : IpoptOptions, optional
        IPOPT settings; silent defaults when omitted.
    backend : str
        Dynamics backend of :func:`youbot_opt.dynamics.build_dynamics`:
        ``"symbolic"`` (default; exact Hessian, expanded to SX) or ``"pinocchio"``
        (Callback, limited-memory Hessian).
    dynamics : Dynamics, optional
        A prebuilt dynamics object (must match ``problem.robot``); overrides ``backend``.
    feasibility_tol : float
        Largest violation (unit of each row) a successful result may have;
        also stored in every result (``TrajOptResult.feasibility_tol``), so
        :meth:`youbot_opt.trajopt.result.TrajOptResult.check` applies the same one.
    compile : bool or "wait"
        Run the per-point dynamics kernels (value, Jacobian, weighted Hessian)
        as C compiled by the system compiler and cached on disk
        (:mod:`youbot_opt.nlp.codegen`). True (default): use the cached
        libraries; if they are missing, compile them now when that is short
        (``codegen.WAIT_SECONDS``: a two-link arm's), else in one background process
        for the next build and run this one on a quick unoptimised build
        (``codegen.QUICK_FLAGS``, compiled first when that takes at most
        ``codegen.QUICK_WAIT_SECONDS``: panda's in about 2 s), or else in CasADi's
        virtual machine (same results; the optimised compile takes from seconds to
        minutes per robot, which a first solve should not wait for). ``"wait"``:
        compile now. False: never compile. Only used by the second-order backends.

    Raises
    ------
    ParameterError
        On bad options, among them a linear solver whose library IPOPT could
        not load (:func:`youbot_opt.nlp.ipopt.check_linear_solver`).

    Attributes
    ----------
    nlp : TranscribedNLP
        The symbolic NLP (inspect it before solving).
    build_time : float
        Wall time in [s] spent building dynamics and NLP (IPOPT's instance is
        created on the first solve).
    compiled : bool
        Whether the solver runs compiled dynamics kernels.
    expanded : bool
        Whether its NLP functions run expanded to SX: from the solve after
        :data:`EXPAND_AFTER_SOLVES`, with compiled kernels only (docs/design.md,
        "Assembled or expanded").
    """

    def __init__(
        self,
        problem: TrajOptProblem,
        method: str | Transcription = "trapezoidal",
        options: IpoptOptions | None = None,
        backend: str = "symbolic",
        *,
        dynamics: Dynamics | None = None,
        feasibility_tol: float = DEFAULT_FEASIBILITY_TOL,
        compile: bool | str = True,
    ) -> None:
        if not isinstance(problem, TrajOptProblem):
            raise ParameterError(
                f"problem must be a TrajOptProblem, got {type(problem).__name__}", name="problem"
            )
        if not feasibility_tol > 0:
            raise ParameterError(
                f"feasibility_tol must be > 0, got {feasibility_tol!r}", name="feasibility_tol"
            )
        tic = time.perf_counter()
        self.problem = problem
        self.method = get_transcription(auto_transcription(problem) if method == "auto" else method)
        self.options = options if options is not None else IpoptOptions()
        if not isinstance(self.options, IpoptOptions):
            raise ParameterError("options must be an IpoptOptions", name="options")
        check_linear_solver(self.options)  # a missing HSL library: say so before building
        if dynamics is None:
            from youbot_opt.dynamics import build_dynamics

            dynamics = build_dynamics(problem.robot, backend, damping=problem.damping)
        self.dynamics = dynamics
        self.backend = str(dynamics.backend)
        self.feasibility_tol = float(feasibility_tol)
        symbolic = self.backend in _SECOND_ORDER_BACKENDS
        self._exact_hessian = self.options.exact_hessian(symbolic)
        self.compiled = False
        self._kernels: Kernels | None = None
        wait = True if compile == "wait" else None  # None: now only if short
        if symbolic:
            # Structured exact derivatives from per-point kernels (compiled to C when
            # possible): O(1) symbolic work on the dynamics, however many knots. Compiled
            # kernels found in the cache by what they derive from are loaded underived.
            fd = dynamics.forward_dynamics
            found = cached_kernels(fd) if compile else None
            if found is None:
                kernels = dynamics_kernels(fd)
                label = f"{problem.robot.name}'s dynamics"
                found = (
                    compile_kernels(kernels, wait=wait, label=label, source=fd)
                    if compile
                    else kernels
                )
                self.compiled = found is not kernels
            else:
                self.compiled = True
            self._kernels = found
        self._paths = _path_constraints(problem)
        # the path rows' own per-point kernels (compiled like the dynamics'), so that
        # IPOPT's Jacobian and Hessian of the clearance rows run compiled code too
        self._path_kernels: tuple[PathKernels, ...] | None = None
        if self._kernels is not None and self._paths:
            self._path_kernels = tuple(
                _path_kernels(c, compile=bool(compile), wait=wait, robot=problem.robot.name)
                for c in self._paths
            )
        self._checker: ExactChecker | None = None  # coal's solids, for overridden ends
        # each scheme's interval stencil (structured_functions), by scheme class: it does
        # not depend on the grid, so the solvers on_grid and with_method make share it
        self._stencils: dict[type[Transcription], IntervalStencil | None] = {}
        self._build(tic)

    def _build(self, tic: float) -> None:
        """Transcribe ``self.problem`` on ``self.method``'s grid; set up the IPOPT solvers."""
        problem = self.problem
        self.nlp: TranscribedNLP = self.method.build(
            problem, self.dynamics.forward_dynamics, self._paths
        )
        self._derivatives: dict[str, ca.Function] = {}
        # the knot accelerations of each result, from the compiled kernel when there is one
        forward = self.dynamics.forward_dynamics
        if self._kernels is not None:
            fast = self._kernels
            forward = fast.forward
            scheme = type(self.method)
            if scheme not in self._stencils:
                self._stencils[scheme] = stencil_of(
                    self.method, problem, self._paths, self._path_kernels
                )
            stencil = self._stencils[scheme]
            # the compiled forward kernel carries its Jacobian: IPOPT's constraint
            # evaluations and the NLP gradient CasADi builds from ``nlp`` run compiled too
            fns = structured_functions(
                self.method,
                problem,
                fast,
                values=fast,
                paths=self._paths,
                path_kernels=self._path_kernels,
                stencil=stencil,
                per_interval=stencil is not None,
            )
            self._nlp_function = fns.nlp
            self._derivatives = {"grad_f": fns.grad_f, "jac_g": fns.jac_g}
            if self._exact_hessian:
                self._derivatives["hess_lag"] = fns.hess_lag
        else:
            self._nlp_function = ca.Function(
                "nlp", [self.nlp.x, self.nlp.p], [self.nlp.f, self.nlp.g], ["x", "p"], ["f", "g"]
            )
        self._forward = forward
        self._accelerations = forward.map(problem.n_knots)
        # keeps the best iterate, returned when a solve fails (youbot_opt.nlp.best_iterate)
        self._recorder = BestIterateRecorder(
            "trajopt_iterates", self.nlp.n_variables, self.nlp.n_constraints, self.nlp.p.numel()
        )
        single_threaded_blas()
        # IPOPT instances are created on first use (a refinement round only warm-starts),
        # one per bound relaxation (nlp.ipopt.bound_relaxation: None for IPOPT's default)
        self._cold_solvers: dict[IpoptValue | None, Any] = {}
        self._warm_solvers: dict[IpoptValue | None, Any] = {}
        self._first_order: tuple[ca.Function, ca.Function] | None = None
        self._solves = 0
        self.expanded = False
        self.build_time = time.perf_counter() - tic
        _log.debug("built %s NLP in %.3f s", self.method.name, self.build_time)

    def on_grid(self, fractions: ArrayLike, *, max_wall_time: float | None = None) -> TrajOptSolver:
        """Return a solver of the same problem, method, options and dynamics on another grid.

        Shares this solver's dynamics and (compiled) derivative kernels, so
        only the transcription is rebuilt: what mesh refinement does per round.

        Parameters
        ----------
        fractions : array_like, shape (n_intervals,)
            Interval fractions of the duration (normalised to sum 1); the new
            problem has ``n_intervals + 1`` knots.
        max_wall_time : float, optional
            Wall-clock cap of each of the new solver's solves in [s] (IPOPT's
            ``max_wall_time``; the smaller of it and the options' own cap):
            how a refinement's time budget bounds a round's solve.

        Returns
        -------
        TrajOptSolver
            A new solver; this one is unchanged.

        Raises
        ------
        ParameterError
            If ``fractions`` is not one or more positive finite numbers.
        """
        tic = time.perf_counter()
        method = self.method.with_fractions(fractions)
        assert method.fractions is not None  # with_fractions(array) always sets a grid
        return self._derived(method, method.fractions.size + 1, max_wall_time, tic)

    def with_method(self, method: str, *, max_wall_time: float | None = None) -> TrajOptSolver:
        """Return a solver of the same problem, grid, options and dynamics with another scheme.

        Shares this solver's dynamics and (compiled) derivative kernels: what
        refinement does when Hermite-Simpson cannot pass the certificate
        (:func:`~youbot_opt.trajopt.refine.refine`, ``fallback``).

        Parameters
        ----------
        method : str
            The transcription's name (``"trapezoidal"``, ``"hermite_simpson"``, ``"radau"``).
        max_wall_time : float, optional
            As :meth:`on_grid`.

        Returns
        -------
        TrajOptSolver
            A new solver on the same knots; this one is unchanged.
        """
        tic = time.perf_counter()
        scheme = get_transcription(method)
        fractions = self.method.fractions
        scheme = scheme if fractions is None else scheme.with_fractions(fractions)
        return self._derived(scheme, self.problem.n_knots, max_wall_time, tic)

    def _derived(
        self, method: Transcription, n_knots: int, max_wall_time: float | None, tic: float
    ) -> TrajOptSolver:
        """Return a solver of ``method`` on ``n_knots`` sharing this one's dynamics and kernels."""
        new = object.__new__(TrajOptSolver)
        new.problem = dataclasses.replace(self.problem, n_knots=n_knots)
        new.method = method
        new.options, new.dynamics, new.backend = self.options, self.dynamics, self.backend
        if max_wall_time is not None:
            check_time_limit(max_wall_time, "max_wall_time")
            own = self.options.max_wall_time
            cap = float(max_wall_time) if own is None else min(own, float(max_wall_time))
            new.options = dataclasses.replace(self.options, max_wall_time=cap)
        new.feasibility_tol, new.compiled = self.feasibility_tol, self.compiled
        new._exact_hessian, new._kernels = self._exact_hessian, self._kernels
        new._paths, new._checker = self._paths, self._checker  # the same coal solids
        new._path_kernels, new._stencils = self._path_kernels, self._stencils
        new._build(tic)
        return new

    @property
    def hessian(self) -> str:
        """IPOPT's Hessian of the Lagrangian here: ``"exact"`` or ``"limited-memory"``."""
        return "exact" if self._exact_hessian else "limited-memory"

    def _expand_on_reuse(self) -> None:
        """Expand the NLP's functions to SX at the solve after :data:`EXPAND_AFTER_SOLVES`.

        The assembled functions (:func:`structured_functions`) are MX graphs: cheap
        to build, with a few copies per call (the stencil route's gathers and
        scatters). ``Function.expand`` writes the same arithmetic as one SX graph
        each, the compiled kernels left as calls, which runs faster but costs
        about as much as a few dozen solves' copies to build (docs/design.md,
        "Assembled or expanded"). A solver solved once (the command line, each
        refinement round) never pays for it; one solved many times (a sweep, a
        multistart, a benchmark) pays it once, after its copies have cost about
        as much. Only with compiled kernels: expanding SX kernels would inline
        the dynamics' derivatives at every point.
        """
        self._solves += 1
        if self._solves != EXPAND_AFTER_SOLVES + 1 or not self._derivatives:
            return
        kernels = [*(self._kernels or ()), *(f for pk in self._path_kernels or () for f in pk)]
        if not kernels or not all(k.is_a("External") for k in kernels):
            return
        self._nlp_function = self._nlp_function.expand()
        self._derivatives = {name: fn.expand() for name, fn in self._derivatives.items()}
        self._cold_solvers.clear()
        self._warm_solvers.clear()
        self.expanded = True

    def _kkt(self, relax: Mapping[str, IpoptValue]) -> dict[str, IpoptValue]:
        """Return the NLP's own IPOPT settings: the bound relaxation and the MUMPS ordering.

        The ordering (:attr:`Transcription.mumps_pivot_order`) replaces
        :data:`~youbot_opt.nlp.ipopt.FAST_KKT`'s only where that applies (``fast_kkt``
        on, MUMPS the linear solver); :attr:`IpoptOptions.extra` overrides both.
        """
        settings: dict[str, IpoptValue] = dict(relax)
        if self.options.fast_kkt and self.options.linear_solver == "mumps":
            settings["mumps_pivot_order"] = self.method.mumps_pivot_order
        return settings

    def _cold(self, relax: Mapping[str, IpoptValue]) -> Any:
        """Return the cold-start IPOPT instance of a bound relaxation (built on first use)."""
        key = relax.get("bound_relax_factor")
        if key not in self._cold_solvers:
            opts = self.options.to_casadi(self._exact_hessian, solver_settings=self._kkt(relax))
            opts["iteration_callback"] = self._recorder
            self._cold_solvers[key] = ca.nlpsol(
                "trajopt", "ipopt", self._nlp_function, {**opts, **self._derivatives}
            )
        return self._cold_solvers[key]

    def nlp_bounds(
        self,
        bound_scale: float = 1.0,
        start: BoundaryState | None = None,
        goal: BoundaryState | None = None,
    ) -> tuple[Array, Array, Array, Array]:
        """Return ``(lbx, ubx, lbg, ubg)``: the NLP's bounds at ``bound_scale``, as :meth:`solve`.

        Parameters
        ----------
        bound_scale : float
            Factor on the bound families (checked by the caller).
        start, goal : BoundaryState, optional
            The boundary states (the problem's when omitted).
        """
        problem = self.problem
        joint_bounds = problem.bounds(bound_scale)
        lbx, ubx = self.nlp.variable_bounds(joint_bounds, self._dt_range())
        lbg, ubg = self.nlp.constraint_bounds(
            problem.start if start is None else start,
            problem.goal if goal is None else goal,
            joint_bounds,
        )
        return lbx, ubx, lbg, ubg

    def first_order_functions(self) -> tuple[ca.Function, ca.Function]:
        """Return ``(x, p) -> (f, grad_f)`` and ``(x, p) -> (g, jac_g)`` of this NLP.

        The exact derivatives IPOPT is given where the backend has them (compiled
        when the kernels are), else CasADi's AD of the transcribed graph, built
        once. :func:`youbot_opt.trajopt.optimality.first_order` evaluates them.
        """
        if "grad_f" in self._derivatives:
            return self._derivatives["grad_f"], self._derivatives["jac_g"]
        if self._first_order is None:
            x, p, f, g = self.nlp.x, self.nlp.p, self.nlp.f, self.nlp.g
            self._first_order = (
                ca.Function("grad_f", [x, p], [f, ca.gradient(f, x)]),
                ca.Function("jac_g", [x, p], [g, ca.jacobian(g, x)]),
            )
        return self._first_order

    def _point_accelerations(self, q: Array, v: Array, tau: Array) -> Array:
        """Forward dynamics [rad/s^2] at knot-major points ``(q, v, tau)`` (the NLP's kernel)."""
        fd = self._forward.map(q.shape[0])
        return np.asarray(fd(q.T, v.T, tau.T), dtype=float).T

    # ----------------------------------------------------------------- solve
    def solve(
        self,
        beta: float = 0.5,
        bound_scale: float = 1.0,
        guess: GuessLike = None,
        start: BoundaryLike | None = None,
        goal: BoundaryLike | None = None,
        *,
        seed: int | None = None,
        warm_start: bool = True,
        initial: tuple[Array, Array, Array] | None = None,
    ) -> TrajOptResult:
        """Solve with the given sweep parameters (no rebuild).

        Parameters
        ----------
        beta : float
            Time weight in [0, 1] of ``f = beta T + (1 - beta) W`` (the NLP's
            parameter; 0.5, the study's base case, by default). Validated here,
            where it enters, and recorded once, in :attr:`TrajOptResult.beta`.
        bound_scale : float
            Factor > 0 on the bound families of ``problem.scaled_bounds`` (1.0 = data sheet).
        guess : None, Trajectory or TrajOptResult
            Initial guess (straight line when ``None``); resampled to the knots.
        start, goal : BoundaryState, (q, v) pair or q vector, optional
            Override the problem's boundary states.
        seed : int, optional
            Seed that produced ``guess`` (recorded in the result only).
        warm_start : bool
            When ``guess`` is a result of the same transcription and size, start
            IPOPT from its primal *and* dual solution (``warm_start_init_point``,
            small initial barrier parameter): a neighbouring sweep point then
            converges in a few iterations. ``False`` uses only its trajectory.
        initial : (x0, lam_x0, lam_g0), optional
            An explicit primal-dual start on this NLP's layout (mesh refinement
            interpolates one from the previous grid); overrides ``guess`` as the
            starting point (``guess`` is still recorded) and warm-starts IPOPT.

        Returns
        -------
        TrajOptResult
            The solution or, on failure, the last iterate with a failure status.

        Raises
        ------
        ParameterError
            On a bad ``beta``, ``bound_scale``, boundary state or guess.
        """
        problem = self.problem
        beta = check_beta(beta)
        bound_scale = check_bound_scale(bound_scale)
        start_state = _boundary("start", start, problem.start)
        goal_state = _boundary("goal", goal, problem.goal)
        problem.check_boundary(bound_scale, start_state, goal_state)
        if problem.clearance is not None and (start is not None or goal is not None):
            self._check_ends_clear(start_state.q, goal_state.q)
        if problem.tool and (start is not None or goal is not None):
            from youbot_opt.trajopt.tool import check_boundary_tool

            states = [("start", start_state.q, start_state.velocity)]
            check_boundary_tool(
                problem.robot, problem.tool, [*states, ("goal", goal_state.q, goal_state.velocity)]
            )
        guess_traj = resolve_guess(problem, guess, start=start_state, goal=goal_state)
        nlp = self.nlp
        dt_range = self._dt_range()
        warm = self._warm_start_point(guess) if warm_start else None
        if initial is not None:
            warm = self._initial_point(initial)
        lbx, ubx, lbg, ubg = self.nlp_bounds(bound_scale, start_state, goal_state)
        relax = bound_relaxation((lbx, ubx, lbg, ubg), self.feasibility_tol)
        self._expand_on_reuse()
        if warm is not None:
            x0, lam_x0, lam_g0 = warm
            solver = self._warm(relax)
        else:
            values = self.method.knot_guess(guess_traj, problem.n_knots)
            if problem.duration is not None:
                values["dt"] = np.array(dt_range[0])
            x0 = nlp.variables.pack(values)
            lam_x0, lam_g0 = np.zeros(nlp.n_variables), np.zeros(nlp.n_constraints)
            solver = self._cold(relax)
        if not np.all(np.isfinite(x0)):
            raise ParameterError("the initial guess is not finite", name="guess")

        self._recorder.reset((lbx, ubx, lbg, ubg), self.feasibility_tol)
        wall, cpu = time.perf_counter(), time.process_time()
        error = ""
        try:
            sol = solver(
                x0=x0, p=beta, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg, lam_x0=lam_x0, lam_g0=lam_g0
            )
            x = np.asarray(sol["x"], dtype=float).ravel()
            lam_x = np.asarray(sol["lam_x"], dtype=float).ravel()
            lam_g = np.asarray(sol["lam_g"], dtype=float).ravel()
        except RuntimeError as exc:  # evaluation errors inside CasADi/IPOPT
            error = str(exc).strip().splitlines()[-1] if str(exc).strip() else repr(exc)
            x, lam_x, lam_g = (
                x0.copy(),
                np.full_like(x0, np.nan),
                np.full(nlp.n_constraints, np.nan),
            )
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        stats = solver.stats()
        note = ""
        if error or not status_from_ipopt(str(stats.get("return_status", ""))).success:
            x, lam_x, lam_g, note = self._best_iterate(x, lam_x, lam_g, beta, (lbx, ubx, lbg, ubg))
        return self._result(
            x, lam_x, lam_g, stats, error, note,
            beta=beta, bound_scale=bound_scale, start=start_state, goal=goal_state,
            bounds=(lbx, ubx, lbg, ubg), guess=guess_traj, wall=wall, cpu=cpu, seed=seed,
        )  # fmt: skip

    # --------------------------------------------------------------- helpers
    def _check_ends_clear(self, start: Array, goal: Array) -> None:
        """Refuse a start or goal given to :meth:`solve` that lacks the clearance margin.

        The problem's own ends were checked when the NLP was built; overridden ones
        are checked here the same way (coal's exact distances; the checker is built
        once per solver), so a state inside an obstacle never reaches IPOPT; nor does,
        without an end window, one whose bounding balls lack the margin the NLP then
        holds at its fixed ends
        (:func:`~youbot_opt.trajopt.clearance.require_model_clearance`: the NLP
        would be infeasible from the start).
        """
        from youbot_opt.collision.clearance import clearance_checker
        from youbot_opt.trajopt.clearance import check_boundary_clearance, require_model_clearance

        clearance = self.problem.clearance
        assert clearance is not None
        if self._checker is None:
            self._checker = clearance_checker(self.problem.robot, clearance)
        check_boundary_clearance(
            self.problem, self._checker, margin=clearance.margin, start=start, goal=goal
        )
        rows = next((c for c in self._paths if c.name == "clearance"), None)
        if rows is not None:
            require_model_clearance(
                self.problem, rows, checker=self._checker, start=start, goal=goal
            )

    def _best_iterate(
        self,
        x: Array,
        lam_x: Array,
        lam_g: Array,
        beta: float,
        bounds: tuple[Array, Array, Array, Array],
    ) -> tuple[Array, Array, Array, str]:
        """After a failed solve: the best recorded iterate if it beats the returned one."""
        best, count = self._recorder.best, self._recorder.count
        if best is None:
            return x, lam_x, lam_g, ""
        final = None
        if np.all(np.isfinite(x)):
            f_dm, g_dm = self._nlp_function(x, beta)
            g = np.asarray(g_dm, dtype=float).ravel()
            if np.all(np.isfinite(g)) and np.isfinite(float(f_dm)):
                final = Iterate(x, lam_x, lam_g, float(f_dm), violation_of(x, g, bounds), -1)
        if final is not None and not better(best, final, self.feasibility_tol):
            return x, lam_x, lam_g, ""
        last = (
            f"violation {final.violation:.3g}, objective {final.objective:.6g}"
            if final is not None
            else "not finite"
        )
        note = (
            f"returned the best iterate, {best.iteration} of {count - 1} (violation "
            f"{best.violation:.3g}, objective {best.objective:.6g}), not the last ({last})"
        )
        return best.x.copy(), best.lam_x.copy(), best.lam_g.copy(), note

    def _warm(self, relax: Mapping[str, IpoptValue]) -> Any:
        """Return the warm-start IPOPT instance of a bound relaxation (sharing derivatives)."""
        key = relax.get("bound_relax_factor")
        if key not in self._warm_solvers:
            opts = self.options.to_casadi(
                self._exact_hessian, warm_start=True, solver_settings=self._kkt(relax)
            )
            opts["iteration_callback"] = self._recorder
            if self._derivatives:
                opts.update(self._derivatives)
            else:
                cold = self._cold(relax)
                for option, name in (("grad_f", "nlp_grad_f"), ("jac_g", "nlp_jac_g")):
                    opts[option] = cold.get_function(name)
                if self._exact_hessian:
                    opts["hess_lag"] = cold.get_function("nlp_hess_l")
            self._warm_solvers[key] = ca.nlpsol("trajopt_warm", "ipopt", self._nlp_function, opts)
        return self._warm_solvers[key]

    def _warm_start_point(self, guess: Any) -> tuple[Array, Array, Array] | None:
        """Primal-dual start ``(x0, lam_x0, lam_g0)`` from a compatible previous result."""
        if not isinstance(guess, TrajOptResult) or guess.method != self.method.name:
            return None
        nlp = self.nlp
        try:
            x0 = nlp.variables.pack(dict(guess.variables))
            lam_x0 = nlp.variables.pack(
                {
                    name: guess.multipliers[f"{BOUND_NAMES[name]}_lower"]
                    + guess.multipliers[f"{BOUND_NAMES[name]}_upper"]
                    for name in nlp.variables.blocks
                }
            )
            lam_g0 = nlp.constraints.pack({k: guess.multipliers[k] for k in nlp.constraints.blocks})
        except (KeyError, ValueError):  # other size, or no multipliers (failed solve)
            return None
        if self.problem.duration is not None:
            x0[nlp.variables["dt"].offset] = self._dt_range()[0]
        finite = np.all(np.isfinite(x0)) and np.all(np.isfinite(lam_x0))
        return (x0, lam_x0, lam_g0) if finite and np.all(np.isfinite(lam_g0)) else None

    def _initial_point(self, initial: tuple[Array, Array, Array]) -> tuple[Array, Array, Array]:
        """Validate an explicit primal-dual start against the NLP's sizes."""
        sizes = (self.nlp.n_variables, self.nlp.n_variables, self.nlp.n_constraints)
        arrays = tuple(np.array(part, dtype=float).ravel() for part in initial)
        if len(arrays) != 3 or any(a.size != n for a, n in zip(arrays, sizes, strict=True)):
            got = [a.size for a in arrays]
            raise ParameterError(
                f"initial must be (x0, lam_x0, lam_g0) of sizes {list(sizes)}, got {got}",
                name="initial",
            )
        x0, lam_x0, lam_g0 = arrays
        if self.problem.duration is not None:
            x0[self.nlp.variables["dt"].offset] = self._dt_range()[0]
        return x0, lam_x0, lam_g0

    def _dt_range(self) -> tuple[float, float]:
        p = self.problem
        if p.duration is not None:
            dt = p.duration / (p.n_knots - 1)
            return dt, dt
        return p.dt_min, p.dt_max

    def _result(
        self,
        x: Array,
        lam_x: Array,
        lam_g: Array,
        stats: dict[str, Any],
        error: str,
        note: str = "",
        *,
        beta: float,
        bound_scale: float,
        start: BoundaryState,
        goal: BoundaryState,
        bounds: tuple[Array, Array, Array, Array],
        guess: Trajectory,
        wall: float,
        cpu: float,
        seed: int | None,
    ) -> TrajOptResult:
        nlp, problem = self.nlp, self.problem
        lbx, ubx, lbg, ubg = bounds
        solver_status = str(stats.get("return_status", "unknown")) if not error else "error"
        status = status_from_ipopt(solver_status)
        message = solver_status if not error else f"solver error: {error}"
        if note:
            message = f"{message}; {note}"
        variables = nlp.variables.unpack(x)
        dt = float(variables["dt"][0, 0])

        finite = bool(np.all(np.isfinite(x)))
        g = np.full(nlp.n_constraints, np.nan)
        a = np.full((problem.n_knots, problem.nv), np.nan)
        if finite:
            _, g_dm = self._nlp_function(x, beta)
            g = np.asarray(g_dm, dtype=float).ravel()
            fd = self._accelerations
            a = np.asarray(fd(variables["q"].T, variables["v"].T, variables["tau"].T)).T
        total_time = (problem.n_knots - 1) * dt
        if self.method.uniform and nlp.rule != "radau":
            work = work_of(dt, variables["tau"], variables.get("tau_mid"), nlp.rule)
        else:
            work = dt * sum(
                float(np.sum(variables[name] ** 2, axis=1) @ w)
                for name, w in self.method.work_weights(problem.n_knots)
            )
        objective = beta * total_time + (1.0 - beta) * work
        violation = max(
            float(np.max(np.maximum(lbg - g, g - ubg), initial=0.0)),
            float(np.max(np.maximum(lbx - x, x - ubx), initial=0.0)),
        )
        all_finite = finite and bool(np.all(np.isfinite(g)) and np.all(np.isfinite(a)))
        all_finite = all_finite and np.isfinite(objective)
        if not all_finite:
            status = SolveStatus.NON_FINITE
            message = f"{message}; non-finite values in the solution, constraints or dynamics"
            violation = float("inf")
        elif status.success and not violation <= self.feasibility_tol:
            status = SolveStatus.CONSTRAINT_VIOLATION
            message = (
                f"{message}, but the solution violates a constraint or bound by "
                f"{violation:.3g} > feasibility_tol = {self.feasibility_tol:.3g}"
            )
        elif status.success and dt <= 0.0:
            status = SolveStatus.CONSTRAINT_VIOLATION
            message = f"{message}, but the time step dt = {dt:.3g} s is not positive"

        trajectory = None
        if all_finite and dt > 0.0:
            trajectory = self.method.trajectory(variables, a, self._point_accelerations)

        multipliers: dict[str, Array] = {}
        if np.all(np.isfinite(lam_x)):
            for name, block in nlp.variables.blocks.items():
                lam = block.take(lam_x)
                family = BOUND_NAMES[name]
                multipliers[f"{family}_lower"] = np.minimum(lam, 0.0)
                multipliers[f"{family}_upper"] = np.maximum(lam, 0.0)
        if np.all(np.isfinite(lam_g)):
            multipliers.update(nlp.constraints.unpack(lam_g))
        structure = BoundStructure(
            unbounded=tuple(nlp.unbounded),
            path={
                name: PathBlock(family=family, values=nlp.constraints[name].take(g))
                for name, family in nlp.path_bounds.items()
            },
        )
        paths = [block.values for block in structure.path.values()]
        for arr in (*multipliers.values(), *variables.values(), *paths):
            arr.setflags(write=False)
        history = np.asarray(stats.get("iterations", {}).get("obj", []), dtype=float)
        history.setflags(write=False)
        result = TrajOptResult(
            problem=problem,
            method=self.method.name,
            backend=self.backend,
            status=status,
            message=message,
            trajectory=trajectory,
            variables=variables,
            duration=total_time,
            dt=dt,
            work=work,
            objective=objective,
            beta=beta,
            bound_scale=bound_scale,
            start=start,
            goal=goal,
            stats=SolveStats(
                solver_status=solver_status,
                iterations=int(stats.get("iter_count", 0)),
                wall_time=wall,
                cpu_time=cpu,
                objective_history=history,
            ),
            max_violation=violation,
            multipliers=multipliers,
            guess=guess,
            options=self.options,
            seed=seed,
            feasibility_tol=self.feasibility_tol,
            bound_structure=structure,
            grid=self.method.fractions,
        )
        return checked(result)  # the independent check (pin.aba, no NLP) sets the status


def _path_constraints(problem: TrajOptProblem) -> tuple[PathConstraint, ...]:
    """Return the problem's path constraints: clearance and tool, start and goal checked first.

    Raises
    ------
    ParameterError
        The start or goal lacks the clearance margin (coal's exact distances),
        naming the state, the link and the obstacle.
    """
    tool = _tool_constraint(problem)
    if problem.clearance is None:
        return tool
    from youbot_opt.collision.clearance import clearance_checker
    from youbot_opt.trajopt.clearance import (
        check_boundary_clearance,
        clearance_constraint,
        require_model_clearance,
    )

    check_boundary_clearance(
        problem,
        clearance_checker(problem.robot, problem.clearance),
        margin=problem.clearance.margin,
    )
    constraint = clearance_constraint(problem)
    if constraint is None:
        return tool
    require_model_clearance(problem, constraint)
    return (constraint, *tool)


def _path_kernels(
    constraint: PathConstraint, *, compile: bool, wait: bool | None, robot: str
) -> PathKernels:
    """Return a path constraint's kernels: compiled from the cache, compiled now or later, or SX."""
    if compile and (found := cached_path_kernels(constraint)) is not None:
        return found
    own = path_kernels(constraint)
    if not compile:
        return own
    label = f"{robot}'s {constraint.name} rows"
    return compile_path_kernels(own, wait=wait, label=label, source=constraint)


def _tool_constraint(problem: TrajOptProblem) -> tuple[PathConstraint, ...]:
    """Return the problem's tool path constraint, its start and goal checked first.

    Raises
    ------
    ParameterError
        The start or goal breaks a tool constraint (naming it and the value).
    """
    if not problem.tool:
        return ()
    from youbot_opt.trajopt.tool import check_boundary_tool, tool_constraint

    states = [(w, s.q, s.velocity) for w, s in (("start", problem.start), ("goal", problem.goal))]
    check_boundary_tool(problem.robot, problem.tool, states)
    constraint = tool_constraint(problem.robot, problem.tool)
    return () if constraint is None else (constraint,)


def auto_transcription(problem: TrajOptProblem) -> str:
    """Choose the transcription of ``problem``: ``"radau"`` if its damping is stiff, else HS.

    The joint damping is stiff on a grid when its fastest relaxation rate
    (:func:`~youbot_opt.dynamics.numeric.damping_rate`, at the start and goal
    configurations) times the grid step exceeds
    :data:`~youbot_opt.dynamics.numeric.STIFF_RATIO`; the step is the
    problem's fixed duration, else the default guess's
    (:data:`~youbot_opt.trajopt.guess.DEFAULT_GUESS_DURATION`), over its
    intervals. The L-stable Radau IIA collocation then carries such a joint on
    its slow motion, where trapezoidal and Hermite-Simpson collocation keep an
    undamped spurious mode (docs/refinement.md, "Stiff joint damping");
    otherwise Hermite-Simpson (fewer variables; certified on coarser grids
    than the trapezoid).

    Parameters
    ----------
    problem : TrajOptProblem
        The problem (robot, damping flag, boundary states, knots, duration).

    Returns
    -------
    str
        ``"radau"`` or ``"hermite_simpson"``.
    """
    if not problem.damping:
        return "hermite_simpson"
    q = np.stack([problem.start.q, problem.goal.q])
    rate = damping_rate(problem.robot, q).rate  # [1/s]
    step = (problem.duration or DEFAULT_GUESS_DURATION) / (problem.n_knots - 1)  # [s]
    return "radau" if rate * step > STIFF_RATIO else "hermite_simpson"


def solve(
    problem: TrajOptProblem,
    *,
    method: str | Transcription = "trapezoidal",
    options: IpoptOptions | None = None,
    backend: str = "symbolic",
    beta: float = 0.5,
    bound_scale: float = 1.0,
    guess: GuessLike = None,
    start: BoundaryLike | None = None,
    goal: BoundaryLike | None = None,
    seed: int | None = None,
) -> TrajOptResult:
    """Build a :class:`TrajOptSolver` and solve once (see its parameters).

    Returns
    -------
    TrajOptResult
        The result; check ``result.success`` or call ``result.raise_for_status()``.
    """
    solver = TrajOptSolver(problem, method, options, backend)
    return solver.solve(
        beta=beta, bound_scale=bound_scale, guess=guess, start=start, goal=goal, seed=seed
    )
