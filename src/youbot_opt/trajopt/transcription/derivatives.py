r"""Exact NLP derivatives assembled from per-point dynamics kernels (the fast path).

The constraints ``g(x, A)`` of every collocation scheme are affine in the
accelerations ``A`` (one column per dynamics point, ``a_k = FD(q_k, v_k, tau_k)``)
and the objective does not involve ``A``; so the gradient, the constraint Jacobian
and the Lagrangian Hessian follow by the chain rule from three small per-point
kernels -- ``a``, ``dA/dz`` and ``sum_i w_i nabla^2 FD_i`` (:func:`dynamics_kernels`)
-- mapped over the points and optionally compiled to C (:func:`compile_kernels`).
:func:`structured_functions` returns them in ``nlpsol``'s ``grad_f``, ``jac_g`` and
``hess_lag`` signatures, assembled from one interval's stencil (:mod:`.stencil`) or
the whole SX graph; both are tested against CasADi's AD of the plain NLP.
Rationale: docs/design.md, "Module notes".
"""

from __future__ import annotations

import hashlib
import inspect
import itertools
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple, TypeVar

import casadi as ca

from youbot_opt.exceptions import TranscriptionError
from youbot_opt.trajopt.transcription.hermite_simpson import HermiteSimpsonCollocation
from youbot_opt.trajopt.transcription.radau import RadauCollocation
from youbot_opt.trajopt.transcription.stencil import (
    IntervalStencil,
    chain_rule,
    interval_stencil,
    stencil_functions,
)
from youbot_opt.trajopt.transcription.trapezoidal import TrapezoidalCollocation

if TYPE_CHECKING:
    from youbot_opt.trajopt.problem import TrajOptProblem
    from youbot_opt.trajopt.transcription.base import Transcription
    from youbot_opt.trajopt.transcription.path import PathConstraint

__all__ = [
    "NLPFunctions",
    "Kernels",
    "PathKernels",
    "cached_kernels",
    "cached_path_kernels",
    "compile_kernels",
    "compile_path_kernels",
    "derivation_index",
    "dynamics_kernels",
    "path_kernels",
    "stencil_of",
    "structured_functions",
]


class Kernels(NamedTuple):
    """Per-point dynamics kernels (CasADi Functions of one point)."""

    forward: ca.Function
    """``(q, v, tau) -> a``."""
    jacobian: ca.Function
    """``(q, v, tau) -> (a, J)`` with ``J = da/d(q, v, tau)`` of shape (nv, 3 nv)."""
    hessian: ca.Function
    """``(q, v, tau, w) -> H = sum_i w_i d^2 a_i / d(q, v, tau)^2`` (3 nv, 3 nv)."""


class PathKernels(NamedTuple):
    """Per-point kernels of one path constraint ``c(q, v)`` (CasADi Functions of one point)."""

    value: ca.Function
    """``(q, v) -> c`` (m,)."""
    jacobian: ca.Function
    """``(q, v) -> (c, J)`` with ``J = dc/dz`` of shape (m, dim z), ``z = (q, v)``, or
    ``z = q`` when ``c`` does not depend on ``v``."""
    hessian: ca.Function
    """``(q, v, w) -> H = sum_i w_i d^2 c_i / dz^2`` (dim z, dim z)."""


class NLPFunctions(NamedTuple):
    """The NLP and its exact derivatives in ``nlpsol``'s signatures."""

    nlp: ca.Function
    """``(x, p) -> (f, g)``."""
    grad_f: ca.Function
    """``(x, p) -> (f, grad_f_x)``."""
    jac_g: ca.Function
    """``(x, p) -> (g, jac_g_x)``."""
    hess_lag: ca.Function
    """``(x, p, lam_f, lam_g) -> triu_hess_gamma_x_x`` (upper triangle)."""


