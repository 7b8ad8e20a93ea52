"""Benchmark the trajectory solver: SLSQP baseline, scaling over knots, multistart, Pareto.

Run ``python benchmarks/bench_trajopt.py [--quick] [--levers] [--workers N] [--json]``.
Everything is measured in one run, so the ratios compare like with like:

* **Base case** (study 1: beta = 0.5, 50 knots, trapezoidal, straight-line
  start): NLP build time with an empty kernel cache (compiles the dynamics
  kernels to C) and with the cache filled, and the solve's CPU time
  (``time.process_time``) and wall time (median of repeated solves).
* **SLSQP baseline**, the stand-in for the study's fmincon: SciPy's SLSQP on
  the *same* transcription (same variables, bounds, constraints ``g(x) = g0``,
  objective, straight-line start), with finite-difference derivatives (SciPy's
  default 2-point differences). It is capped at ``--slsqp-cap`` seconds; a
  capped run makes the printed ratio a lower bound (marked ``>=``).
* **Scaling** over 25 ... 1600 knots (``--quick``: 25 ... 200): build, solve
  CPU and wall time, iterations and the objective at ``tol = 1e-8`` (the
  default), compared with ``tol = 1e-6`` and ``tol = 1e-10`` from the same start,
  which shows that ``1e-8`` reaches the optimum; the largest grid is also
  solved from the 50-knot solution (mesh refinement).
* **Multistart** of 50 seeded random spline starts on ``--workers`` worker
  processes (wall time, including the pool) and the **19-point Pareto sweep**
  beta = 0.05 ... 0.95, each point warm-started from its neighbour.
* **Side by side with Drake** (issue 13, item 7; ``--side-by-side`` runs only
  this): the base case through ``TrajOptSolver.solve()`` as a user calls it
  (solver built as a user builds it, warmed up past the expansion of its NLP
  functions, then medians; the assembled functions' solves reported too), both
  transcriptions, against Drake with IPOPT on the same robot (parsed from the
  same URDF), start, bounds, objective and tolerance: our trapezoidal NLP
  hand-built in a ``MathematicalProgram``, and Drake's ``DirectCollocation``
  (see :class:`DrakeBaselines`), in alternating runs. ``solve()`` covers the
  guess, the IPOPT call with the best-iterate callback, the result and the
  independent ``pin.aba`` check; the table splits the IPOPT call from the rest.
  Drake comes with the ``bench`` extra (``pip install -e ".[bench]"``); without
  it the section prints that and is skipped.
* ``--levers``: the speed levers measured one by one on the base case and at
  400 knots -- derivative route (CasADi AD of the MX graph, of the graph
  expanded to SX, structured per-point kernels in CasADi's VM, the same
  kernels compiled to C) and IPOPT options (barrier-parameter oracle,
  limited-memory Hessian, looser tolerance). With ``--side-by-side`` it
  prints instead the issue-13 table through ``solve()`` (:func:`solve_levers`):
  IPOPT's KKT settings one by one (MUMPS's AMD ordering among them), barrier
  oracles, the best-iterate recorder's cost, Hermite-Simpson's Bernstein rows
  and its compressed form, the stage-wise fatrop prototype
  (:func:`fatrop_trapezoid`), and on UR5 and Panda the oracles' iterations and
  the two MUMPS orderings' CPU time. Their measurements and verdicts:
  docs/collocation.md, "The 0.03 s target".

Targets (issue 3, item 8, on 2 cores): base solve <= 0.05 s CPU, build <= 0.5 s
(cached), >= 300x faster than SLSQP, 1600 knots <= 2 s, 19-point Pareto <=
0.5 s, 50-start multistart <= 2 s wall. Issue 13, item 7: through ``solve()``
trapezoidal <= 0.02 s CPU, Hermite-Simpson <= 0.03 s, >= 100x faster than
Drake on both. The machine's load average is printed:
on a shared machine, wall times are inflated by other processes, CPU times
much less so.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np
from scipy.optimize import minimize

from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.guess import resolve_guess
from youbot_opt.trajopt.multistart import run_multistart
from youbot_opt.trajopt.pareto import DEFAULT_BETAS, pareto_sweep
from youbot_opt.trajopt.solver import EXPAND_AFTER_SOLVES, TrajOptSolver

TARGET_SOLVE_CPU = 0.05  # [s] base case, CPU
TARGET_BUILD = 0.5  # [s] base case NLP build (cached kernels)
TARGET_RATIO = 300.0  # SLSQP time / IPOPT time
TARGET_1600 = 2.0  # [s] 1600-knot solve
TARGET_PARETO = 0.5  # [s] wall, 19 warm-started points
TARGET_MULTISTART = 2.0  # [s] wall, 50 starts on 2 workers
TARGET_TRAPEZOID_CPU = 0.02  # [s] base case through solve(), trapezoidal (issue 13, item 7)
TARGET_HS_CPU = 0.03  # [s] base case through solve(), Hermite-Simpson
TARGET_DRAKE_RATIO = 100.0  # Drake time / ours, both methods
BETA = 0.5


def _timed(fn: Callable[[], Any]) -> tuple[Any, float, float]:
    """``fn()``, its wall time and its CPU time in [s]."""
    wall, cpu = time.perf_counter(), time.process_time()
    value = fn()
    return value, time.perf_counter() - wall, time.process_time() - cpu


def _build(n_knots: int, **kwargs: Any) -> tuple[TrajOptSolver, float, float]:
    return _timed(lambda: TrajOptSolver(study1_problem(n_knots), **kwargs))


def _repeat_solve(solver: TrajOptSolver, repeats: int, **kwargs: Any) -> tuple[Any, float, float]:
    """Last result and the median wall and CPU time of ``repeats`` solves."""
    walls, cpus, result = [], [], None
    for _ in range(repeats):
        result, wall, cpu = _timed(lambda: solver.solve(beta=BETA, **kwargs))
        walls.append(wall)
        cpus.append(cpu)
    return result, statistics.median(walls), statistics.median(cpus)


def _nlp_data(solver: TrajOptSolver) -> dict[str, Any]:
    """Straight-line start and numeric bounds of ``solver``'s NLP (public pieces only)."""
    problem, nlp = solver.problem, solver.nlp
    guess = resolve_guess(problem, None)
    bounds = problem.bounds(1.0)
    lbx, ubx = nlp.variable_bounds(bounds, (problem.dt_min, problem.dt_max))
    lbg, ubg = nlp.constraint_bounds(problem.start, problem.goal, bounds)
    x0 = nlp.variables.pack(solver.method.knot_guess(guess, problem.n_knots))
    return {"x0": x0, "lbx": lbx, "ubx": ubx, "lbg": lbg, "ubg": ubg}


class _Capped(Exception):
    pass


