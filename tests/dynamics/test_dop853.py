"""DOP853 without SciPy: SciPy's DOP853 step for step, row-wise error control, failures."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.integrate._ivp import dop853_coefficients as scipy_coefficients
from scipy.linalg import expm

from _steppers import step_to_end
from youbot_opt.dynamics import dop853
from youbot_opt.dynamics.dop853 import Dop853
from youbot_opt.dynamics.stepper import TOO_SMALL_STEP

RTOL, ATOL = 1e-10, 1e-12


def _pendulum(t: float, y: np.ndarray) -> np.ndarray:
    """Forced pendulums, one a row: y = [angle, rate], gravity 9.81, forcing cos(3 t)."""
    out = np.empty_like(y)
    out[:, 0] = y[:, 1]
    out[:, 1] = -9.81 * np.sin(y[:, 0]) + np.cos(3.0 * t)
    return out


def _integrate(fun, y0: np.ndarray, t_end: float, **kwargs) -> tuple[Dop853, list[float]]:
    stepper = Dop853(fun, 0.0, y0, t_bound=t_end, **kwargs)
    return stepper, step_to_end(stepper, t_end)


def test_coefficients_are_scipys() -> None:
    """The transcribed tableau, error weights and dense-output matrix equal SciPy's exactly."""
    np.testing.assert_array_equal(dop853._C, scipy_coefficients.C)
    np.testing.assert_array_equal(dop853._A, scipy_coefficients.A)
    np.testing.assert_array_equal(dop853._E3, scipy_coefficients.E3)
    np.testing.assert_array_equal(dop853._E5, scipy_coefficients.E5)
    np.testing.assert_array_equal(dop853._D, scipy_coefficients.D)


def _pendulum_row(t: float, y: np.ndarray) -> np.ndarray:
    return _pendulum(t, y[None])[0]


@pytest.mark.parametrize("rtol, atol", [(1e-10, 1e-12), (1e-6, 1e-9), (1e-3, 1e-6)])
@pytest.mark.parametrize("start", [(1.0, 0.0), (2.5, 3.0)])
def test_one_row_takes_scipys_steps(rtol: float, atol: float, start: tuple[float, float]) -> None:
    """With one row the steps are SciPy's DOP853's, and the states as accurate as SciPy's.

    Same algorithm, so the same steps, up to rounding: the error estimate is a
    cancellation of stage values, so rounding (1e-16) enters it as about
    1e-16 / tol relative, and the step sizes and times carry it from step to
    step. Measured: step times within 1.1e-4 relative at tol 1e-10 (SkylakeX;
    5e-5 Haswell), 3e-7 at 1e-6 and 1e-3; the bound is 10x that (1e-3, 1e-5).
    The states are not compared with SciPy's (their difference is that
    rounding's): both are compared with a reference solved at rtol 1e-13, and
    ours must be as accurate as SciPy's, within 1e-2 of the tolerance (the
    global errors here are 0.1-33 tolerances; a relative change of the steps of
    1e-4 changes them by about 1e-3 tolerance), at the end and on the last
    step's dense output.
    """
    y0 = np.array([start])
    ref = solve_ivp(
        _pendulum_row, (0.0, 5.0), y0[0], method="DOP853", rtol=1e-13, atol=1e-15,
        dense_output=True,
    )  # fmt: skip
    sol = solve_ivp(
        _pendulum_row, (0.0, 5.0), y0[0], method="DOP853", rtol=rtol, atol=atol, dense_output=True
    )
    stepper, times = _integrate(_pendulum, y0, 5.0, rtol=rtol, atol=atol)
    assert len(times) == sol.t.size
    np.testing.assert_allclose(times, sol.t, rtol=1e-3 if rtol < 1e-8 else 1e-5, atol=0.0)
    tol = atol + rtol * np.abs(ref.y[:, -1])
    ours, scipys = np.abs(stepper.y[0] - ref.y[:, -1]), np.abs(sol.y[:, -1] - ref.y[:, -1])
    assert np.all(ours <= scipys + 1e-2 * tol), (ours / tol, scipys / tol)
    inside = np.linspace(stepper.t_old, stepper.t, 7)
    exact = ref.sol(inside).T
    tol_in = atol + rtol * np.abs(exact)
    ours_in = np.abs(stepper.dense(inside)[:, 0] - exact)
    assert np.all(ours_in <= np.abs(sol.sol(inside).T - exact) + 1e-2 * tol_in)


def test_linear_system_is_accurate_to_the_tolerance() -> None:
    """y' = A y (a damped oscillator pair) against expm: global error within 10 (atol + rtol |y|).

    The local error of each step is held below the tolerance; over these ~60
    steps of a contracting system the global error stays within a few of them.
    """
    a = np.array([[0.0, 1.0, 0.0, 0.0], [-4.0, -0.2, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0],
                  [1.0, 0.0, -9.0, -0.1]])  # fmt: skip
    y0 = np.array([[1.0, 0.0, -0.5, 0.3]])
    stepper, _ = _integrate(lambda t, y: y @ a.T, y0, 4.0, rtol=RTOL, atol=ATOL)
    exact = expm(4.0 * a) @ y0[0]
    assert np.all(np.abs(stepper.y[0] - exact) <= 10.0 * (ATOL + RTOL * np.abs(exact)))
    mid = 0.5 * (stepper.t_old + stepper.t)
    exact_mid = expm(mid * a) @ y0[0]
    assert np.all(np.abs(stepper.dense(np.array([mid]))[0, 0] - exact_mid) <= 10.0 * (ATOL + RTOL))