def dynamics_kernels(forward_dynamics: ca.Function) -> Kernels:
    """Value, Jacobian and weighted-Hessian kernels of an SX forward-dynamics Function.

    Parameters
    ----------
    forward_dynamics : casadi.Function
        ``(q[nv], v[nv], tau[nv]) -> a[nv]``, twice differentiable (SX).

    Returns
    -------
    Kernels
        The three per-point Functions (SX, not compiled).

    Raises
    ------
    TranscriptionError
        If the Function cannot be expanded to SX (e.g. a Callback backend).
    """
    try:
        fd = (
            forward_dynamics.expand()
            if not forward_dynamics.is_a("SXFunction")
            else forward_dynamics
        )
    except RuntimeError as exc:
        raise TranscriptionError(
            f"structured derivatives need an SX-expandable forward dynamics: {exc}"
        ) from exc
    nv = fd.size1_in(0)
    q, v, tau, w = (ca.SX.sym(name, nv) for name in ("q", "v", "tau", "w"))
    z = ca.vertcat(q, v, tau)
    a = fd(q, v, tau)
    jac = ca.jacobian(a, z)
    hess = ca.hessian(ca.dot(w, a), z)[0]
    opts = {"cse": True}
    return Kernels(
        forward=ca.Function("fd_value", [q, v, tau], [a], ["q", "v", "tau"], ["a"], opts),
        jacobian=ca.Function(
            "fd_jacobian", [q, v, tau], [a, ca.densify(jac)], ["q", "v", "tau"], ["a", "J"], opts
        ),
        hessian=ca.Function(
            "fd_hessian", [q, v, tau, w], [ca.densify(hess)], ["q", "v", "tau", "w"], ["H"], opts
        ),
    )


def derivation_index(function: ca.Function, *derive: Callable[..., object]) -> str | None:
    """Name what per-point kernels are derived from: ``function`` and the deriving code.

    The key :func:`youbot_opt.nlp.codegen.load_indexed` finds compiled kernels
    by without deriving them again: the serialised ``function`` (deterministic
    for one model) and the source of the functions that derive and compile
    the kernels; None when that source cannot be read (no index then).
    """
    try:
        code = "\0".join(inspect.getsource(f) for f in derive)
    except (OSError, TypeError):
        return None
    text = function.serialize()
    return hashlib.sha256(f"{code}\0{text}".encode()).hexdigest()


def cached_kernels(forward_dynamics: ca.Function) -> Kernels | None:
    """Return the compiled kernels of ``forward_dynamics`` if the cache has them, else None.

    Found by :func:`derivation_index` (the kernels are not derived: that and
    their code generation take longer than the load, about 0.7 s for ur5).
    """
    return _cached(Kernels, derivation_index(forward_dynamics, dynamics_kernels, _compiled))


def compile_kernels(
    kernels: Kernels,
    *,
    wait: bool | None = True,
    label: str | None = None,
    source: ca.Function | None = None,
) -> Kernels:
    """Compile the kernels to C, cached on disk (:func:`youbot_opt.nlp.codegen.compile_functions`).

    The missing ones are compiled in one batch: now (``wait`` True), in one
    background process (False), or now only when that is short (None: a
    two-link arm's, not the youBot's; docs/design.md). Returns ``kernels``
    itself (the same object, after the codegen warning) if any kernel cannot be compiled, or is
    not cached yet and is compiling in the background for the next build
    (``label`` names it in the log). The compiled ``forward`` kernel carries its
    compiled Jacobian (first derivatives), so an NLP Function built on it can be
    handed to ``nlpsol``, which differentiates it once (reverse mode) when it is
    created; the other two compiled kernels have no derivatives. ``source``: the
    forward dynamics the kernels were derived from, which indexes them for
    :func:`cached_kernels`.
    """
    index = None if source is None else derivation_index(source, dynamics_kernels, _compiled)
    return _compiled(kernels, wait=wait, label=label, index=index)


_K = TypeVar("_K", "Kernels", "PathKernels")


def _cached(kind: type[_K], index: str | None) -> _K | None:
    """Return the compiled kernels of ``kind`` indexed by ``index`` if the cache has them."""
    from youbot_opt.nlp.codegen import load_indexed

    found = None if index is None else load_indexed(index)
    return None if found is None or len(found) != len(kind._fields) else kind(*found)


def _compiled(kernels: _K, *, wait: bool | None, label: str | None, index: str | None) -> _K:
    """Return ``kernels`` compiled (the first, the value, with its Jacobian), else themselves."""
    from youbot_opt.nlp.codegen import compile_functions

    compiled = type(kernels)(
        *compile_functions(
            kernels,
            wait=wait,
            label=label,
            with_jacobian=[k is kernels[0] for k in kernels],
            index=index,
        )
    )
    if any(c is k for c, k in zip(compiled, kernels, strict=True)):
        return kernels
    return compiled


def _block_diagonal(values: Any, rows: int, cols: int, count: int) -> Any:
    """Block-diagonal matrix of ``count`` dense ``rows x cols`` blocks stored side by side."""
    pattern = ca.diagcat(*[ca.Sparsity.dense(rows, cols)] * count)
    return ca.SX(pattern, ca.vec(values))


