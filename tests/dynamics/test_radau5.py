"""Radau IIA without SciPy: SciPy's Radau step for step, stiff accuracy, stacked rows, failures."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.integrate._ivp import radau as scipy_radau
from scipy.linalg import expm

from _steppers import step_to_end
from youbot_opt.dynamics import radau5
from youbot_opt.dynamics.radau5 import Radau5
from youbot_opt.dynamics.stepper import MAX_FACTOR, MIN_FACTOR, TOO_SMALL_STEP

MU = 100.0  # Van der Pol's stiffness: relaxation phases at rate ~ MU, jumps in ~ 1 / MU


def _vdp_row(t: float, y: np.ndarray) -> np.ndarray:
    return np.array([y[1], MU * (1.0 - y[0] ** 2) * y[1] - y[0]])


def _vdp_jac_row(t: float, y: np.ndarray) -> np.ndarray:
    return np.array([[0.0, 1.0], [-2.0 * MU * y[0] * y[1] - 1.0, MU * (1.0 - y[0] ** 2)]])


def _vdp(t: float, y: np.ndarray) -> np.ndarray:
    """Van der Pol oscillators, one a row: y = [x, x']."""
    out = np.empty_like(y)
    out[:, 0] = y[:, 1]
    out[:, 1] = MU * (1.0 - y[:, 0] ** 2) * y[:, 1] - y[:, 0]
    return out


def _vdp_jac(t: float, y: np.ndarray) -> np.ndarray:
    """One 2x2 block a row."""
    return np.array([_vdp_jac_row(t, row) for row in y])


@functools.cache
def _vdp_reference(t_end: float) -> np.ndarray:
    """Van der Pol from (2, 0) at ``t_end`` by SciPy's Radau at rtol 1e-13 (slow: once)."""
    return solve_ivp(
        _vdp_row, (0.0, t_end), [2.0, 0.0], method="Radau", rtol=1e-13, atol=1e-15,
        jac=_vdp_jac_row,
    ).y[:, -1]  # fmt: skip


def _integrate(fun, jac, y0: np.ndarray, t_end: float, **kwargs) -> tuple[Radau5, list[float]]:
    stepper = Radau5(fun, jac, 0.0, y0, t_bound=t_end, **kwargs)
    return stepper, step_to_end(stepper, t_end)


def test_coefficients_are_scipys() -> None:
    """The nodes, error weights, eigenvalues, transformations and dense output equal SciPy's."""
    for ours, theirs in (
        (radau5._C, scipy_radau.C),
        (radau5._E, scipy_radau.E),
        (radau5._T, scipy_radau.T),
        (radau5._TI, scipy_radau.TI),
        (radau5._TI_REAL, scipy_radau.TI_REAL),
        (radau5._TI_COMPLEX, scipy_radau.TI_COMPLEX),
        (radau5._P, scipy_radau.P),
    ):
        np.testing.assert_array_equal(ours, theirs)
    assert radau5._MU_REAL == scipy_radau.MU_REAL
    assert radau5._MU_COMPLEX == scipy_radau.MU_COMPLEX
    assert radau5._NEWTON_MAXITER == scipy_radau.NEWTON_MAXITER
    assert (MIN_FACTOR, MAX_FACTOR) == (
        scipy_radau.MIN_FACTOR,
        scipy_radau.MAX_FACTOR,
    )


@pytest.mark.parametrize(
    "rtol, atol, drift", [(1e-3, 1e-6, 1e-5), (1e-6, 1e-9, 1e-5), (1e-10, 1e-12, 2e-3)]
)
def test_one_row_takes_scipys_steps(rtol: float, atol: float, drift: float) -> None:
    """Van der Pol (mu 100) to t = 100 with the exact Jacobian: SciPy's Radau's steps.

    Same algorithm, so the same accepted steps and the same evaluations of f
    and of the Jacobian, up to rounding: the error estimate and the Newton
    increments are differences of stage values, so rounding (1e-16) enters
    them as about 1e-16 / tol relative and the step times carry it from step
    to step. Measured: step times within 7e-8 relative at tol 1e-3, 6e-7 at
    1e-6 and 1.7e-4 at 1e-10; ``drift`` is 10x that. The states are compared
    with a reference (SciPy's Radau at rtol 1e-13), not with SciPy's: ours
    must be as accurate as SciPy's, within 1e-2 of the tolerance (the errors
    are 1e-3 to 5e-2 tolerances).
    """
    t_end, y0 = 100.0, np.array([2.0, 0.0])
    sol = solve_ivp(
        _vdp_row, (0.0, t_end), y0, method="Radau", rtol=rtol, atol=atol, jac=_vdp_jac_row,
        dense_output=True,
    )  # fmt: skip
    stepper, times = _integrate(_vdp, _vdp_jac, y0[None], t_end, rtol=rtol, atol=atol)
    assert len(times) == sol.t.size
    assert (stepper.nfev, stepper.njev) == (sol.nfev, sol.njev)
    np.testing.assert_allclose(times, sol.t, rtol=drift, atol=0.0)
    exact = _vdp_reference(t_end)
    tol = atol + rtol * np.abs(exact)
    ours, scipys = np.abs(stepper.y[0] - exact), np.abs(sol.y[:, -1] - exact)
    assert np.all(ours <= scipys + 1e-2 * tol), (ours / tol, scipys / tol)
    inside = np.linspace(stepper.t_old, stepper.t, 7)
    assert np.all(np.abs(stepper.dense(inside)[:, 0] - sol.sol(inside).T) <= tol)


def test_a_stiff_linear_system_is_accurate_to_the_tolerance() -> None:
    """y' = A y with eigenvalues -1e4, -1e3 and -0.5 +- 3i against expm (stiffness ratio 2e4).

    Radau IIA is L-stable and the local error of each step is held below the
    tolerance, so the global error of this contracting system stays within a
    few tolerances: within 10 (atol + rtol |y|) at the end and on the dense
    output of the last step. The fast modes are excited at the start, so the
    first steps resolve them (2e-6 s); then the steps grow far beyond the
    explicit stability limit (about 3 / 1e4 s): fewer than a tenth of the
    1.3e4 steps an explicit method would need.
    """
    rng = np.random.default_rng(3)
    basis = rng.normal(size=(4, 4))
    blocks = np.zeros((4, 4))
    blocks[0, 0], blocks[1, 1] = -1e4, -1e3
    blocks[2:, 2:] = [[-0.5, 3.0], [-3.0, -0.5]]
    a = basis @ blocks @ np.linalg.inv(basis)
    y0 = np.array([[1.0, -0.5, 0.3, 2.0]])
    rtol, atol = 1e-8, 1e-10
    stepper, times = _integrate(
        lambda t, y: y @ a.T, lambda t, y: a[None], y0, 4.0, rtol=rtol, atol=atol
    )
    exact = expm(4.0 * a) @ y0[0]
    assert np.all(np.abs(stepper.y[0] - exact) <= 10.0 * (atol + rtol * np.abs(exact)))
    mid = 0.5 * (stepper.t_old + stepper.t)
    exact_mid = expm(mid * a) @ y0[0]
    got = stepper.dense(np.array([mid]))[0, 0]
    assert np.all(np.abs(got - exact_mid) <= 10.0 * (atol + rtol * np.abs(exact_mid)))
    assert len(times) < 1300


def test_stacked_rows_and_blocks_take_the_largest_rows_steps() -> None:
    """Two Van der Pol rows, one Jacobian block each: the stiffer row decides the steps.

    Stacking a row twice takes the row's steps (to rounding: the same count,
    times to 1e-5 relative). A small start stacked with it, or the two as one
    row of 4 with two 2x2 blocks (one norm over both, SciPy's way), end within
    10 tolerances of a reference (SciPy's Radau at rtol 1e-13).
    """
    rtol, atol, t_end = 1e-6, 1e-9, 20.0
    wild, calm = np.array([[2.0, 0.0]]), np.array([[0.01, 0.0]])
    one, times_one = _integrate(_vdp, _vdp_jac, wild, t_end, rtol=rtol, atol=atol)
    two, times_two = _integrate(
        _vdp, _vdp_jac, np.vstack([wild, wild]), t_end, rtol=rtol, atol=atol
    )
    assert len(times_two) == len(times_one)
    np.testing.assert_allclose(times_two, times_one, rtol=1e-5, atol=0.0)
    both, times_both = _integrate(
        _vdp, _vdp_jac, np.vstack([wild, calm]), t_end, rtol=rtol, atol=atol
    )
    assert len(times_both) >= len(times_one)
    ref = solve_ivp(
        _vdp_row, (0.0, t_end), calm[0], method="Radau", rtol=1e-13, atol=1e-15, jac=_vdp_jac_row
    ).y[:, -1]

    def flat(t: float, y: np.ndarray) -> np.ndarray:
        return _vdp(t, y.reshape(2, 2)).reshape(1, 4)

    def flat_jac(t: float, y: np.ndarray) -> np.ndarray:
        return _vdp_jac(t, y.reshape(2, 2))

    joint, _ = _integrate(flat, flat_jac, np.hstack([wild, calm]), t_end, rtol=rtol, atol=atol)
    ref_wild = _vdp_reference(t_end)
    refs = np.concatenate([ref_wild, ref])
    tol = 10.0 * (atol + rtol * np.abs(refs))
    assert np.all(np.abs(joint.y[0] - refs) <= tol)
    assert np.all(np.abs(both.y.reshape(-1) - refs) <= tol)


def test_knot_to_knot_steps_end_on_each_knot_and_keep_their_length() -> None:
    """Forcing that jumps at knots: every step ends on a knot, not across one; after a
    cut step the next may be as long as before; the solution matches a per-knot restart.
    """
    knots = np.linspace(0.0, 2.0, 9)
    level = {"k": 0}

    def fun(t: float, y: np.ndarray) -> np.ndarray:
        out = _vdp(t, y)
        out[:, 1] += 50.0 * (-1.0) ** level["k"]
        return out

    rtol, atol = 1e-8, 1e-10
    stepper = Radau5(fun, _vdp_jac, 0.0, np.array([[2.0, 0.0]]), rtol=rtol, atol=atol,
                     t_bound=knots[1])  # fmt: skip
    for k in range(knots.size - 1):
        level["k"] = k
        if k:
            stepper.refresh()
        while stepper.t < knots[k + 1]:
            assert stepper.step(knots[k + 1])
            assert stepper.t <= knots[k + 1]
        assert stepper.t == knots[k + 1]
    x = np.array([2.0, 0.0])
    for k in range(knots.size - 1):
        level["k"] = k
        x = solve_ivp(
            lambda t, y: fun(t, y[None])[0], (knots[k], knots[k + 1]), x, method="Radau",
            rtol=1e-12, atol=1e-14, jac=_vdp_jac_row,
        ).y[:, -1]  # fmt: skip
    assert np.all(np.abs(stepper.y[0] - x) <= 10.0 * (atol + rtol * np.abs(x)))
    # a step cut to a tenth of its size: its error is ~1e-4 of a full step's, so
    # the controller would grow it (factor >= 1), and the next step is the full one
    wanted = stepper.h_abs
    bound = stepper.t + 0.1 * wanted
    assert stepper.step(bound) and stepper.t == bound
    assert stepper.h_abs >= wanted


def test_a_nan_derivative_fails_the_step_and_keeps_the_state() -> None:
    """NaN from f after t = 0.5: the step halves until too small, then fails, state kept."""

    def poisoned(t: float, y: np.ndarray) -> np.ndarray:
        return _vdp(t, y) * (np.nan if t > 0.5 else 1.0)

    stepper = Radau5(poisoned, _vdp_jac, 0.0, np.array([[2.0, 0.0]]), rtol=1e-8, atol=1e-10,
                     t_bound=2.0)  # fmt: skip
    while stepper.step(2.0):
        assert stepper.t <= 0.5 and np.all(np.isfinite(stepper.y))
    assert stepper.message == TOO_SMALL_STEP and stepper.t <= 0.5
    assert np.all(np.isfinite(stepper.y))