def slsqp_baseline(solver: TrajOptSolver, cap: float) -> dict[str, Any]:
    """SciPy SLSQP with finite differences on ``solver``'s transcription, capped at ``cap`` s."""
    data = _nlp_data(solver)
    nlp_fn = ca.Function(
        "nlp_ref", [solver.nlp.x, solver.nlp.p], [solver.nlp.f, solver.nlp.g]
    ).expand()
    lbg = data["lbg"]
    if np.any(data["ubg"] != lbg):
        raise ValueError("the SLSQP baseline expects equality constraints only (trapezoidal)")
    best = {"x": data["x0"]}
    start = time.process_time()

    def fg(x: np.ndarray) -> tuple[float, np.ndarray]:
        if time.process_time() - start > cap:
            raise _Capped
        f, g = nlp_fn(x, BETA)
        return float(f), np.asarray(g).ravel() - lbg

    iterations = [0]

    def count(x: np.ndarray) -> None:  # SLSQP calls it once per iteration
        iterations[0] += 1
        best["x"] = x.copy()

    wall, cpu = time.perf_counter(), time.process_time()
    capped, message = False, ""
    try:
        res = minimize(
            lambda x: fg(x)[0],
            data["x0"],
            method="SLSQP",
            bounds=list(zip(data["lbx"], data["ubx"], strict=True)),
            constraints=[{"type": "eq", "fun": lambda x: fg(x)[1]}],
            options={"maxiter": 5000, "ftol": 1e-10},
            callback=count,
        )
        x, message = res.x, str(res.message)
    except _Capped:
        x, capped, message = best["x"], True, f"capped at {cap:.0f} s CPU"
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    f, g = nlp_fn(x, BETA)
    return {
        "objective": float(f),
        "violation": float(np.max(np.abs(np.asarray(g).ravel() - lbg))),
        "iterations": iterations[0],
        "wall": wall,
        "cpu": cpu,
        "capped": capped,
        "message": message,
    }


def _raw_ipopt(
    solver: TrajOptSolver, route: str, options: IpoptOptions
) -> tuple[float, float, int]:
    """Build and solve the base NLP by a CasADi-AD route; (build, solve CPU) [s], iterations."""
    nlp = solver.nlp

    def build() -> Any:
        fn = ca.Function("nlp", [nlp.x, nlp.p], [nlp.f, nlp.g], ["x", "p"], ["f", "g"])
        fn = fn.expand() if route == "expand" else fn
        return ca.nlpsol("raw", "ipopt", fn, options.to_casadi(True))

    ipopt, build_wall, _ = _timed(build)
    data = _nlp_data(solver)
    _, _, cpu = _timed(lambda: ipopt(p=BETA, **data))
    _, _, cpu2 = _timed(lambda: ipopt(p=BETA, **data))
    return build_wall, min(cpu, cpu2), int(ipopt.stats()["iter_count"])


def _levers(rows: list[str]) -> None:
    """Measure the speed levers one at a time (base case and 400 knots)."""
    rows.append(
        f"{'lever':<44} {'knots':>5} {'build [s]':>9} {'solve CPU [s]':>13} {'iter':>5} {'f':>10}"
    )
    for n in (50, 400):
        ref, _, _ = _build(n)
        for route in ("mx", "expand"):
            b, cpu, it = _raw_ipopt(ref, route, IpoptOptions())
            name = (
                "CasADi AD, MX graph, F.map over knots"
                if route == "mx"
                else ("CasADi AD, MX graph expanded to SX")
            )
            rows.append(f"{name:<44} {n:>5} {b:>9.3f} {cpu:>13.4f} {it:>5} {'':>10}")
        for label, kwargs in (
            ("structured kernels, CasADi VM", {"compile": False}),
            ("structured kernels, compiled C (default)", {}),
            ("  + mu_oracle=probing", {"options": IpoptOptions(extra={"mu_oracle": "probing"})}),
            ("  + hessian=limited-memory", {"options": IpoptOptions(hessian="limited-memory")}),
            ("  + tol=1e-6", {"options": IpoptOptions(tol=1e-6)}),
        ):
            solver, build, _ = _build(n, **kwargs)
            res, _, cpu = _repeat_solve(solver, 3 if n <= 50 else 1)
            rows.append(
                f"{label:<44} {n:>5} {build:>9.3f} {cpu:>13.4f} {res.iterations:>5} "
                f"{res.objective:>10.6f}"
            )


# ------------------------------------------------------- solve() levers (#13)
def _median_solve_cpu(solver: TrajOptSolver, repeats: int) -> tuple[Any, float]:
    """Last result and median CPU [s] of ``repeats`` solves after one warm-up solve."""
    solver.solve(beta=BETA)
    result, _, cpu = _repeat_solve(solver, repeats)
    return result, cpu


def _raw_call(solver: TrajOptSolver, recorder: bool, fns: Any = None) -> dict[str, float]:
    """The IPOPT call alone on ``solver``'s NLP (public pieces), with or without the recorder.

    Returns the call's median CPU [s] over 5 calls, the CPU IPOPT reports inside
    the NLP functions and the callback, the iterations and the objective.
    """
    from youbot_opt.nlp.best_iterate import BestIterateRecorder
    from youbot_opt.trajopt.transcription.derivatives import (
        compile_kernels,
        dynamics_kernels,
        structured_functions,
    )

    nlp = solver.nlp
    if fns is None:
        kernels = dynamics_kernels(solver.dynamics.forward_dynamics)
        fns = structured_functions(
            solver.method, solver.problem, compile_kernels(kernels), values=kernels
        )
    opts = solver.options.to_casadi(True)
    data = _nlp_data(solver)
    if recorder:
        rec = BestIterateRecorder("bench", nlp.n_variables, nlp.n_constraints, 1)
        opts["iteration_callback"] = rec
        rec.reset((data["lbx"], data["ubx"], data["lbg"], data["ubg"]), solver.feasibility_tol)
    derivatives = {"grad_f": fns.grad_f, "jac_g": fns.jac_g, "hess_lag": fns.hess_lag}
    ipopt = ca.nlpsol("bench", "ipopt", fns.nlp, {**opts, **derivatives})
    ipopt(p=BETA, **data)
    cpus = []
    for _ in range(5):
        sol, _, cpu = _timed(lambda: ipopt(p=BETA, **data))
        cpus.append(cpu)
    st = ipopt.stats()
    functions = sum(v for k, v in st.items() if k.startswith("t_proc_nlp"))
    return {
        "cpu": statistics.median(cpus), "functions": functions,
        "callback": st.get("t_proc_callback_fun", 0.0), "iterations": st["iter_count"],
        "objective": float(sol["f"]),
    }  # fmt: skip