def path_kernels(constraint: PathConstraint) -> PathKernels:
    """Value, Jacobian and weighted-Hessian kernels of a path constraint's ``c(q, v)``.

    Parameters
    ----------
    constraint : PathConstraint
        Its ``function`` maps ``(q (nv,), v (nv,)) -> c (m,)`` (SX, twice differentiable).

    Returns
    -------
    PathKernels
        The three per-point Functions (SX, not compiled), named after the constraint.
    """
    fn = constraint.function
    if not fn.is_a("SXFunction"):
        fn = fn.expand()
    nv, m = fn.size1_in(0), fn.size1_out(0)
    q, v, w = ca.SX.sym("q", nv), ca.SX.sym("v", nv), ca.SX.sym("w", m)
    c = fn(q, v)
    # derivatives in (q, v), or in q alone when c ignores v (clearance): no structural
    # zeros of dc/dv in the NLP's Jacobian and Hessian, nor in IPOPT's factorisation
    z = ca.vertcat(q, v) if ca.depends_on(c, v) else q
    opts = {"cse": True}
    name = f"path_{constraint.name}"
    return PathKernels(
        value=ca.Function(f"{name}_value", [q, v], [c], ["q", "v"], ["c"], opts),
        jacobian=ca.Function(
            f"{name}_jacobian",
            [q, v],
            [c, ca.densify(ca.jacobian(c, z))],
            ["q", "v"],
            ["c", "J"],
            opts,
        ),  # fmt: skip
        hessian=ca.Function(
            f"{name}_hessian",
            [q, v, w],
            [ca.densify(ca.hessian(ca.dot(w, c), z)[0])],
            ["q", "v", "w"],
            ["H"],
            opts,
        ),  # fmt: skip
    )


def cached_path_kernels(constraint: PathConstraint) -> PathKernels | None:
    """Return the compiled kernels of a path constraint if the cache has them, else None.

    As :func:`cached_kernels`, keyed by the constraint's Function.
    """
    index = derivation_index(constraint.function, path_kernels, _compiled)
    return _cached(PathKernels, index)


def compile_path_kernels(
    kernels: PathKernels,
    *,
    wait: bool | None = True,
    label: str | None = None,
    source: PathConstraint | None = None,
) -> PathKernels:
    """Compile a path constraint's kernels to C, as :func:`compile_kernels` the dynamics'.

    Returns ``kernels`` itself when any of the three is not compiled (yet);
    ``source``, the constraint they were derived from, indexes them for
    :func:`cached_path_kernels`.
    """
    index = None if source is None else derivation_index(source.function, path_kernels, _compiled)
    return _compiled(kernels, wait=wait, label=label, index=index)


class _PointSet(NamedTuple):
    """One kernel mapped over the points of one group: the dynamics', or a path row block's.

    ``values`` (rows, points), ``jacobians`` (rows, width points) and ``hessians``
    (width, width points) are the SX symbols standing for the kernel outputs;
    ``select`` picks the points' coordinates ``z`` the derivatives are taken in
    (width each, point-major) out of ``x``, ``arguments`` the kernels' inputs
    (``n_in`` blocks of ``nv`` each, point-major).
    """

    points: int
    rows: int
    width: int
    select: ca.DM
    arguments: ca.DM
    n_in: int
    values: ca.SX
    jacobians: ca.SX
    hessians: ca.SX
    value: ca.Function
    jacobian: ca.Function
    hessian: ca.Function


def stencil_of(
    method: Transcription,
    problem: TrajOptProblem,
    paths: tuple[PathConstraint, ...] = (),
    path_kernels: tuple[PathKernels, ...] | None = None,
) -> IntervalStencil | None:
    """Return one interval of ``method`` differentiated once, or None where it does not apply.

    It applies to the built-in schemes (not to subclasses, which may change the
    rows) whose path rows come from their kernels (``path_kernels``) or that
    have none; it does not depend on the grid or the number of knots, so one
    serves every refinement round (:func:`structured_functions`).
    """
    schemes = (TrapezoidalCollocation, HermiteSimpsonCollocation, RadauCollocation)
    if type(method) not in schemes or (paths and path_kernels is None):
        return None
    return interval_stencil(method, problem, paths, [True] * len(paths))


