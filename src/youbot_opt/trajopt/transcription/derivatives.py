r"""Exact NLP derivatives assembled from per-point dynamics kernels (the fast path).

The constraints ``g(x, A)`` of every collocation scheme are affine in the
accelerations ``A`` (one column per dynamics point, ``a_k = FD(q_k, v_k, tau_k)``)
and the objective does not involve ``A``; so the gradient, the constraint Jacobian
and the Lagrangian Hessian follow by the chain rule from three small per-point
kernels -- ``a``, ``dA/dz`` and ``sum_i w_i nabla^2 FD_i`` (:func:`dynamics_kernels`)
-- mapped over the points and optionally compiled to C (:func:`compile_kernels`).
:func:`structured_functions` returns them with the signatures of ``nlpsol``'s
``grad_f``, ``jac_g`` and ``hess_lag`` options; they are tested against CasADi's
own derivatives of the plain NLP. Derivation and rationale: docs/design.md,
"Module notes".
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import casadi as ca

from youbot_opt.exceptions import TranscriptionError

if TYPE_CHECKING:
    from youbot_opt.trajopt.problem import TrajOptProblem
    from youbot_opt.trajopt.transcription.base import Transcription
    from youbot_opt.trajopt.transcription.path import PathConstraint

__all__ = [
    "NLPFunctions",
    "Kernels",
    "compile_kernels",
    "dynamics_kernels",
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


def compile_kernels(
    kernels: Kernels, *, wait: bool | None = True, label: str | None = None
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
    created; the other two compiled kernels have no derivatives.
    """
    from youbot_opt.nlp.codegen import compile_functions

    compiled = Kernels(
        *compile_functions(
            kernels, wait=wait, label=label, with_jacobian=[k is kernels.forward for k in kernels]
        )
    )
    if any(c is k for c, k in zip(compiled, kernels, strict=True)):
        return kernels
    return compiled


def _block_diagonal(values: Any, rows: int, cols: int, count: int) -> Any:
    """Block-diagonal matrix of ``count`` dense ``rows x cols`` blocks stored side by side."""
    pattern = ca.diagcat(*[ca.Sparsity.dense(rows, cols)] * count)
    return ca.SX(pattern, ca.vec(values))