def _compressed_hs(solver: TrajOptSolver) -> dict[str, float]:
    """Compressed Hermite-Simpson (q_m, v_m substituted, tau_m kept), CasADi AD, one IPOPT call.

    The same problem as ``solver``'s (uniform grid, Bernstein rows, Simpson's
    rule), built from the same per-point dynamics; returns the IPOPT-internal
    CPU (call minus the CPU inside the NLP functions), iterations, objective
    and the sizes. The derivatives are CasADi's (exact Hessian), which does
    not change the iterates, only the function time that is subtracted.
    """
    from youbot_opt.trajopt.quadrature import quadrature_weights

    problem = solver.problem
    fd = solver.dynamics.forward_dynamics
    fd = fd if fd.is_a("SXFunction") else fd.expand()
    nv, n = problem.nv, problem.n_knots
    q, v, tau = (ca.SX.sym(name, nv, n) for name in ("q", "v", "tau"))
    tau_m, dt, beta = ca.SX.sym("tau_m", nv, n - 1), ca.SX.sym("dt"), ca.SX.sym("beta")
    a = fd.map(n)(q, v, tau)
    q0, q1, v0, v1, a0, a1 = q[:, :-1], q[:, 1:], v[:, :-1], v[:, 1:], a[:, :-1], a[:, 1:]
    q_m = 0.5 * (q0 + q1) + dt / 8 * (v0 - v1)
    v_m = 0.5 * (v0 + v1) + dt / 8 * (a0 - a1)
    a_m = fd.map(n - 1)(q_m, v_m, tau_m)
    rows = [
        q1 - q0 - dt / 6 * (v0 + 4 * v_m + v1), v1 - v0 - dt / 6 * (a0 + 4 * a_m + a1),
        q[:, 0], v[:, 0], q[:, n - 1], v[:, n - 1],
        v0 + dt / 3 * a0, v1 - dt / 3 * a1, q0 + dt / 3 * v0, q1 - dt / 3 * v1,
    ]  # fmt: skip
    w_knots, w_mid = quadrature_weights("simpson", n)
    work = dt * (
        ca.mtimes(ca.sum1(tau**2), ca.DM(w_knots))
        + ca.mtimes(ca.sum1(tau_m**2), ca.DM(np.asarray(w_mid, dtype=float)))
    )
    x = ca.vertcat(ca.vec(q), ca.vec(v), ca.vec(tau), ca.vec(tau_m), dt)
    nlp = {"x": x, "p": beta, "f": beta * (n - 1) * dt + (1 - beta) * work}
    nlp["g"] = ca.vertcat(*[ca.vec(r) for r in rows])
    ipopt = ca.nlpsol("compressed", "ipopt", nlp, solver.options.to_casadi(True))
    b, rep = problem.bounds(1.0), (lambda arr, k: np.tile(np.asarray(arr, dtype=float), k))
    lbx = np.concatenate([rep(b.q_lower, n), rep(b.v_lower, n), rep(b.tau_lower, 2 * n - 1)])
    ubx = np.concatenate([rep(b.q_upper, n), rep(b.v_upper, n), rep(b.tau_upper, 2 * n - 1)])
    ends = [problem.start.q, problem.start.velocity, problem.goal.q, problem.goal.velocity]
    zero = np.zeros(2 * nv * (n - 1))
    lbg = np.concatenate([zero, *ends, rep(b.v_lower, 2 * n - 2), rep(b.q_lower, 2 * n - 2)])
    ubg = np.concatenate([zero, *ends, rep(b.v_upper, 2 * n - 2), rep(b.q_upper, 2 * n - 2)])
    g = solver.method.knot_guess(resolve_guess(problem, None), n)
    x0 = np.concatenate([g["q"].ravel(), g["v"].ravel(), g["tau"].ravel(), g["tau_mid"].ravel()])
    data: dict[str, Any] = {"x0": np.append(x0, float(np.ravel(g["dt"])[0]))}
    data.update(lbx=np.append(lbx, problem.dt_min))
    data.update(ubx=np.append(ubx, problem.dt_max), lbg=lbg, ubg=ubg, p=BETA)
    ipopt(**data)
    cpus = []
    for _ in range(3):
        sol, _, cpu = _timed(lambda: ipopt(**data))
        cpus.append(cpu)
    st = ipopt.stats()
    functions = sum(v for k, v in st.items() if k.startswith("t_proc_nlp"))
    return {
        "internal": statistics.median(cpus) - functions, "iterations": st["iter_count"],
        "objective": float(sol["f"]), "n_variables": x.numel(), "n_rows": nlp["g"].numel(),
        "hessian_nnz": ipopt.get_function("nlp_hess_l").sparsity_out(0).nnz(),
    }  # fmt: skip


def fatrop_trapezoid(solver: TrajOptSolver, repeats: int = 5) -> dict[str, Any]:
    """The base-case trapezoidal NLP in stage-wise form, solved by CasADi's fatrop plugin.

    A prototype (issue 13, item 7, lever (d)): fatrop needs the NLP as an
    optimal control problem -- stage ``k`` holds a state ``X_k`` and a control
    ``U_k``, consecutive stages are joined by gap-closing rows
    ``X_{k+1} = F(X_k, U_k)``, everything else is a stage's own path row.
    The trapezoid is implicit (its defects involve both knots), so the state
    is ``X_k = (q_k, v_k, tau_k, dt)`` (the free step carried as a state), the
    control ``U_k`` a copy of the next knot's ``(q, v, tau)``, the gap-closing
    row ``X_{k+1} = (U_k, dt)`` and the trapezoid defects path rows of stage
    ``k``; boundary states are bounds on ``X_0`` and ``X_{N-1}``. Same
    objective, bounds, straight-line start and tolerance (1e-8) as ours;
    CasADi's own derivatives (exact Hessian, SX in CasADi's virtual machine),
    whose evaluation time is reported separately. The same NLP solved by IPOPT
    is the control. Returns, per solver, the median CPU [s] of ``repeats``
    solves, the CPU inside the NLP functions, iterations, objective and
    CasADi's success flag.
    """
    from youbot_opt.trajopt.quadrature import quadrature_weights

    problem = solver.problem
    fd = solver.dynamics.forward_dynamics
    fd = fd if fd.is_a("SXFunction") else fd.expand()
    nv, n, b = problem.nv, problem.n_knots, problem.bounds(1.0)
    w_knots, _ = quadrature_weights("trapezoidal", n)
    guess = solver.method.knot_guess(resolve_guess(problem, None), n)
    beta = ca.SX.sym("beta")
    w: list[Any] = []
    g: list[Any] = []
    lbw: list[float] = []
    ubw: list[float] = []
    w0: list[float] = []
    cost: Any = 0
    lo_x = np.concatenate([b.q_lower, b.v_lower, b.tau_lower, [problem.dt_min]])
    hi_x = np.concatenate([b.q_upper, b.v_upper, b.tau_upper, [problem.dt_max]])
    state = ca.SX.sym("X_0", 3 * nv + 1)
    for k in range(n):
        lo, hi = lo_x.copy(), hi_x.copy()
        for end, knot in ((problem.start, 0), (problem.goal, n - 1)):
            if k == knot:
                lo[:nv] = hi[:nv] = end.q
                lo[nv : 2 * nv] = hi[nv : 2 * nv] = end.velocity
        w.append(state)
        lbw += lo.tolist()
        ubw += hi.tolist()
        w0 += [*guess["q"][k], *guess["v"][k], *guess["tau"][k], float(np.ravel(guess["dt"])[0])]
        q, v, tau, dt = state[:nv], state[nv : 2 * nv], state[2 * nv : 3 * nv], state[3 * nv]
        cost += (1 - beta) * dt * w_knots[k] * ca.sumsqr(tau) + (beta * dt if k < n - 1 else 0)
        if k == n - 1:
            break
        control = ca.SX.sym(f"U_{k}", 3 * nv)
        w.append(control)
        lbw += [-np.inf] * (3 * nv)
        ubw += [np.inf] * (3 * nv)
        w0 += [*guess["q"][k + 1], *guess["v"][k + 1], *guess["tau"][k + 1]]
        following = ca.SX.sym(f"X_{k + 1}", 3 * nv + 1)
        g.append(following - ca.vertcat(control, dt))  # gap closing
        q1, v1, tau1 = control[:nv], control[nv : 2 * nv], control[2 * nv :]
        a0, a1 = fd(q, v, tau), fd(q1, v1, tau1)
        g.append(ca.vertcat(q1 - q - dt / 2 * (v + v1), v1 - v - dt / 2 * (a0 + a1)))
        state = following
    nlp = {"x": ca.vertcat(*w), "f": cost, "g": ca.vertcat(*g), "p": beta}
    rows = nlp["g"].numel()
    args = {"x0": w0, "lbx": lbw, "ubx": ubw, "lbg": [0.0] * rows, "ubg": [0.0] * rows, "p": BETA}
    out: dict[str, Any] = {"n_variables": nlp["x"].numel(), "n_rows": rows}
    settings = {
        "fatrop": {
            "structure_detection": "auto", "equality": [True] * rows,
            "fatrop": {"tol": solver.options.tol, "print_level": 0},
        },
        "ipopt": {"ipopt": {"tol": solver.options.tol, "print_level": 0, "sb": "yes"}},
    }  # fmt: skip
    for name, opts in settings.items():
        try:
            nlpsol = ca.nlpsol(f"proto_{name}", name, nlp, {**opts, "print_time": False})
        except RuntimeError as exc:  # plugin missing from this CasADi build
            out[name] = {"error": str(exc).strip().splitlines()[-1]}
            continue
        sol = nlpsol(**args)
        cpus = []
        for _ in range(repeats):
            sol, _, cpu = _timed(lambda nlpsol=nlpsol: nlpsol(**args))
            cpus.append(cpu)
        st = nlpsol.stats()
        out[name] = {
            "cpu": statistics.median(cpus), "iterations": int(st.get("iter_count", -1)),
            "functions": sum(v for k, v in st.items() if k.startswith("t_proc_nlp")),
            "objective": float(sol["f"]), "success": bool(st.get("success", False)),
            "status": st.get("return_status", st.get("unified_return_status", "?")),
        }  # fmt: skip
    return out