def test_identical_rows_take_the_one_rows_steps() -> None:
    """Stacking a row twice takes the row's steps: the error norm is the largest row's.

    Not bitwise (the products of two rows round differently): the same number
    of steps, the step times to 1e-4 relative and the states to 1e-3 of the
    tolerance, as against SciPy above.
    """
    rtol, atol = 1e-8, 1e-10
    y0 = np.array([[1.0, 0.0]])
    one, times_one = _integrate(_pendulum, y0, 3.0, rtol=rtol, atol=atol)
    two, times_two = _integrate(_pendulum, np.vstack([y0, y0]), 3.0, rtol=rtol, atol=atol)
    assert len(times_one) == len(times_two)
    np.testing.assert_allclose(times_two, times_one, rtol=1e-4, atol=0.0)
    tol = 1e-3 * (atol + rtol * np.abs(one.y[0]))
    assert np.all(np.abs(two.y - one.y[0]) <= tol)


def test_each_row_is_held_to_the_tolerance() -> None:
    """A calm row stacked with a wild one: the wild row's error decides the steps.

    The stack takes the wild row's steps alone (to rounding) and no fewer, so
    the calm row comes out as accurate as integrated alone, or more.
    """
    wild, calm = np.array([[2.5, 3.0]]), np.array([[0.01, 0.0]])
    alone_wild, times_wild = _integrate(_pendulum, wild, 3.0, rtol=1e-8, atol=1e-10)
    alone_calm, times_calm = _integrate(_pendulum, calm, 3.0, rtol=1e-8, atol=1e-10)
    both, times_both = _integrate(_pendulum, np.vstack([wild, calm]), 3.0, rtol=1e-8, atol=1e-10)
    assert len(times_calm) < len(times_wild) <= len(times_both)
    reference = solve_ivp(
        lambda t, y: _pendulum(t, y[None])[0], (0.0, 3.0), calm[0], method="DOP853",
        rtol=1e-13, atol=1e-15,
    ).y[:, -1]  # fmt: skip
    error_alone = np.max(np.abs(alone_calm.y[0] - reference))
    error_stacked = np.max(np.abs(both.y[1] - reference))
    assert error_stacked <= error_alone + 1e-15
    np.testing.assert_allclose(both.y[0], alone_wild.y[0], rtol=1e-7, atol=1e-9)


def test_steps_end_on_the_bound_and_resume_at_their_length() -> None:
    """A step cut to land on a bound lands on it exactly; the next step is as long as before."""
    y0 = np.array([[1.0, 0.0]])
    stepper = Dop853(_pendulum, 0.0, y0, rtol=1e-6, atol=1e-9, t_bound=10.0)
    while stepper.t < 1.0:
        assert stepper.step(10.0)
    wanted = stepper.h_abs
    bound = stepper.t + 0.1 * wanted
    assert stepper.step(bound) and stepper.t == bound
    assert stepper.h_abs >= wanted


def test_a_nan_derivative_fails_the_step_and_keeps_the_state() -> None:
    """NaN from the right-hand side after t = 0.5: the step shrinks until too small, then fails.

    The state stays the last accepted one (before 0.5); a NaN from the start
    fails the first step (no endless loop on a NaN step size).
    """

    def poisoned(t: float, y: np.ndarray) -> np.ndarray:
        return _pendulum(t, y) * (np.nan if t > 0.5 else 1.0)

    stepper = Dop853(poisoned, 0.0, np.array([[1.0, 0.0]]), rtol=RTOL, atol=ATOL, t_bound=2.0)
    while stepper.step(2.0):
        assert stepper.t <= 0.5 and np.all(np.isfinite(stepper.y))
    assert stepper.message == TOO_SMALL_STEP and stepper.t <= 0.5
    assert np.all(np.isfinite(stepper.y))

    def nan(t: float, y: np.ndarray) -> np.ndarray:
        return np.full_like(y, np.nan)

    at_start = Dop853(nan, 0.0, np.array([[1.0, 0.0]]), rtol=RTOL, atol=ATOL, t_bound=2.0)
    assert not at_start.step(2.0) and at_start.message == TOO_SMALL_STEP and at_start.t == 0.0


def test_the_dense_output_is_the_steps_after_a_refresh() -> None:
    """A knot changes ``fun`` and ``refresh`` re-evaluates f: the last step's interpolant,
    built before the change, stays the step's (and ends on the step's state)."""
    forcing = {"on": 1.0}

    def fun(t: float, y: np.ndarray) -> np.ndarray:
        out = _pendulum(t, y)
        out[:, 1] += forcing["on"]
        return out

    stepper = Dop853(fun, 0.0, np.array([[1.0, 0.0]]), rtol=RTOL, atol=ATOL, t_bound=1.0)
    assert stepper.step(0.3)
    inside = np.linspace(stepper.t_old, stepper.t, 5)
    want, f_step = stepper.dense(inside), stepper.f.copy()
    forcing["on"] = -5.0  # the next interval's right-hand side
    stepper.refresh()
    assert not np.array_equal(stepper.f, f_step)
    np.testing.assert_array_equal(stepper.dense(inside), want)
    np.testing.assert_allclose(stepper.dense(np.array([stepper.t]))[0], stepper.y, rtol=1e-14)