def structured_functions(
    method: Transcription,
    problem: TrajOptProblem,
    kernels: Kernels,
    *,
    values: Kernels | None = None,
    paths: tuple[PathConstraint, ...] = (),
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
        Path constraints of the NLP (SX Functions of ``(q, v)``; their exact
        derivatives come from ``x`` directly, as they involve no dynamics).

    Returns
    -------
    NLPFunctions
        ``nlp``, ``grad_f``, ``jac_g`` and ``hess_lag``.
    """
    values = kernels if values is None else values
    nv, n = problem.nv, problem.n_knots
    blocks = method.variable_blocks(nv, n)
    sym = {name: ca.SX.sym(name, width, count) for name, width, count in blocks}
    x = ca.vertcat(*[ca.vec(sym[name]) for name, _, _ in blocks])
    beta = ca.SX.sym("beta")
    points = method.dynamics_points(sym)
    groups = list(points)
    counts = {g: points[g][0].size2() for g in groups}
    accel = {g: ca.SX.sym(f"a_{g}", nv, counts[g]) for g in groups}
    jac_sym = {g: ca.SX.sym(f"J_{g}", nv, 3 * nv * counts[g]) for g in groups}
    hess_sym = {g: ca.SX.sym(f"H_{g}", 3 * nv, 3 * nv * counts[g]) for g in groups}
    parts = method.expressions(problem, sym, accel, beta, paths)
    f, g = parts.f, parts.g
    lam_g = ca.SX.sym("lam_g", g.numel())
    lam_f = ca.SX.sym("lam_f")

    # Selection z = P x of each group's point states, point-major (q_k, v_k, tau_k).
    select = {grp: ca.evalf(ca.jacobian(ca.vec(ca.vertcat(*points[grp])), x)) for grp in groups}
    a_all = ca.vertcat(*[ca.vec(accel[grp]) for grp in groups])
    j_ax = ca.vertcat(
        *[
            ca.mtimes(_block_diagonal(jac_sym[grp], nv, 3 * nv, counts[grp]), select[grp])
            for grp in groups
        ]
    )
    jac_g = ca.jacobian(g, x) + ca.mtimes(ca.jacobian(g, a_all), j_ax)

    lag = lam_f * f + ca.dot(lam_g, g)
    grad_a = ca.gradient(lag, a_all)
    hess = ca.hessian(lag, x)[0]
    cross = ca.mtimes(j_ax.T, ca.jacobian(grad_a, x))
    hess = hess + cross + cross.T
    l_aa = ca.jacobian(grad_a, a_all)
    if l_aa.nnz() > 0:  # not for collocation (g is affine in A); kept for generality
        hess = hess + ca.mtimes(ca.mtimes(j_ax.T, l_aa), j_ax)
    for grp in groups:
        block = _block_diagonal(hess_sym[grp], 3 * nv, 3 * nv, counts[grp])
        hess = hess + ca.mtimes(ca.mtimes(select[grp].T, block), select[grp])
    weights = ca.vertsplit(grad_a, [0, *_offsets(nv, counts, groups)])
    weights = [ca.reshape(w, nv, counts[grp]) for w, grp in zip(weights, groups, strict=True)]

    a_in = [accel[grp] for grp in groups]
    j_in = [jac_sym[grp] for grp in groups]
    h_in = [hess_sym[grp] for grp in groups]
    f_sx = ca.Function("nlp_f_sx", [x, beta], [f])  # f never involves A: no dynamics
    g_sx = ca.Function("nlp_g_sx", [x, *a_in, beta], [g])
    grad_sx = ca.Function("nlp_grad_f_sx", [x, beta], [f, ca.gradient(f, x)])
    jac_sx = ca.Function("nlp_jac_g_sx", [x, *a_in, *j_in, beta], [g, jac_g])
    weight_sx = ca.Function("nlp_weights_sx", [x, *a_in, lam_g, lam_f, beta], weights)
    hess_sx = ca.Function(
        "nlp_hess_sx", [x, *a_in, *j_in, *h_in, lam_g, lam_f, beta], [ca.triu(hess)]
    )

    # MX wrappers: slice the point states out of x, map the kernels, assemble.
    xm, pm = ca.MX.sym("x", x.numel()), ca.MX.sym("p")
    lfm, lgm = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", g.numel())

    def states(grp: str) -> list[Any]:
        z = ca.reshape(ca.mtimes(ca.DM(select[grp]), xm), 3 * nv, counts[grp])
        return [z[:nv, :], z[nv : 2 * nv, :], z[2 * nv :, :]]

    zs = {grp: states(grp) for grp in groups}
    a_val = [values.forward.map(counts[grp])(*zs[grp]) for grp in groups]
    f_val, g_val = f_sx(xm, pm), g_sx(xm, *a_val, pm)
    jac_out = {grp: kernels.jacobian.map(counts[grp])(*zs[grp]) for grp in groups}
    a_k = [jac_out[grp][0] for grp in groups]
    j_k = [jac_out[grp][1] for grp in groups]
    g_k, jac_val = jac_sx(xm, *a_k, *j_k, pm)
    w_out = weight_sx(xm, *a_k, lgm, lfm, pm)
    w_k: list[Any] = [w_out] if len(groups) == 1 else list(w_out)
    h_k = [
        kernels.hessian.map(counts[grp])(*zs[grp], w) for grp, w in zip(groups, w_k, strict=True)
    ]
    f_g, grad_val = grad_sx(xm, pm)
    return NLPFunctions(
        nlp=ca.Function("nlp", [xm, pm], [f_val, g_val], ["x", "p"], ["f", "g"]),
        grad_f=ca.Function("nlp_grad_f", [xm, pm], [f_g, grad_val], ["x", "p"], ["f", "grad_f_x"]),
        jac_g=ca.Function("nlp_jac_g", [xm, pm], [g_k, jac_val], ["x", "p"], ["g", "jac_g_x"]),
        hess_lag=ca.Function(
            "nlp_hess_l",
            [xm, pm, lfm, lgm],
            [hess_sx(xm, *a_k, *j_k, *h_k, lgm, lfm, pm)],
            ["x", "p", "lam_f", "lam_g"],
            ["triu_hess_gamma_x_x"],
        ),
    )


def _offsets(nv: int, counts: dict[str, int], groups: list[str]) -> list[int]:
    """Cumulative row offsets of the groups' accelerations in the stacked ``A``."""
    out, total = [], 0
    for grp in groups:
        total += nv * counts[grp]
        out.append(total)
    return out