_FAST_STEP = {"fast_step_computation": "yes"}
_NO_MUMPS_SCALING = {"mumps_scaling": 0, "mumps_permuting_scaling": 0}


def solve_levers(repeats: int = 10) -> list[str]:
    """Issue 13, item 7: each lever's effect on the base case through ``solve()``, one run.

    Rows per method: IPOPT's own KKT settings (the defaults before
    ``fast_kkt``), each setting of :data:`youbot_opt.nlp.ipopt.FAST_KKT` alone,
    all of them (the default), then barrier-oracle alternatives on top of the
    default; the IPOPT call with and without the best-iterate recorder; for
    Hermite-Simpson, the NLP without its Bernstein rows (a different, weaker
    problem: the cost of exact between-knot bounds) and the compressed form.
    Then the stage-wise fatrop prototype (:func:`fatrop_trapezoid`). Last, the
    iteration counts of UR5 and Panda (trapezoidal, 40 and 10 knots) under the
    quality-function and probing oracles (why probing is no default), and
    their CPU time with MUMPS's automatic and AMD orderings (both methods).
    """
    from youbot_opt.robot.load import load_model
    from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
    from youbot_opt.trajopt.transcription.hermite_simpson import HermiteSimpsonCollocation

    class _NoHull(HermiteSimpsonCollocation):
        unbounded = ()

        def path_constraints(self, sym: Any, accel: Any) -> list[tuple[str, str, Any]]:
            return []

    settings: list[tuple[str, dict[str, Any]]] = [
        ("IPOPT's KKT settings (fast_kkt=False, before)", {"fast_kkt": False}),
        ("  + fast_step_computation=yes", {"fast_kkt": False, "extra": {**_FAST_STEP}}),
        ("  + min_refinement_steps=0", {"fast_kkt": False, "extra": {"min_refinement_steps": 0}}),
        ("  + MUMPS scaling off", {"fast_kkt": False, "extra": {**_NO_MUMPS_SCALING}}),
        ("  + MUMPS AMD ordering", {"fast_kkt": False, "extra": {"mumps_pivot_order": 0}}),
        ("fast_kkt=True, MUMPS's automatic ordering", {"extra": {"mumps_pivot_order": 7}}),
        ("fast_kkt=True (the default)", {}),
        ("  + mu_oracle=probing", {"extra": {"mu_oracle": "probing"}}),
        ("  + mu_oracle=loqo", {"extra": {"mu_oracle": "loqo"}}),
        ("  + mu_strategy=monotone", {"mu_strategy": "monotone"}),
        ("  + nlp_scaling_method=none", {"extra": {"nlp_scaling_method": "none"}}),
        ("  + mehrotra_algorithm=yes (no line search)", {"extra": {"mehrotra_algorithm": "yes"}}),
    ]  # fmt: skip
    out = [
        f"{'lever (base case, through solve())':<46} {'method':<16} {'CPU [s]':>8} {'vs before':>9}"
        f" {'iter':>4} {'f':>12}"
    ]
    problem = study1_problem(50)
    for method in METHODS:
        before = float("nan")
        for label, kwargs in settings:
            solver = TrajOptSolver(problem, method, options=IpoptOptions(**kwargs))
            res, cpu = _median_solve_cpu(solver, repeats)
            before = cpu if kwargs == {"fast_kkt": False} else before
            out.append(
                f"{label:<46} {method:<16} {cpu:>8.4f} {cpu / before - 1:>+8.0%} "
                f"{res.iterations:>4} {res.objective:>12.9f}"
            )
        solver = TrajOptSolver(problem, method)
        with_rec, without = _raw_call(solver, True), _raw_call(solver, False)
        out.append(
            f"{'IPOPT call alone, best-iterate recorder':<46} {method:<16} {with_rec['cpu']:>8.4f}"
            f" {'':>9} {with_rec['iterations']:>4} {with_rec['objective']:>12.9f}"
        )
        out.append(
            f"{'IPOPT call alone, no recorder':<46} {method:<16} {without['cpu']:>8.4f} "
            f"{without['cpu'] / with_rec['cpu'] - 1:>+8.0%} {without['iterations']:>4} "
            f"{without['objective']:>12.9f}"
        )
        out.append(
            f"    (inside: NLP functions {with_rec['functions']:.4f} s, recorder "
            f"{with_rec['callback']:.4f} s; IPOPT itself "
            f"{with_rec['cpu'] - with_rec['functions'] - with_rec['callback']:.4f} s)"
        )
        if method == "hermite_simpson":
            hull = TrajOptSolver(problem, _NoHull())
            res, cpu = _median_solve_cpu(hull, repeats)
            out.append(
                f"{'  without the Bernstein rows (weaker problem)':<46} {method:<16} {cpu:>8.4f} "
                f"{'':>9} {res.iterations:>4} {res.objective:>12.9f}"
            )
            comp = _compressed_hs(solver)
            sep = with_rec["cpu"] - with_rec["functions"] - with_rec["callback"]
            out.append(
                f"    compressed form (q_m, v_m substituted): {comp['n_variables']} variables, "
                f"{comp['n_rows']} rows (separated {solver.nlp.n_variables}, "
                f"{solver.nlp.n_constraints}), Hessian nnz {comp['hessian_nnz']}; IPOPT itself "
                f"{comp['internal']:.4f} s in {comp['iterations']} iterations (separated "
                f"{sep:.4f} s in {with_rec['iterations']}), f = {comp['objective']:.9f}"
            )
    proto = fatrop_trapezoid(TrajOptSolver(problem, "trapezoidal"))
    for name in ("fatrop", "ipopt"):
        r = proto[name]
        if "error" in r:
            out.append(f"  fatrop prototype: {name} unavailable ({r['error']})")
            continue
        own = r["cpu"] - r["functions"]
        out.append(
            f"  stage-wise trapezoid ({proto['n_variables']} variables, {proto['n_rows']} rows), "
            f"{name}: {r['cpu']:.4f} s CPU, of which NLP functions (CasADi VM) "
            f"{r['functions']:.4f} s, solver itself {own:.4f} s in {r['iterations']} iterations "
            f"({1e3 * own / max(r['iterations'], 1):.2f} ms each), f = {r['objective']:.9f}, "
            f"success {r['success']} (status {r['status']})"
        )
    ur5 = load_model("ur5")
    cases = [
        ("UR5, 40 knots", ur5, [0.0, -1.2, 1.0, -0.5, 0.3, 0.0],
         [0.8, -0.6, 0.4, -1.2, -0.3, 0.5], 40, 0.5),
    ]  # fmt: skip
    try:
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the locked mimic finger
            panda = load_model("panda")
        cases.append(
            ("Panda, 10 knots, min time", panda, [0.0, -0.5, 0.0, -2.0, 0.0, 1.6, 0.8, 0.02],
             [0.5, -0.2, 0.3, -1.6, 0.2, 1.9, 0.4, 0.02], 10, 1.0)
        )  # fmt: skip
    except Exception as exc:  # noqa: BLE001 -- example-robot-data without panda
        out.append(f"panda skipped: {exc}")
    for name, robot, q0, q1, n, beta in cases:
        prob = TrajOptProblem(
            robot=robot, start=BoundaryState(q=np.array(q0)), goal=BoundaryState(q=np.array(q1)),
            n_knots=n,
        )  # fmt: skip
        line = f"  oracle robustness, {name}, trapezoidal:"
        for oracle in ("quality-function", "probing"):
            opts = IpoptOptions(extra={"mu_oracle": oracle})
            res = TrajOptSolver(prob, options=opts, compile=False).solve(beta=beta)
            line += f" {oracle} {res.iterations} iterations (f = {res.objective:.8f});"
        out.append(line)
        for method in METHODS:
            line = f"  MUMPS ordering, {name}, {method}:"
            for label, extra in (("automatic", {"mumps_pivot_order": 7}), ("AMD (default)", {})):
                amd = TrajOptSolver(prob, method, IpoptOptions(extra=extra), compile="wait")
                amd.solve(beta=beta)  # warm-up
                runs = range(repeats // 2 + 1)
                timed = [_timed(lambda a=amd, b=beta: a.solve(beta=b)) for _ in runs]
                res, cpu = timed[-1][0], statistics.median(t[2] for t in timed)
                line += f" {label} {cpu:.4f} s, {res.iterations} it, f = {res.objective:.9f};"
            out.append(line)
    return out


# ---------------------------------------------------------------- side by side
METHODS = ("trapezoidal", "hermite_simpson")
DRAKE_NAMES = {
    "trapezoidal": "hand-built trapezoid, MathematicalProgram",
    "hermite_simpson": "DirectCollocation (Hermite-Simpson)",
}
DRAKE_HINT = 'pip install -e ".[bench]"'


def _root_link(urdf: str) -> str:
    """The URDF link no joint has as its child (welded to Drake's world)."""
    import xml.etree.ElementTree as ET

    tree = ET.fromstring(urdf)
    children = {j.find("child").get("link") for j in tree.iter("joint")}  # type: ignore[union-attr]
    roots = [link.get("name") for link in tree.iter("link") if link.get("name") not in children]
    if len(roots) != 1:
        raise ValueError(f"expected one root link in the URDF, found {roots}")
    return str(roots[0])


class DrakeBaselines:
    """The base case in Drake: the same robot, start, bounds, objective and IPOPT tolerance.

    The robot is parsed from the same URDF text by pydrake's ``Parser`` (root
    link welded to the world, one actuator per joint of our model, in its
    order). Two NLPs are built once and solved from the same straight-line
    start as ours:

    * ``trapezoidal``: our trapezoidal NLP hand-built in a ``MathematicalProgram``
      -- the same variables ``q, v, tau`` (N x nv each) and ``dt``, the same
      bounds, the same boundary rows, the same defects (one generic constraint
      per interval, forward dynamics of Drake's plant in AutoDiffXd, as a
      pydrake user writes it) and the same objective ``beta (N-1) dt + (1-beta) W``
      with the trapezoidal rule for ``W``;
    * ``hermite_simpson``: Drake's ``DirectCollocation`` (cubic states,
      first-order-hold torque, equal intervals, running cost
      ``(1-beta) tau . tau`` and final cost ``beta T``). It is Drake's
      Hermite-Simpson transcription, not ours: ours also has free midpoint
      torques and Simpson's rule for ``W``, so the optima differ slightly.

    Both are solved by pydrake's ``IpoptSolver`` with ``tol`` = ours. Drake has
    no second derivatives: its IPOPT runs with a limited-memory Hessian.
    """

    def __init__(self, solver: TrajOptSolver, beta: float) -> None:
        from pydrake.multibody.parsing import Parser
        from pydrake.multibody.plant import MultibodyPlant
        from pydrake.solvers import IpoptSolver, SolverOptions

        problem = solver.problem
        urdf = open(problem.robot.urdf_path, encoding="utf-8").read()
        plant = MultibodyPlant(0.0)
        Parser(plant).AddModelsFromString(urdf, "urdf")
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(_root_link(urdf)))
        names = [problem.robot.model.names[i] for i in range(1, problem.robot.model.njoints)]
        for name in names:
            joint = plant.GetJointByName(name)
            plant.AddJointActuator(f"{name}_actuator", joint)
        plant.Finalize()
        self.plant, self.problem, self.beta = plant, problem, beta
        self.nv = problem.nv
        guess = resolve_guess(problem, None)
        self.straight = solver.method.knot_guess(guess, problem.n_knots)
        self.ipopt = IpoptSolver()
        self.options = SolverOptions()
        self.options.SetOption(IpoptSolver.id(), "tol", float(solver.options.tol))
        self.dynamics_error = self._same_robot(names)
        self.programs = {"trapezoidal": self._trapezoid(), "hermite_simpson": self._dircol()}

    def _same_robot(self, names: list[str]) -> float:
        """Largest |a_drake - a_pinocchio| [rad/s^2] over random states (same robot, same order)."""
        import pinocchio as pin

        model = self.problem.robot.model
        data = model.createData()
        context = self.plant.CreateDefaultContext()
        rng = np.random.default_rng(0)
        err = 0.0
        for _ in range(5):
            q, v, tau = (rng.uniform(-1.0, 1.0, self.nv) for _ in range(3))
            self.plant.SetPositions(context, q)
            self.plant.SetVelocities(context, v)
            self.plant.get_actuation_input_port().FixValue(context, tau)
            a = self.plant.EvalTimeDerivatives(context).CopyToVector()[self.nv :]
            err = max(err, float(np.max(np.abs(a - pin.aba(model, data, q, v, tau)))))
        return err

    def _accelerations(self) -> Callable[[np.ndarray], np.ndarray]:
        """``z = (q, v, tau) -> a`` with Drake's plant, for float or AutoDiffXd ``z``."""
        nv, plant = self.nv, self.plant
        plant_ad = plant.ToAutoDiffXd()
        ctx, ctx_ad = plant.CreateDefaultContext(), plant_ad.CreateDefaultContext()
        port, port_ad = plant.get_actuation_input_port(), plant_ad.get_actuation_input_port()

        def accel(z: np.ndarray) -> np.ndarray:
            p, c, u = (plant_ad, ctx_ad, port_ad) if z.dtype == object else (plant, ctx, port)
            p.SetPositionsAndVelocities(c, z[: 2 * nv])
            u.FixValue(c, z[2 * nv :])
            return p.EvalTimeDerivatives(c).CopyToVector()[nv:]

        return accel

    def _trapezoid(self) -> Any:
        from pydrake.solvers import MathematicalProgram

        problem, nv, n, beta = self.problem, self.nv, self.problem.n_knots, self.beta
        accel = self._accelerations()

        def defect(z: np.ndarray) -> np.ndarray:  # z = (knot k, knot k+1, dt)
            k0, k1, dt = z[: 3 * nv], z[3 * nv : 6 * nv], z[6 * nv]
            a0, a1 = accel(k0), accel(k1)
            dq = k1[:nv] - k0[:nv] - 0.5 * dt * (k0[nv : 2 * nv] + k1[nv : 2 * nv])
            dv = k1[nv : 2 * nv] - k0[nv : 2 * nv] - 0.5 * dt * (a0 + a1)
            return np.concatenate([dq, dv])

        prog = MathematicalProgram()
        q, v, tau = (prog.NewContinuousVariables(n, nv, name) for name in ("q", "v", "tau"))
        dt = prog.NewContinuousVariables(1, "dt")
        b = problem.bounds(1.0)
        for k in range(n):
            prog.AddBoundingBoxConstraint(b.q_lower, b.q_upper, q[k])
            prog.AddBoundingBoxConstraint(b.v_lower, b.v_upper, v[k])
            prog.AddBoundingBoxConstraint(b.tau_lower, b.tau_upper, tau[k])
        prog.AddBoundingBoxConstraint(problem.dt_min, problem.dt_max, dt)
        zero = np.zeros(2 * nv)
        for k in range(n - 1):
            z = np.concatenate([q[k], v[k], tau[k], q[k + 1], v[k + 1], tau[k + 1], dt])
            prog.AddConstraint(defect, zero, zero, z)
        eye = np.eye(nv)
        for var, value in (
            (q[0], problem.start.q), (v[0], problem.start.velocity),
            (q[-1], problem.goal.q), (v[-1], problem.goal.velocity),
        ):  # fmt: skip
            prog.AddLinearEqualityConstraint(eye, value, var)
        weights = np.ones(n)
        weights[[0, -1]] = 0.5
        work = dt[0] * sum(weights[k] * tau[k].dot(tau[k]) for k in range(n))
        prog.AddCost(beta * (n - 1) * dt[0] + (1.0 - beta) * work)
        g = self.straight
        for var, value in ((q, g["q"]), (v, g["v"]), (tau, g["tau"]), (dt, np.atleast_1d(g["dt"]))):
            prog.SetInitialGuess(var, value)
        return prog

    def _dircol(self) -> Any:
        from pydrake.planning import DirectCollocation
        from pydrake.trajectories import PiecewisePolynomial

        problem, nv, beta, plant = self.problem, self.nv, self.beta, self.plant
        n = problem.n_knots
        # Drake needs a finite largest step; 1 s (T <= 49 s) is far from binding (T ~ 2 s).
        dt_max = min(problem.dt_max, 1.0)
        dircol = DirectCollocation(
            plant, plant.CreateDefaultContext(), n, problem.dt_min, dt_max,
            plant.get_actuation_input_port().get_index(),
        )  # fmt: skip
        prog = dircol.prog()
        dircol.AddEqualTimeIntervalsConstraints()
        b = problem.bounds(1.0)
        x_lo, x_hi = np.concatenate([b.q_lower, b.v_lower]), np.concatenate([b.q_upper, b.v_upper])
        for k in range(n):
            prog.AddBoundingBoxConstraint(x_lo, x_hi, dircol.state(k))
            prog.AddBoundingBoxConstraint(b.tau_lower, b.tau_upper, dircol.input(k))
        eye = np.eye(2 * nv)
        start = np.concatenate([problem.start.q, problem.start.velocity])
        goal = np.concatenate([problem.goal.q, problem.goal.velocity])
        prog.AddLinearEqualityConstraint(eye, start, dircol.initial_state())
        prog.AddLinearEqualityConstraint(eye, goal, dircol.final_state())
        u = dircol.input()
        dircol.AddRunningCost((1.0 - beta) * u.dot(u))
        dircol.AddFinalCost(beta * dircol.time()[0])
        g = self.straight
        t = float(np.ravel(g["dt"])[0]) * np.arange(n)
        dircol.SetInitialTrajectory(
            PiecewisePolynomial.FirstOrderHold(t, g["tau"].T),
            PiecewisePolynomial.FirstOrderHold(t, np.vstack([g["q"].T, g["v"].T])),
        )
        return prog

    def solve(self, method: str) -> tuple[float, float, float, bool]:
        """Solve one NLP from the straight line; (wall, CPU) [s], objective, success."""
        prog = self.programs[method]
        wall, cpu = time.perf_counter(), time.process_time()
        result = self.ipopt.Solve(prog, None, self.options)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        return wall, cpu, float(result.get_optimal_cost()), bool(result.is_success())


