"""Time forward dynamics and its Jacobian for each dynamics backend vs Pinocchio.

Run ``python benchmarks/bench_dynamics.py [--quick]``. For the youBot arm (from
``youbot_opt.robot.load.load_model``) and the UR5 it measures, per call:

* ``pin.aba`` and ``pin.computeABADerivatives`` called from Python (reference);
* the symbolic backend's ``forward_dynamics`` (ABA transcription) and the CRBA
  variant ``M⁻¹(tau - nle)`` as SX Functions, and the ABA JIT-compiled by gcc
  at -O0 (if gcc is found; higher levels take minutes to compile the UR5
  Hessian);
* the ``"pinocchio"`` Callback backend;
* each one's Jacobian w.r.t. (q, v, tau), and for the symbolic variants the
  Hessian of ``λᵀ a`` (what IPOPT's exact Hessian needs).

Two timings are reported: a Python call of the Function (includes CasADi's
Python-call overhead, a few µs) and the per-knot cost inside ``.map(N)`` (one
call over N knots, as an NLP evaluates it). Both are divided by the same
Pinocchio reference, itself a Python call (with pybind/boost binding overhead):

* ``call / pin``: Python call of the Function / Python call of Pinocchio, the
  like-for-like comparison (both pay a Python-call overhead);
* ``map / pin``: per-knot time inside ``.map(N)`` / Python call of Pinocchio,
  which flatters CasADi (its per-knot cost carries no Python overhead while
  the reference does); it is what an NLP's constraint evaluation sees.

Medians over repeated runs; the machine is shared, so expect ~20 % noise.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import time
from collections.abc import Callable

import casadi as ca
import numpy as np
import pinocchio as pin

from youbot_opt.dynamics import build_dynamics, build_symbolic_model

N_MAP = 200  # knots per mapped call


def _median_time(fn: Callable[[], object], reps: int, sample_time: float) -> float:
    """Median over ``reps`` samples of the mean time per call, in [s].

    Each sample repeats ``fn`` for about ``sample_time`` [s] (at least once).
    """
    start = time.perf_counter()
    fn()
    inner = max(1, int(sample_time / max(time.perf_counter() - start, 1e-7)))
    samples = []
    for _ in range(reps):
        start = time.perf_counter()
        for _ in range(inner):
            fn()
        samples.append((time.perf_counter() - start) / inner)
    return statistics.median(samples)


def _jit_options() -> dict[str, object] | None:
    """JIT via gcc at -O0: -O1 takes ~50 s to compile the UR5 Hessian (-O0: ~5 s)."""
    if shutil.which("gcc") is None:
        return None
    return {"jit": True, "compiler": "shell", "jit_options": {"compiler": "gcc", "flags": ["-O0"]}}


def _derived(fn: ca.Function, nv: int, sym: type, opts: dict[str, object]) -> list[ca.Function]:
    """Function, its Jacobian and (SX only) the Hessian of λᵀ f, all named."""
    q, v, u, lam = (sym.sym(n, nv) for n in ("q", "v", "u", "lam"))
    a = fn(q, v, u)
    x = ca.vertcat(q, v, u)
    out = [
        ca.Function("f", [q, v, u], [a], opts),
        ca.Function("jacobian_a", [q, v, u], [ca.jacobian(a, x)], opts),
    ]
    if sym is ca.SX:
        hess, _ = ca.hessian(ca.dot(lam, a), x)
        out.append(ca.Function("hessian_lagrangian", [q, v, u, lam], [hess], opts))
    return out


def bench_robot(
    label: str, model: pin.Model, reps: int, sample_time: float
) -> list[tuple[str, ...]]:
    """Return table rows.

    Each row is (robot, variant, quantity, Python call [µs], per knot in map [µs],
    call / pin, map / pin); the ratios divide by Pinocchio's Python call.
    """
    rng = np.random.default_rng(0)
    nv = model.nv
    q, v, tau = rng.uniform(-1, 1, nv), rng.normal(size=nv), rng.normal(size=nv)
    lam = rng.normal(size=nv)
    data = model.createData()
    b = model.damping
    t_aba = _median_time(lambda: pin.aba(model, data, q, v, tau - b * v), reps, sample_time)
    t_der = _median_time(
        lambda: pin.computeABADerivatives(model, data, q, v, tau - b * v), reps, sample_time
    )
    rows = [
        (label, "pin (python)", "a", f"{t_aba * 1e6:.2f}", "-", "1.00", "-"),
        (label, "pin (python)", "da/dx", f"{t_der * 1e6:.2f}", "-", "1.00", "-"),
    ]
    sym_model = build_symbolic_model(model)
    dyn_sym = build_dynamics(model, "symbolic")
    dyn_cb = build_dynamics(model, "pinocchio")
    bvec = ca.DM(b)
    qs, vs, us = (ca.SX.sym(n, nv) for n in ("q", "v", "u"))
    crba_fd = ca.Function(
        "fd_crba", [qs, vs, us], [sym_model.forward_dynamics_crba(qs, vs, us - bvec * vs)]
    )
    variants: list[tuple[str, ca.Function, type, dict[str, object]]] = [
        ("symbolic ABA", dyn_sym.forward_dynamics, ca.SX, {"cse": True}),
        ("symbolic CRBA", crba_fd, ca.SX, {"cse": True}),
    ]
    jit = _jit_options()
    if jit is not None:
        jit_opts = {"cse": True, **jit}
        variants.append(("symbolic ABA jit", dyn_sym.forward_dynamics, ca.SX, jit_opts))
    variants.append(("callback", dyn_cb.forward_dynamics, ca.MX, {}))
    tile = [np.tile(x[:, None], (1, N_MAP)) for x in (q, v, tau, lam)]
    for name, fn, sym, opts in variants:
        fns = _derived(fn, nv, sym, opts)
        for quantity, f, ref in zip(
            ("a", "da/dx", "hess λᵀa"), fns, (t_aba, t_der, t_der), strict=False
        ):
            args = (q, v, tau, lam)[: f.n_in()]
            t_call = _median_time(lambda f=f, args=args: f(*args), reps, sample_time)
            mapped = f.map(N_MAP)
            margs = tile[: f.n_in()]
            t_map = _median_time(lambda m=mapped, a=margs: m(*a), reps, sample_time) / N_MAP
            size = f.n_instructions() if sym is ca.SX else "-"
            rows.append(
                (
                    label,
                    f"{name} [{size} instr]",
                    quantity,
                    f"{t_call * 1e6:.2f}",
                    f"{t_map * 1e6:.2f}",
                    f"{t_call / ref:.2f}",
                    f"{t_map / ref:.2f}",
                )
            )
    return rows


def _models() -> list[tuple[str, pin.Model]]:
    from youbot_opt.robot.load import load_model

    out = []
    for name in ("youbot", "ur5"):
        robot = load_model(name, damping=0.1) if name == "youbot" else load_model(name)
        out.append((name, robot.model))
    return out


def main() -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repetitions (smoke test)")
    args = parser.parse_args()
    reps, sample_time = (3, 0.005) if args.quick else (9, 0.03)
    start = time.perf_counter()
    rows: list[tuple[str, ...]] = []
    for label, model in _models():
        rows.extend(bench_robot(label, model, reps, sample_time))
    header = (
        "robot",
        "variant",
        "quantity",
        "python call [µs]",
        f"in map({N_MAP}) [µs/knot]",
        "call / pin",
        "map / pin",
    )
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    for row in [header, *rows]:
        print("  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)))
    print(
        "\nReference 'pin': Pinocchio called from Python (pin.aba for a, "
        "computeABADerivatives for da/dx and hess λᵀa), binding overhead included."
        "\ncall / pin: Python call of the Function / that reference (like for like)."
        f"\nmap / pin:  per-knot time inside one map(N={N_MAP}) call / that reference "
        "(no Python overhead on the CasADi side; what an NLP evaluation sees)."
        f"\ngcc jit: {'on' if _jit_options() else 'off'}; "
        f"total {time.perf_counter() - start:.1f} s"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