def structured_functions(
    method: Transcription,
    problem: TrajOptProblem,
    kernels: Kernels,
    *,
    values: Kernels | None = None,
    paths: tuple[PathConstraint, ...] = (),
    path_kernels: tuple[PathKernels, ...] | None = None,
    stencil: IntervalStencil | None = None,
    per_interval: bool = True,
) -> NLPFunctions:
    """Build the NLP and its exact derivatives from per-point kernels.

    Parameters
    ----------
    method : Transcription
        The collocation scheme.
    problem : TrajOptProblem
        The problem.
    kernels : Kernels
        Kernels used inside the derivative Functions (possibly compiled).
    values : Kernels, optional
        Kernels for the plain ``nlp`` Function (default ``kernels``), whose
        ``forward`` must be differentiable by CasADi (the SX kernel, or a
        compiled one from :func:`compile_kernels`, which carries its Jacobian).
    paths : tuple of PathConstraint
        Path constraints of the NLP (SX Functions of ``(q, v)``).
    path_kernels : tuple of PathKernels, optional
        One per path constraint (:func:`path_kernels`, possibly compiled): each
        constraint's rows at a group of points that are plain variables (the
        knots; Hermite-Simpson's midpoints; Radau's stages) are then assembled
        from them like the dynamics; elsewhere (the trapezoid's midpoints, an
        expression of the knots) and without them, from ``x`` directly in SX.
    stencil : IntervalStencil, optional
        :func:`stencil_of` this scheme, problem and path constraints, reused
        across grids (derived here when omitted).
    per_interval : bool
        Assemble from one interval's stencil mapped over the grid
        (:mod:`~youbot_opt.trajopt.transcription.stencil`) when the scheme allows
        (True, default), else differentiate the whole NLP's SX graph: the same
        NLP and derivatives (the stencil's route costs no symbolic work at the
        NLP's size).

    Returns
    -------
    NLPFunctions
        ``nlp``, ``grad_f``, ``jac_g`` and ``hess_lag``.
    """
    values = kernels if values is None else values
    if per_interval:
        if stencil is None:
            stencil = stencil_of(method, problem, paths, path_kernels)
        if stencil is not None:
            return NLPFunctions(
                *stencil_functions(
                    stencil, method, problem, kernels, values.forward, path_kernels or ()
                )
            )
    nv, n = problem.nv, problem.n_knots
    blocks = method.variable_blocks(nv, n)
    sym = {name: ca.SX.sym(name, width, count) for name, width, count in blocks}
    x = ca.vertcat(*[ca.vec(sym[name]) for name, _, _ in blocks])
    beta = ca.SX.sym("beta")
    points = method.dynamics_points(sym)
    groups = list(points)
    counts = {g: points[g][0].size2() for g in groups}
    accel = {g: ca.SX.sym(f"a_{g}", nv, counts[g]) for g in groups}

    def selection(columns: Any) -> ca.DM:
        return ca.evalf(ca.jacobian(ca.vec(ca.vertcat(*columns)), x))

    sets = [
        _PointSet(
            points=counts[g],
            rows=nv,
            width=3 * nv,
            select=selection(points[g]),
            arguments=selection(points[g]),
            n_in=3,
            values=accel[g],
            jacobians=ca.SX.sym(f"J_{g}", nv, 3 * nv * counts[g]),
            hessians=ca.SX.sym(f"H_{g}", 3 * nv, 3 * nv * counts[g]),
            value=values.forward,
            jacobian=kernels.jacobian,
            hessian=kernels.hessian,
        )  # fmt: skip
        for g in groups
    ]
    path_values: dict[str, ca.SX] = {}
    if path_kernels is not None and paths:
        if len(path_kernels) != len(paths):
            raise TranscriptionError(
                f"{len(path_kernels)} path kernels for {len(paths)} path constraints"
            )
        for constraint, pk in zip(paths, path_kernels, strict=True):
            for grp, (qp, vp) in method.path_points(sym).items():
                if not ca.vertcat(qp, vp).is_valid_input():  # an expression: SX below
                    continue
                count, m, name = qp.size2(), constraint.width, f"{constraint.name}_{grp}"
                width = int(pk.jacobian.size2_out(1))  # nv (q) or 2 nv (q, v)
                path_values[name] = ca.SX.sym(f"c_{name}", m, count)
                sets.append(
                    _PointSet(
                        points=count,
                        rows=m,
                        width=width,
                        select=selection((qp, vp) if width == 2 * nv else (qp,)),
                        arguments=selection((qp, vp)),
                        n_in=2,
                        values=path_values[name],
                        jacobians=ca.SX.sym(f"Jc_{name}", m, width * count),
                        hessians=ca.SX.sym(f"Hc_{name}", width, width * count),
                        value=pk.value,
                        jacobian=pk.jacobian,
                        hessian=pk.hessian,
                    )  # fmt: skip
                )
    parts = method.expressions(problem, sym, accel, beta, paths, path_values or None)
    f, g = parts.f, parts.g
    lam_g = ca.SX.sym("lam_g", g.numel())
    lam_f = ca.SX.sym("lam_f")

    # g = g(x, A, C): affine in the kernel outputs (accelerations A, path rows C)
    a_all = ca.vertcat(*[ca.vec(ps.values) for ps in sets])
    j_ax = ca.vertcat(
        *[
            ca.mtimes(_block_diagonal(ps.jacobians, ps.rows, ps.width, ps.points), ps.select)
            for ps in sets
        ]
    )
    jac_g, hess, grad_a = chain_rule(g, x, a_all, j_ax, lam_f * f + ca.dot(lam_g, g))
    for ps in sets:
        block = _block_diagonal(ps.hessians, ps.width, ps.width, ps.points)
        hess = hess + ca.mtimes(ca.mtimes(ps.select.T, block), ps.select)
    offsets = list(itertools.accumulate(ps.rows * ps.points for ps in sets))
    weights = ca.vertsplit(grad_a, [0, *offsets])
    weights = [ca.reshape(w, ps.rows, ps.points) for w, ps in zip(weights, sets, strict=True)]

    v_in = [ps.values for ps in sets]
    j_in = [ps.jacobians for ps in sets]
    h_in = [ps.hessians for ps in sets]
    f_sx = ca.Function("nlp_f_sx", [x, beta], [f])  # f never involves A: no dynamics
    g_sx = ca.Function("nlp_g_sx", [x, *v_in, beta], [g])
    grad_sx = ca.Function("nlp_grad_f_sx", [x, beta], [f, ca.gradient(f, x)])
    jac_sx = ca.Function("nlp_jac_g_sx", [x, *v_in, *j_in, beta], [g, jac_g])
    weight_sx = ca.Function("nlp_weights_sx", [x, *v_in, lam_g, lam_f, beta], weights)
    hess_sx = ca.Function(
        "nlp_hess_sx", [x, *v_in, *j_in, *h_in, lam_g, lam_f, beta], [ca.triu(hess)]
    )

    # MX wrappers: slice the point inputs out of x, map the kernels, assemble.
    xm, pm = ca.MX.sym("x", x.numel()), ca.MX.sym("p")
    lfm, lgm = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", g.numel())

    def inputs(ps: _PointSet) -> list[Any]:
        z = ca.reshape(ca.mtimes(ps.arguments, xm), ps.n_in * nv, ps.points)
        return ca.vertsplit(z, list(range(0, ps.n_in * nv + 1, nv)))

    zs = [inputs(ps) for ps in sets]
    vals = [ps.value.map(ps.points)(*z) for ps, z in zip(sets, zs, strict=True)]
    f_val, g_val = f_sx(xm, pm), g_sx(xm, *vals, pm)
    jac_out = [ps.jacobian.map(ps.points)(*z) for ps, z in zip(sets, zs, strict=True)]
    v_k = [out[0] for out in jac_out]
    j_k = [out[1] for out in jac_out]
    g_k, jac_val = jac_sx(xm, *v_k, *j_k, pm)
    w_out = weight_sx(xm, *v_k, lgm, lfm, pm)
    w_k: list[Any] = [w_out] if len(sets) == 1 else list(w_out)
    h_k = [ps.hessian.map(ps.points)(*z, w) for ps, z, w in zip(sets, zs, w_k, strict=True)]
    f_g, grad_val = grad_sx(xm, pm)
    return NLPFunctions(
        nlp=ca.Function("nlp", [xm, pm], [f_val, g_val], ["x", "p"], ["f", "g"]),
        grad_f=ca.Function("nlp_grad_f", [xm, pm], [f_g, grad_val], ["x", "p"], ["f", "grad_f_x"]),
        jac_g=ca.Function("nlp_jac_g", [xm, pm], [g_k, jac_val], ["x", "p"], ["g", "jac_g_x"]),
        hess_lag=ca.Function(
            "nlp_hess_l",
            [xm, pm, lfm, lgm],
            [hess_sx(xm, *v_k, *j_k, *h_k, lgm, lfm, pm)],
            ["x", "p", "lam_f", "lam_g"],
            ["triu_hess_gamma_x_x"],
        ),
    )