def side_by_side(
    drake_repeats: int, ours_total: int = 10, options: IpoptOptions | None = None
) -> dict[str, Any]:
    """Ours through ``TrajOptSolver.solve()`` against Drake, in alternating runs.

    ``options`` are our solvers' IPOPT options (default: the library's; e.g.
    another linear solver); Drake keeps its own IPOPT settings and MUMPS.

    Each of our solvers is built as a user builds it and warmed up past the
    expansion of its NLP functions (``EXPAND_AFTER_SOLVES + 1`` solves, those
    before it timed and reported as the assembled functions' CPU); then
    ``drake_repeats`` rounds each run, per method, one uncounted warm-up solve
    of ours (Drake's run has evicted our caches), about
    ``ours_total / drake_repeats`` counted ones (at least ``ours_total`` in all)
    and one Drake solve, so both see the same machine state. Medians are reported.
    Drake is skipped (with the install hint) when pydrake is not installed.
    """
    for m in METHODS:  # fill the kernel cache first (a user's second session)
        TrajOptSolver(study1_problem(50), m, compile="wait")
    ours = {m: TrajOptSolver(study1_problem(50), m, options) for m in METHODS}
    assembled: dict[str, list[float]] = {m: [] for m in METHODS}
    for m, solver in ours.items():
        # warm-up: the first call, then the solves before the functions' expansion
        # (TrajOptSolver: a solver solved more than EXPAND_AFTER_SOLVES times runs
        # them as SX), timed as the "assembled" column; the counted runs come after
        solver.solve(beta=BETA)
        for _ in range(EXPAND_AFTER_SOLVES - 1):
            assembled[m].append(_timed(lambda s=solver: s.solve(beta=BETA))[2])
        solver.solve(beta=BETA)  # the expansion and the first solve after it
    try:
        drake: DrakeBaselines | None = DrakeBaselines(ours["trapezoidal"], BETA)
        note = ""
    except ImportError as exc:
        drake, note = (
            None,
            f"Drake baseline skipped, pydrake is not installed ({exc}): {DRAKE_HINT}",
        )
    if drake is not None:
        for m in METHODS:  # Drake's warm-up
            drake.solve(m)
    runs: dict[str, dict[str, list[float]]] = {
        m: {k: [] for k in ("cpu", "wall", "ipopt_cpu", "drake_cpu", "drake_wall")} for m in METHODS
    }
    last: dict[str, Any] = {}
    drake_f: dict[str, tuple[float, bool]] = {}
    rounds = max(drake_repeats, 1)
    for _ in range(rounds):
        for m in METHODS:
            ours[m].solve(beta=BETA)  # warm-up after the other solver's run (not counted)
            for _ in range(-(-ours_total // rounds)):
                res, wall, cpu = _timed(lambda m=m: ours[m].solve(beta=BETA))
                runs[m]["cpu"].append(cpu)
                runs[m]["wall"].append(wall)
                runs[m]["ipopt_cpu"].append(res.stats.cpu_time)
                last[m] = res
            if drake is not None:
                wall, cpu, f, ok = drake.solve(m)
                runs[m]["drake_cpu"].append(cpu)
                runs[m]["drake_wall"].append(wall)
                drake_f[m] = (f, ok)
    out: dict[str, Any] = {"note": note, "linear_solver": ours[METHODS[0]].options.linear_solver}
    for m in METHODS:
        r = {k: statistics.median(v) if v else float("nan") for k, v in runs[m].items()}
        res = last[m]
        r.update(n_ours=len(runs[m]["cpu"]), n_drake=len(runs[m]["drake_cpu"]))
        r.update(objective=res.objective, iterations=res.iterations, status=res.status.value)
        r.update(compiled=ours[m].compiled, expanded=ours[m].expanded)
        r.update(assembled_cpu=statistics.median(assembled[m]) if assembled[m] else float("nan"))
        if m in drake_f:
            r.update(drake_objective=drake_f[m][0], drake_success=drake_f[m][1])
            r.update(ratio_cpu=r["drake_cpu"] / r["cpu"], ratio_wall=r["drake_wall"] / r["wall"])
        out[m] = r
    if drake is not None:
        out["drake_dynamics_error"] = drake.dynamics_error
    return out


def print_side_by_side(sbs: dict[str, Any]) -> None:
    """The side-by-side table (ours through solve() against Drake)."""
    targets = {"trapezoidal": TARGET_TRAPEZOID_CPU, "hermite_simpson": TARGET_HS_CPU}
    print(
        "\nside by side: study-1 base case (50 knots, beta = 0.5, straight-line start, "
        "IPOPT tol 1e-8), ours through TrajOptSolver.solve(), alternating runs, medians; "
        f"our linear solver {sbs['linear_solver']}"
    )
    print(
        f"{'method':<16} {'ours CPU':>9} {'wall':>8} {'target':>8} {'':>4} {'f':>9} {'iter':>4}"
        f" | {'Drake':<42} {'CPU':>7} {'wall':>7} {'f':>9} | {'CPU x':>7} {'wall x':>7} {'goal':>6}"
    )
    for m in METHODS:
        r = sbs[m]
        target = targets[m]
        line = (
            f"{m:<16} {r['cpu']:>9.4f} {r['wall']:>8.4f} {'<= ' + str(target):>8} "
            f"{_verdict(r['cpu'], target):>4} {r['objective']:>9.6f} {r['iterations']:>4}"
        )
        if "ratio_cpu" in r:
            ok = "" if r["drake_success"] else " (failed)"
            line += (
                f" | {DRAKE_NAMES[m] + ok:<42} {r['drake_cpu']:>7.3f} {r['drake_wall']:>7.3f} "
                f"{r['drake_objective']:>9.6f} | {r['ratio_cpu']:>6.1f}x {r['ratio_wall']:>6.1f}x "
                f"{_verdict(r['ratio_cpu'], TARGET_DRAKE_RATIO, larger_is_better=True):>6}"
            )
        print(line)
    for m in METHODS:
        r = sbs[m]
        outside = r["cpu"] - r["ipopt_cpu"]
        print(
            f"  {m}: {r['n_ours']} solves of ours (kernels "
            f"{'compiled' if r['compiled'] else 'in the CasADi VM'}), {r['n_drake']} of Drake; "
            "the IPOPT call "
            f"(with the best-iterate callback) {r['ipopt_cpu']:.4f} s CPU, the rest of solve() "
            f"(guess, result, independent pin.aba check) {outside:.4f} s; functions "
            f"{'expanded to SX' if r['expanded'] else 'assembled (MX)'}, the "
            f"{EXPAND_AFTER_SOLVES - 1} solves before the expansion {r['assembled_cpu']:.4f} s CPU"
        )
    if sbs["note"]:
        print(sbs["note"])
    else:
        print(
            f"  Drake's plant from the same URDF: max |a_drake - a_pinocchio| = "
            f"{sbs['drake_dynamics_error']:.1e} rad/s^2; Drake's IPOPT has no exact Hessian "
            f"(limited-memory); goal >= {TARGET_DRAKE_RATIO:.0f}x"
        )


def _verdict(value: float, target: float, *, larger_is_better: bool = False) -> str:
    ok = value >= target if larger_is_better else value <= target
    return "PASS" if ok else "MISS"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="knots <= 200, 10 starts, 5 weights")
    parser.add_argument("--levers", action="store_true", help="also measure each speed lever")
    parser.add_argument("--workers", type=int, default=2, help="multistart pool size (default 2)")
    parser.add_argument(
        "--slsqp-cap", type=float, default=None, help="SLSQP CPU cap in [s] (default 300, quick 30)"
    )
    parser.add_argument("--json", action="store_true", help="print the figures as JSON too")
    parser.add_argument(
        "--side-by-side", action="store_true", help="only the table of ours against Drake"
    )
    parser.add_argument(
        "--drake-repeats", type=int, default=None, help="alternating rounds (default 5, quick 3)"
    )
    parser.add_argument(
        "--linear-solver",
        default="mumps",
        help="our IPOPT linear solver for the side-by-side table (default mumps; HSL's ma57, "
        "ma27, ... need --linear-solver-library)",
    )
    parser.add_argument(
        "--linear-solver-library", default=None, help="path of libhsl.so (or Pardiso's library)"
    )
    args = parser.parse_args()
    options = IpoptOptions(
        linear_solver=args.linear_solver, linear_solver_library=args.linear_solver_library
    )
    repeats = args.drake_repeats if args.drake_repeats is not None else (3 if args.quick else 5)
    if args.side_by_side:
        load = os.getloadavg()
        sbs = side_by_side(repeats, options=options)
        print(f"load average at start {load[0]:.2f}, at end {os.getloadavg()[0]:.2f} (2 cores)")
        print_side_by_side(sbs)
        if args.levers:
            print("\n" + "\n".join(solve_levers()))
        if args.json:
            print(json.dumps({"side_by_side": sbs}))
        return
    quick = args.quick
    cap = args.slsqp_cap if args.slsqp_cap is not None else (30.0 if quick else 300.0)
    knots = (25, 50, 100, 200) if quick else (25, 50, 100, 200, 400, 800, 1600)
    n_starts = 10 if quick else 50
    betas = DEFAULT_BETAS[::4] if quick else DEFAULT_BETAS
    load0 = os.getloadavg()
    out: dict[str, Any] = {"quick": quick, "loadavg_start": load0}

    # -- base case: cold build (empty kernel cache), cached build, solve
    with tempfile.TemporaryDirectory() as cache:
        old = os.environ.get("YOUBOT_OPT_CACHE")
        os.environ["YOUBOT_OPT_CACHE"] = cache
        try:
            # "wait": compile now (the default compiles in the background and
            # runs this build in CasADi's VM), so the second build loads the cache
            _, cold_build, _ = _build(50, compile="wait")
            solver, cached_build, _ = _build(50)
        finally:
            if old is None:
                del os.environ["YOUBOT_OPT_CACHE"]
            else:
                os.environ["YOUBOT_OPT_CACHE"] = old
    base, base_wall, base_cpu = _repeat_solve(solver, 20)
    out["base"] = {
        "build_cold_s": cold_build, "build_cached_s": cached_build, "solve_wall_s": base_wall,
        "solve_cpu_s": base_cpu, "objective": base.objective, "iterations": base.iterations,
        "compiled": solver.compiled,
    }  # fmt: skip

    sbs = side_by_side(repeats, options=options)
    out["side_by_side"] = sbs
    slsqp = slsqp_baseline(solver, cap)
    ratio_cpu = slsqp["cpu"] / base_cpu
    ratio_wall = slsqp["wall"] / base_wall
    out["slsqp"] = {**slsqp, "ratio_cpu": ratio_cpu, "ratio_wall": ratio_wall}

    # -- scaling over knots
    scaling = []
    for n in knots:
        s, build, build_cpu = _build(n)
        res, wall, cpu = _repeat_solve(s, 3 if n <= 200 else 1)
        loose = TrajOptSolver(s.problem, options=IpoptOptions(tol=1e-6)).solve(beta=BETA)
        tight = TrajOptSolver(s.problem, options=IpoptOptions(tol=1e-10)).solve(beta=BETA)
        scaling.append({
            "n_knots": n, "build_s": build, "build_cpu_s": build_cpu, "solve_wall_s": wall,
            "solve_cpu_s": cpu, "iterations": res.iterations, "objective": res.objective,
            "status": res.status.value, "objective_tol_1e-6": loose.objective,
            "iterations_tol_1e-6": loose.iterations, "objective_tol_1e-10": tight.objective,
        })  # fmt: skip
    out["scaling"] = scaling
    # Mesh refinement: the largest grid started from the 50-knot solution (resampled).
    refined, refined_wall, refined_cpu = _timed(lambda: s.solve(beta=BETA, guess=base))
    out["refined"] = {
        "n_knots": knots[-1], "solve_wall_s": refined_wall, "solve_cpu_s": refined_cpu,
        "iterations": refined.iterations, "objective": refined.objective,
    }  # fmt: skip

    # -- multistart and Pareto sweep on the base-case solver
    ms, ms_wall, _ = _timed(
        lambda: run_multistart(
            solver,
            n_starts,
            beta=BETA,
            seed=0,
            sweep=SweepOptions(executor="process", workers=args.workers),
        )  # fmt: skip
    )
    # default: the points run one after another in one crash-isolated worker process
    front, pareto_wall, _ = _timed(lambda: pareto_sweep(solver, betas))
    # in-process (no isolation): its CPU time is the solver work itself
    _, pareto_serial_wall, pareto_cpu = _timed(
        lambda: pareto_sweep(solver, betas, sweep=SweepOptions(executor="serial"))
    )
    optima = ms.distinct_optima()
    out["multistart"] = {
        "n_starts": n_starts, "workers": args.workers, "wall_s": ms_wall,
        "success_rate": ms.success_rate, "optima": [[o.objective, o.count] for o in optima],
    }  # fmt: skip
    out["pareto"] = {
        "n_points": len(betas), "wall_s": pareto_wall,
        "serial_wall_s": pareto_serial_wall, "serial_cpu_s": pareto_cpu,
        "iterations": sum(p.iterations for p in front.points),
    }  # fmt: skip
    out["loadavg_end"] = os.getloadavg()

    # -- report
    bound = ">=" if slsqp["capped"] else ""
    print(f"load average at start {load0[0]:.2f}, at end {out['loadavg_end'][0]:.2f} (2 cores)")
    print(f"\n{'case':<52} {'measured':>12} {'target':>10} {'':>5}")
    # fmt: off
    rows: list[tuple[str, str, str, str]] = []

    def row(name: str, value: str, target: str = "", verdict: str = "") -> None:
        rows.append((name, value, target, verdict))

    row("base case solve() CPU [s] (median of 20)", f"{base_cpu:.4f}", f"<= {TARGET_SOLVE_CPU}",
        _verdict(base_cpu, TARGET_SOLVE_CPU))
    row("base case solve, wall [s]", f"{base_wall:.4f}")
    row("NLP build, empty kernel cache [s]", f"{cold_build:.3f}")
    row("NLP build, cached kernels [s]", f"{cached_build:.3f}", f"<= {TARGET_BUILD}",
        _verdict(cached_build, TARGET_BUILD))
    row("SLSQP (finite differences) / IPOPT, CPU", f"{bound}{ratio_cpu:.0f}x",
        f">= {TARGET_RATIO:.0f}x", _verdict(ratio_cpu, TARGET_RATIO, larger_is_better=True))
    row("SLSQP / IPOPT, wall", f"{bound}{ratio_wall:.0f}x")
    for r in scaling:
        if r["n_knots"] == 1600:
            row("1600 knots solve, CPU [s]", f"{r['solve_cpu_s']:.3f}", f"<= {TARGET_1600}",
                _verdict(r["solve_cpu_s"], TARGET_1600))
            row("1600 knots solve, wall [s]", f"{r['solve_wall_s']:.3f}", f"<= {TARGET_1600}",
                _verdict(r["solve_wall_s"], TARGET_1600))
    row(f"{knots[-1]} knots from the 50-knot solution, CPU [s]", f"{refined_cpu:.3f}")
    row(f"{knots[-1]} knots from the 50-knot solution, wall [s]", f"{refined_wall:.3f}")
    full = len(betas) == 19 and n_starts == 50
    row(f"Pareto {len(betas)} points warm-started, one worker, wall [s]", f"{pareto_wall:.3f}",
        f"<= {TARGET_PARETO}" if full else "", _verdict(pareto_wall, TARGET_PARETO) if full else "")
    row("  same, in-process (executor='serial'), wall [s]", f"{pareto_serial_wall:.3f}")
    row("  same, in-process (executor='serial'), CPU [s]", f"{pareto_cpu:.3f}")
    row(f"multistart {n_starts} starts, {args.workers} workers, wall [s]", f"{ms_wall:.3f}",
        f"<= {TARGET_MULTISTART}" if full else "",
        _verdict(ms_wall, TARGET_MULTISTART) if full else "")
    # fmt: on
    for name, value, target, verdict in rows:
        print(f"{name:<52} {value:>12} {target:>10} {verdict:>5}")

    print(
        f"\nbase case: IPOPT f = {base.objective:.6f} ({base.iterations} iterations, kernels "
        f"{'compiled' if solver.compiled else 'in the CasADi VM'}); SLSQP f = "
        f"{slsqp['objective']:.6f}, max |g| = {slsqp['violation']:.1e}, "
        f"{slsqp['iterations']} iterations, {slsqp['cpu']:.1f} s CPU ({slsqp['message']})"
    )
    print(
        f"multistart: success rate {100 * ms.success_rate:.0f} %, {len(optima)} distinct optima "
        + ", ".join(f"f = {o.objective:.6f} x{o.count}" for o in optima)
    )
    print(f"pareto: {out['pareto']['iterations']} IPOPT iterations in total")
    print(
        f"{knots[-1]} knots from the 50-knot solution: f = {refined.objective:.7f}, "
        f"{refined.iterations} iterations (from the straight line: f = "
        f"{scaling[-1]['objective']:.7f}, {scaling[-1]['iterations']} iterations)"
    )
    print(
        f"\n{'knots':>5} {'build [s]':>9} {'build CPU':>9} {'solve [s]':>9} {'solve CPU':>9} "
        f"{'iter':>5} {'f (tol 1e-8)':>13} {'f (tol 1e-6)':>13} {'iter':>5} {'f (tol 1e-10)':>13}"
    )
    for r in scaling:
        print(
            f"{r['n_knots']:>5} {r['build_s']:>9.3f} {r['build_cpu_s']:>9.3f} "
            f"{r['solve_wall_s']:>9.3f} {r['solve_cpu_s']:>9.3f} {r['iterations']:>5} "
            f"{r['objective']:>13.7f} {r['objective_tol_1e-6']:>13.7f} "
            f"{r['iterations_tol_1e-6']:>5} {r['objective_tol_1e-10']:>13.7f}"
        )
    print_side_by_side(sbs)
    if args.levers:
        lever_rows: list[str] = []
        _levers(lever_rows)
        print("\n" + "\n".join(lever_rows))
    if args.json:
        print(json.dumps(out))


if __name__ == "__main__":
    main()
