r"""NLP derivatives from one interval's stencil, scattered over the grid by index maps.

Each block of ``g`` of the built-in schemes is one column per interval (a function
of its stencil: two knots, interior points, their accelerations, the step
``h_k = r_k dt``), one column at the first or last interval (boundary rows, Radau's
start torque) or a path constraint's rows at variable points. The chain rule of
:mod:`~youbot_opt.trajopt.transcription.derivatives` is applied once, in SX, to one
interval (the 2-knot NLP, ``dt`` standing for ``h``: :func:`interval_stencil`, reused
across grids); :func:`stencil_functions` maps it over the intervals and scatters the
outputs into ``g``, its Jacobian and the Lagrangian Hessian by numeric index maps.

    fns = stencil_functions(interval_stencil(method, problem, (), []), method, ...)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import casadi as ca
import numpy as np

from youbot_opt.exceptions import TranscriptionError
from youbot_opt.trajopt.objectives import duration, objective_value
from youbot_opt.trajopt.transcription.scatter import Indices, SparseEntries, upper_entries

if TYPE_CHECKING:
    from youbot_opt.trajopt.problem import TrajOptProblem
    from youbot_opt.trajopt.transcription.base import Transcription
    from youbot_opt.trajopt.transcription.path import PathConstraint

__all__ = ["IntervalStencil", "chain_rule", "interval_stencil", "stencil_functions"]

_Ints = Indices


class _RowSet(NamedTuple):
    """Derivative Functions of some of one interval's rows, and their local patterns.

    Local coordinates ``z = (s, h)``: the stencil's variables ``s`` and the step ``h``
    (index ``len(s)``). ``jac_rows``/``jac_cols``: the Jacobian's nonzeros in the
    order ``jacobian`` returns them; ``hess_rows``/``hess_cols`` (``rows <= cols``)
    likewise for the upper triangle of the Lagrangian Hessian without the kernels'
    Hessians, whose weights ``hessian`` returns (``(nv, points)``).
    """

    rows: _Ints
    value: ca.Function
    jacobian: ca.Function
    hessian: ca.Function
    jac_rows: _Ints
    jac_cols: _Ints
    hess_rows: _Ints
    hess_cols: _Ints


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class IntervalStencil:
    """One interval of a scheme, differentiated once: what :func:`stencil_functions` maps.

    Attributes
    ----------
    nv : int
        Joints.
    local_blocks : list of (str, int, int)
        The 2-knot NLP's variable blocks (``dt`` last): count 2 for knot blocks,
        1 for interval blocks.
    groups : list of (str, int, ndarray)
        Dynamics groups: name, local count (2: one point per knot, 1: one per
        interval) and the local indices of each local point's ``(q, v, tau)``,
        shape ``(count, 3 nv)``.
    path_groups : list of (str, str, int, ndarray, int)
        Path-constraint blocks from kernels: block name, group, local count, the
        local indices of each point's ``(q, v)`` (``(count, 2 nv)``) and the index
        of the constraint.
    g_blocks : list of (str, int, str)
        Blocks of ``g`` in order: name, width, kind (``"interval"``, ``"first"``,
        ``"last"`` or ``"point"``).
    interval, first, last : _RowSet or None
        The rows of each kind (local row indices into the 2-knot ``g``).
    points : ndarray
        ``(group index, local column)`` of each of the interval's dynamics points, in
        the order of the Functions' acceleration inputs.
    """

    nv: int
    local_blocks: list[tuple[str, int, int]]
    groups: list[tuple[str, int, _Ints]]
    path_groups: list[tuple[str, str, int, _Ints, int]]
    g_blocks: list[tuple[str, int, str]]
    interval: _RowSet | None
    first: _RowSet | None
    last: _RowSet | None
    points: _Ints


def _indices(x: ca.SX, expr: ca.SX) -> _Ints:
    """Positions in ``x`` of the symbols of ``expr`` (plain variables), column-major."""
    fn = ca.Function("indices", [x], [ca.vec(expr)])
    return np.rint(np.asarray(fn(np.arange(x.numel(), dtype=float))).ravel()).astype(np.int64)


def _triplet(m: ca.SX) -> tuple[_Ints, _Ints]:
    rows, cols = m.sparsity().get_triplet()
    return np.asarray(rows, dtype=np.int64), np.asarray(cols, dtype=np.int64)


def chain_rule(g: ca.SX, x: ca.SX, a: ca.SX, j_ax: ca.SX, lag: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
    """Return ``dg/dx``, ``d2 lag/dx2`` and ``d lag/da`` of expressions in ``x`` and ``a(x)``.

    ``g`` and ``lag`` are written in the free symbols ``x`` and ``a``; ``a``
    stands for the per-point kernels' outputs, whose Jacobian ``j_ax`` is given.
    The Hessian leaves out ``sum_i (d lag/d a_i) d2 a_i/dx2`` (the kernels' own
    Hessians, which the caller adds weighted by ``d lag/da``):
    ``lag_xx + J^T lag_ax + lag_xa J + J^T lag_aa J``.

    Parameters
    ----------
    g : casadi.SX
        The rows, a column.
    x, a : casadi.SX
        The variables and the kernel outputs (columns of symbols).
    j_ax : casadi.SX
        ``da/dx``, sparse.
    lag : casadi.SX
        A scalar (the rows weighted by their multipliers, plus the objective's term).

    Returns
    -------
    jac : casadi.SX
        ``dg/dx``.
    hess : casadi.SX
        ``d2 lag/dx2`` without the kernels' second derivatives (symmetric, full).
    grad_a : casadi.SX
        ``d lag/da``: the weights of the kernels' Hessians.
    """
    jac = ca.jacobian(g, x) + ca.mtimes(ca.jacobian(g, a), j_ax)
    grad_a = ca.gradient(lag, a)
    hess = ca.hessian(lag, x)[0]
    cross = ca.mtimes(j_ax.T, ca.jacobian(grad_a, x))
    hess = hess + cross + cross.T
    l_aa = ca.jacobian(grad_a, a)
    if l_aa.nnz() > 0:  # not for collocation (g is affine in a); kept for generality
        hess = hess + ca.mtimes(ca.mtimes(j_ax.T, l_aa), j_ax)
    return jac, hess, grad_a


def _row_set(
    rows: _Ints, g: ca.SX, s: ca.SX, h: ca.SX, a: ca.SX, jac: ca.SX, z_of_point: _Ints
) -> _RowSet:
    """Apply the chain rule of the per-point kernels to ``rows`` of the local ``g``."""
    nv, npts = a.size1(), a.size2()
    lam = ca.SX.sym("lam", rows.size)
    gr = g[rows.tolist()] if rows.size else ca.SX(0, 1)
    z = ca.vertcat(s, h)
    # d vec(a) / dz: each point's kernel Jacobian (nv x 3 nv) at its (q, v, tau) in s
    r_idx = np.repeat(np.arange(npts * nv).reshape(npts, nv), 3 * nv, axis=1).ravel()
    c_idx = np.repeat(z_of_point, nv, axis=0).ravel()
    # jac is (nv, 3 nv npts): entry (i, p 3nv + c) at column-major position (p 3nv + c) nv + i
    src = (
        (np.arange(npts)[:, None, None] * 3 * nv + np.arange(3 * nv)[None, None, :]) * nv
        + np.arange(nv)[None, :, None]
    ).ravel()
    sp, mapping = ca.Sparsity.triplet(npts * nv, z.numel(), r_idx.tolist(), c_idx.tolist(), True)
    order = np.empty(src.size, dtype=np.int64)
    order[np.asarray(mapping, dtype=np.int64)] = src
    j_az = ca.SX(sp, ca.vec(jac)[order.tolist()])
    jac_z, hess, grad_a = chain_rule(gr, z, ca.vec(a), j_az, ca.dot(lam, gr))
    upper = ca.triu(hess)
    jr, jc = _triplet(jac_z)
    hr, hc = _triplet(upper)
    opts = {"cse": True}
    names = ["s", "a", "h"]
    return _RowSet(
        rows=rows,
        value=ca.Function("stencil_g", [s, a, h], [gr], names, ["g"], opts),
        jacobian=ca.Function(
            "stencil_jac",
            [s, a, jac, h],
            [gr, jac_z.nz[:]],
            ["s", "a", "J", "h"],
            ["g", "nz"],
            opts,
        ),
        hessian=ca.Function(
            "stencil_hess",
            [s, a, jac, lam, h],
            [upper.nz[:], ca.reshape(grad_a, nv, npts)],
            ["s", "a", "J", "lam", "h"],
            ["nz", "w"],
            opts,
        ),
        jac_rows=jr,
        jac_cols=jc,
        hess_rows=hr,
        hess_cols=hc,
    )


def interval_stencil(
    method: Transcription,
    problem: TrajOptProblem,
    paths: tuple[PathConstraint, ...],
    kernel_paths: Sequence[bool],
) -> IntervalStencil | None:
    """Differentiate one interval of ``method``; None if its rows are not per interval.

    Parameters
    ----------
    method : Transcription
        The scheme (its grid is irrelevant: the step ``h`` is a symbol).
    problem : TrajOptProblem
        The problem (its joints; the NLP's size is irrelevant).
    paths : tuple of PathConstraint
        The NLP's path constraints.
    kernel_paths : sequence of bool
        Per path constraint: whether its rows at points that are variables come
        from its per-point kernels (else they are SX rows of the stencil).
    """
    nv = problem.nv
    uniform = type(method)()
    local = dataclasses.replace(problem, n_knots=2)
    three = dataclasses.replace(problem, n_knots=3)

    def transcribe(prob: TrajOptProblem) -> tuple[Any, ...]:
        blocks = uniform.variable_blocks(nv, prob.n_knots)
        sym = {name: ca.SX.sym(name, w, c) for name, w, c in blocks}
        x = ca.vertcat(*[ca.vec(sym[name]) for name, _, _ in blocks])
        points = uniform.dynamics_points(sym)
        accel = {g: ca.SX.sym(f"a_{g}", nv, p[0].size2()) for g, p in points.items()}
        values: dict[str, ca.SX] = {}
        for constraint, use in zip(paths, kernel_paths, strict=True):
            if not use:
                continue
            for grp, (qp, vp) in uniform.path_points(sym).items():
                if ca.vertcat(qp, vp).is_valid_input():
                    name = f"{constraint.name}_{grp}"
                    values[name] = ca.SX.sym(name, constraint.width, qp.size2())
        beta = ca.SX.sym("beta")
        parts = uniform.expressions(prob, sym, accel, beta, paths, values or None)
        return blocks, sym, x, points, accel, values, parts

    blocks, sym, x, points, accel, values, parts = transcribe(local)
    _, _, x3, _, accel3, values3, parts3 = transcribe(three)
    if not all(ca.vertcat(*p).is_valid_input() for p in points.values()):
        return None
    groups = [
        (g, p[0].size2(), _indices(x, ca.vertcat(*p)).reshape(-1, 3 * nv))
        for g, p in points.items()
    ]
    # a point's (q, v, tau) column by column: _indices gives vec(vertcat(q, v, tau))
    path_groups = []
    for ic, (constraint, use) in enumerate(zip(paths, kernel_paths, strict=True)):
        if not use:
            continue
        for grp, (qp, vp) in uniform.path_points(sym).items():
            name = f"{constraint.name}_{grp}"
            if name in values:
                idx = _indices(x, ca.vertcat(qp, vp)).reshape(-1, 2 * nv)
                path_groups.append((name, grp, qp.size2(), idx, ic))
    # kinds of g's blocks from the 3-knot NLP: 2 columns per interval, 1 at an end
    layout3 = parts3.constraints
    a3 = ca.vertcat(*[ca.vec(a) for a in accel3.values()], *[ca.vec(c) for c in values3.values()])
    stencil3 = [set(_local_to_global(blocks, nv, 3, k).tolist()) for k in (0, 1)]
    g_blocks: list[tuple[str, int, str]] = []
    for name, block in layout3.blocks.items():
        if name in values:
            g_blocks.append((name, block.width, "point"))
        elif block.count == 2:
            g_blocks.append((name, block.width, "interval"))
        elif block.count == 1:
            expr = parts3.g[block.offset : block.offset + block.size]
            if ca.depends_on(expr, a3):
                return None
            used = set(_triplet(ca.jacobian(expr, x3))[1].tolist())
            if used <= stencil3[0] and not used <= stencil3[1]:
                g_blocks.append((name, block.width, "first"))
            elif used <= stencil3[1] and not used <= stencil3[0]:
                g_blocks.append((name, block.width, "last"))
            else:
                return None
        else:
            return None
    # the 2-knot NLP's g in the same block order; rows of each kind
    offsets = parts.constraints.blocks
    kinds: dict[str, list[int]] = {"interval": [], "first": [], "last": []}
    for name, width, kind in g_blocks:
        if kind != "point":
            off = offsets[name].offset
            kinds[kind].extend(range(off, off + width))
    s = x[: x.numel() - 1]
    h = x[x.numel() - 1]
    order = list(points)
    a = ca.horzcat(*[accel[g] for g in order])
    jac = ca.SX.sym("J", nv, 3 * nv * a.size2())
    z_of_point = np.concatenate([idx for _, _, idx in groups])
    pts = np.array([(i, c) for i, (_, count, _) in enumerate(groups) for c in range(count)])
    sets = {
        kind: None if not rows else _row_set(np.array(rows), parts.g, s, h, a, jac, z_of_point)
        for kind, rows in kinds.items()
    }
    return IntervalStencil(
        nv=nv,
        local_blocks=blocks,
        groups=groups,
        path_groups=path_groups,
        g_blocks=g_blocks,
        interval=sets["interval"],
        first=sets["first"],
        last=sets["last"],
        points=pts,
    )


def _local_to_global(blocks: list[tuple[str, int, int]], nv: int, n_knots: int, k: Any) -> Any:
    """Global indices in ``x`` of the local (2-knot) variables of interval(s) ``k``.

    ``k`` an int: shape ``(n_local,)``; an array: ``(len(k), n_local)``. A local
    block of count 2 is a knot block (global count ``n_knots``), of count 1 an
    interval block (``n_knots - 1``); ``dt`` (last) maps to the global ``dt``.
    """
    k_arr = np.atleast_1d(np.asarray(k, dtype=np.int64))[:, None]
    parts = []
    offset = 0
    for _name, width, count in blocks[:-1]:
        col, row = np.divmod(np.arange(width * count), width)
        parts.append(offset + (k_arr + col[None, :]) * width + row[None, :])
        offset += width * (n_knots if count == 2 else n_knots - 1)
    parts.append(np.full((k_arr.shape[0], 1), offset, dtype=np.int64))
    out = np.concatenate(parts, axis=1)
    return out[0] if np.ndim(k) == 0 else out


def _global_points(idx: _Ints, count: int, gmap: _Ints) -> _Ints:
    """Global indices of a group's points, ``(N or N - 1, width)``, from their local ones.

    ``idx`` (local count, width): a group of local count 2 has a point per knot
    (knot ``j`` from interval ``min(j, N - 2)``), of count 1 one per interval.
    """
    m = gmap.shape[0]
    total = m + 1 if count == 2 else m
    k = np.minimum(np.arange(total), m - 1)
    col = np.arange(total) - k if count == 2 else np.zeros(total, dtype=np.int64)
    return np.asarray(gmap[k[:, None], idx[col]], dtype=np.int64)


def _objective(
    method: Transcription, blocks: list[tuple[str, int, int]], xm: Any, pm: Any, lfm: Any
) -> tuple[Any, Any, tuple[Any, _Ints, _Ints, _Ints, Any]]:
    """Return ``f``, its gradient and its Hessian's entries, from the work's weighted sum.

    ``f = objective_value(duration(dt, N), dt S, beta)`` with ``S = sum w . (tau . tau)``
    over the torque columns (:meth:`Transcription.time_and_work`): its derivatives in
    the scalars ``(dt, S)`` come from SX, the torques' by the chain rule. Entries of a
    zero weight or of a derivative that is structurally zero are left out, as SX does.
    The Hessian's entries are ``(values, rows, cols, positions, scale)`` for
    :meth:`SparseEntries.add`.
    """
    n = next(c for name, _, c in blocks if name == "q")
    offsets, offset = {}, 0
    for name, width, count in blocks:
        offsets[name] = offset
        offset += width * count
    n_x, dt_index = offset, offsets["dt"]
    dt, total, beta = ca.SX.sym("dt"), ca.SX.sym("S"), ca.SX.sym("beta")
    f = objective_value(duration(dt, n), dt * total, beta)
    first = ca.gradient(f, ca.vertcat(dt, total))
    second = ca.hessian(f, ca.vertcat(dt, total))[0]
    if not second[1, 1].is_zero():
        raise TranscriptionError("the objective is not affine in the work")
    terms = ca.Function(
        "objective_terms", [dt, total, beta], [f, first[0], first[1], second[0, 0], second[0, 1]]
    )
    sums, taus, weights, rows = [], [], [], []
    for name, w in method.work_weights(n):
        width = next(wd for nm, wd, _ in blocks if nm == name)
        tau = ca.reshape(xm[offsets[name] : offsets[name] + width * w.size], width, w.size)
        sums.append(ca.mtimes(ca.sum1(tau**2), ca.DM(w)))
        used = np.flatnonzero(w != 0.0)
        index = (offsets[name] + used[:, None] * width + np.arange(width)[None, :]).ravel()
        taus.append(xm[index.tolist()])
        weights.append(np.repeat(2.0 * w[used], width))
        rows.append(index)
    total_m = sums[0]
    for term in sums[1:]:  # in time_and_work's order
        total_m = total_m + term
    f_m, f_dt, f_s, f_dtdt, f_dts = terms(xm[dt_index], total_m, pm)
    tau_rows = np.concatenate(rows)
    twice_w = ca.DM(np.concatenate(weights).tolist())
    tau_w = ca.vertcat(*taus) * twice_w  # 2 w tau: dS / dtau
    dt_at = np.array([dt_index])

    def entries(parts: list[tuple[ca.SX, Any, Any, _Ints, _Ints]]) -> tuple[Any, _Ints, _Ints]:
        """Stack the parts ``(derivative in SX, in MX, factor, rows, cols)`` that are not zero."""
        kept = [(d * v, r, c) for sx, d, v, r, c in parts if not sx.is_zero()]
        values = ca.vertcat(*[v for v, _, _ in kept])
        return (
            values,
            np.concatenate([r for _, r, _ in kept]),
            np.concatenate([c for *_, c in kept]),
        )

    grad_values, grad_rows, _ = entries(
        [(first[1], f_s, tau_w, tau_rows, tau_rows), (first[0], f_dt, 1.0, dt_at, dt_at)]
    )
    grad = SparseEntries()
    grad.add(grad_values, grad_rows, np.zeros_like(grad_rows), np.arange(grad_rows.size))
    hess_values, hess_rows, hess_cols = entries(
        [
            (first[1], lfm * f_s, twice_w, tau_rows, tau_rows),
            (second[0, 1], lfm * f_dts, tau_w, tau_rows, np.full(tau_rows.size, dt_index)),
            (second[0, 0], lfm * f_dtdt, 1.0, dt_at, dt_at),
        ]
    )
    return (
        f_m,
        ca.densify(grad.matrix(n_x, 1)),  # dense, as CasADi's gradient
        (hess_values, hess_rows, hess_cols, np.arange(hess_rows.size), 1.0),
    )


def stencil_functions(
    stencil: IntervalStencil,
    method: Transcription,
    problem: TrajOptProblem,
    kernels: tuple[ca.Function, ca.Function, ca.Function],
    forward: ca.Function,
    path_kernels: Sequence[tuple[ca.Function, ca.Function, ca.Function]],
) -> tuple[ca.Function, ca.Function, ca.Function, ca.Function]:
    """Map the stencil over ``method``'s grid: ``nlp``, ``grad_f``, ``jac_g`` and ``hess_lag``.

    Parameters
    ----------
    stencil : IntervalStencil
        From :func:`interval_stencil` for this scheme, problem and path constraints.
    method : Transcription
        The scheme on its grid.
    problem : TrajOptProblem
        The problem (its knots).
    kernels : (value, jacobian, hessian)
        The dynamics kernels used in the derivatives.
    forward : casadi.Function
        The dynamics value kernel of ``nlp`` (differentiable by CasADi).
    path_kernels : sequence of (value, jacobian, hessian)
        One per path constraint (those without kernel rows are not used).

    Returns
    -------
    tuple of casadi.Function
        In ``nlpsol``'s signatures, as
        :class:`~youbot_opt.trajopt.transcription.derivatives.NLPFunctions`.
    """
    nv, n = stencil.nv, problem.n_knots
    m = n - 1
    blocks = method.variable_blocks(nv, n)
    n_x = sum(w * c for _, w, c in blocks)
    gmap = _local_to_global(stencil.local_blocks, nv, n, np.arange(m))  # (m, n_local)
    n_s = gmap.shape[1] - 1
    r = method.ratios(n)

    # the dynamics points: global (q, v, tau) per group; each interval's point ids
    z_dyn = [_global_points(idx, count, gmap) for _, count, idx in stencil.groups]
    starts = np.concatenate(([0], np.cumsum([z.shape[0] for z in z_dyn]))).astype(np.int64)
    n_pts = int(starts[-1])
    gi, col = stencil.points[:, 0], stencil.points[:, 1]
    knot_group = np.array([count == 2 for _, count, _ in stencil.groups])
    pid = starts[gi][None, :] + np.arange(m)[:, None] + np.where(knot_group[gi], col, 0)[None, :]
    z_path = [_global_points(idx, count, gmap) for _, _, count, idx, _ in stencil.path_groups]

    # g's block offsets and each row set's global rows
    path_count = {pg[0]: z.shape[0] for pg, z in zip(stencil.path_groups, z_path, strict=True)}
    g_off: dict[str, int] = {}
    n_g = 0
    for name, width, kind in stencil.g_blocks:
        g_off[name] = n_g
        n_g += width * {"interval": m, "point": path_count.get(name, 0)}.get(kind, 1)
    ks = {"interval": np.arange(m), "first": np.array([0]), "last": np.array([m - 1])}

    def global_rows(kind: str) -> _Ints:
        rows, widths = [], []
        for name, width, kd in stencil.g_blocks:
            if kd == kind:
                rows.append(g_off[name] + np.arange(width))
                widths.append(np.full(width, width))
        k = ks[kind][:, None] if kind == "interval" else np.zeros((1, 1), dtype=np.int64)
        return np.concatenate(rows)[None, :] + k * np.concatenate(widths)[None, :]

    sets = [(rs, kind) for rs, kind in ((stencil.interval, "interval"), (stencil.first, "first"),
                                        (stencil.last, "last")) if rs is not None]  # fmt: skip
    xm, pm = ca.MX.sym("x", n_x), ca.MX.sym("p")
    lfm, lgm = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", n_g)

    def point_inputs(z: _Ints, parts: int) -> list[Any]:
        arg = ca.reshape(xm[z.ravel().tolist()], parts * nv, z.shape[0])
        return ca.vertsplit(arg, list(range(0, parts * nv + 1, nv)))

    dyn_in = [point_inputs(z, 3) for z in z_dyn]
    path_in = [point_inputs(z, 2) for z in z_path]
    path_k = [path_kernels[ic] for *_, ic in stencil.path_groups]
    s_all = ca.reshape(xm[gmap[:, :n_s].ravel().tolist()], n_s, m)
    h_all = xm[n_x - 1] * ca.DM(r).T

    def stencil_inputs(kind: str, a_all: Any, j_all: Any | None) -> list[Any]:
        """Return the inputs ``(s, a[, J], h)`` of the row set ``kind`` at its intervals."""
        k = ks[kind]
        cols = pid[k].ravel()
        whole = kind == "interval"  # all intervals: s and h as they are
        args = [s_all if whole else s_all[:, k.tolist()], a_all[:, cols.tolist()]]
        if j_all is not None:
            jc = (cols[:, None] * 3 * nv + np.arange(3 * nv)[None, :]).ravel()
            args.append(j_all[:, jc.tolist()])
        return [*args, h_all if whole else h_all[:, k.tolist()]]

    def call(fn: ca.Function, kind: str, args: list[Any], extra: Any = None) -> Any:
        args = args if extra is None else [*args[:-1], extra, args[-1]]
        return fn.map(m)(*args) if kind == "interval" else fn(*args)

    f_val, grad_val, f_hess = _objective(method, blocks, xm, pm, lfm)

    def g_of(outputs: list[tuple[Any, _Ints]]) -> Any:
        """``g`` from (values, their global rows) pieces."""
        rows = np.concatenate([rw.ravel() for _, rw in outputs])
        perm = np.argsort(rows, kind="stable")
        if not np.array_equal(rows[perm], np.arange(n_g)):
            raise AssertionError("the stencil's rows do not cover g once")
        return ca.vertcat(*[ca.vec(v) for v, _ in outputs])[perm.tolist()]

    def path_rows(i: int) -> _Ints:
        name = stencil.path_groups[i][0]
        width = int(path_k[i][0].size1_out(0))
        return g_off[name] + np.arange(width * z_path[i].shape[0])

    # ---- nlp: (f, g) with the value kernels
    a_val = ca.horzcat(*[forward.map(z.shape[0])(*a) for z, a in zip(z_dyn, dyn_in, strict=True)])
    g_parts = [(call(rs.value, kind, stencil_inputs(kind, a_val, None)), global_rows(kind))
               for rs, kind in sets]  # fmt: skip
    for i, (pk, args) in enumerate(zip(path_k, path_in, strict=True)):
        g_parts.append((pk[0].map(z_path[i].shape[0])(*args), path_rows(i)))
    g_val = g_of(g_parts)

    # ---- jac_g
    jac_out = [kernels[1].map(z.shape[0])(*a) for z, a in zip(z_dyn, dyn_in, strict=True)]
    a_jac = ca.horzcat(*[o[0] for o in jac_out])
    j_jac = ca.horzcat(*[o[1] for o in jac_out])
    entries = SparseEntries()
    g_parts = []
    jac_in = {kind: stencil_inputs(kind, a_jac, j_jac) for _, kind in sets}
    for rs, kind in sets:
        g_k, nz = call(rs.jacobian, kind, jac_in[kind])
        rows = global_rows(kind)
        g_parts.append((g_k, rows))
        k = ks[kind]
        cols = gmap[k][:, rs.jac_cols]
        scale = np.where(rs.jac_cols == n_s, r[k][:, None], 1.0)
        entries.add(ca.vec(nz), rows[:, rs.jac_rows], cols, np.arange(cols.size), scale)
    for i, (pk, args) in enumerate(zip(path_k, path_in, strict=True)):
        count = z_path[i].shape[0]
        c_k, jc = pk[1].map(count)(*args)
        g_parts.append((c_k, path_rows(i)))
        mw, width = int(jc.size1()), int(pk[1].size2_out(1))
        p, c, j = np.meshgrid(np.arange(count), np.arange(width), np.arange(mw), indexing="ij")
        entries.add(
            ca.vec(jc), g_off[stencil.path_groups[i][0]] + p * mw + j, z_path[i][p, c],
            (p * width + c) * mw + j,
        )  # fmt: skip
    g_jac = g_of(g_parts)
    jac_val = entries.matrix(n_g, n_x)

    # ---- hess_lag: objective, stencil terms, kernel Hessians at the points
    entries = SparseEntries()
    entries.add(*f_hess)
    w_entries = SparseEntries()
    lam_rows = [lgm[global_rows(kind).ravel().tolist()] for _, kind in sets]
    for (rs, kind), lam in zip(sets, lam_rows, strict=True):
        k = ks[kind]
        lam_k = ca.reshape(lam, -1, k.size)
        nz, w = call(rs.hessian, kind, jac_in[kind], lam_k)
        a, b = gmap[k][:, rs.hess_rows], gmap[k][:, rs.hess_cols]
        power = (rs.hess_rows == n_s).astype(int) + (rs.hess_cols == n_s).astype(int)
        scale = r[k][:, None] ** power[None, :]
        entries.add(ca.vec(nz), np.minimum(a, b), np.maximum(a, b), np.arange(a.size), scale)
        w_rows = (pid[k][:, :, None] * nv + np.arange(nv)[None, None, :]).ravel()
        w_entries.add(ca.vec(w), w_rows, np.zeros_like(w_rows), np.arange(w_rows.size))
    weights = ca.reshape(ca.densify(w_entries.matrix(nv * n_pts, 1)), nv, n_pts)
    for gi_, (z, args) in enumerate(zip(z_dyn, dyn_in, strict=True)):
        count = z.shape[0]
        w_g = weights[:, int(starts[gi_]) : int(starts[gi_]) + count]
        hk = kernels[2].map(count)(*args, w_g)
        rows, cols, pos = upper_entries(3 * nv, count, z)
        entries.add(ca.vec(hk), rows, cols, pos)
    for i, (pk, args) in enumerate(zip(path_k, path_in, strict=True)):
        count = z_path[i].shape[0]
        mw, width = int(pk[0].size1_out(0)), int(pk[2].size1_out(0))
        lam_c = ca.reshape(lgm[path_rows(i).tolist()], mw, count)
        hk = pk[2].map(count)(*args, lam_c)
        rows, cols, pos = upper_entries(width, count, z_path[i][:, :width])
        entries.add(ca.vec(hk), rows, cols, pos)
    hess_val = entries.matrix(n_x, n_x)

    return (
        ca.Function("nlp", [xm, pm], [f_val, g_val], ["x", "p"], ["f", "g"]),
        ca.Function("nlp_grad_f", [xm, pm], [f_val, grad_val], ["x", "p"], ["f", "grad_f_x"]),
        ca.Function("nlp_jac_g", [xm, pm], [g_jac, jac_val], ["x", "p"], ["g", "jac_g_x"]),
        ca.Function(
            "nlp_hess_l",
            [xm, pm, lfm, lgm],
            [hess_val],
            ["x", "p", "lam_f", "lam_g"],
            ["triu_hess_gamma_x_x"],
        ),
    )
