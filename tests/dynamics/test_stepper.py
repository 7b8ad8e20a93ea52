"""What the steppers share (youbot_opt.dynamics.stepper), against SciPy and by hand."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate._ivp import common as scipy_common
from scipy.integrate._ivp import rk as scipy_rk

from youbot_opt.dynamics.dop853 import Dop853
from youbot_opt.dynamics.radau5 import Radau5
from youbot_opt.dynamics.stepper import (
    MAX_FACTOR,
    MIN_FACTOR,
    SAFETY,
    Stepper,
    TrialStep,
    initial_step,
    min_step,
    next_step_size,
    trial_step,
)


def _pendulum(t: float, y: np.ndarray) -> np.ndarray:
    """A damped pendulum on a stack of rows (theta, omega)."""
    return np.stack([y[..., 1], -9.81 * np.sin(y[..., 0]) - 0.3 * y[..., 1]], axis=-1)


def test_controller_constants_are_scipys():
    """The step-size bounds and safety factor are SciPy's (``rk.py``)."""
    assert (SAFETY, MIN_FACTOR, MAX_FACTOR) == (
        scipy_rk.SAFETY,
        scipy_rk.MIN_FACTOR,
        scipy_rk.MAX_FACTOR,
    )


@pytest.mark.parametrize("order", [7, 3])
@pytest.mark.parametrize("y0", [[1.0, 0.0], [0.2, -3.0], [0.0, 0.0]])
def test_initial_step_is_scipys_on_one_row(order: int, y0: list[float]) -> None:
    """One row: SciPy's ``select_initial_step`` (to rounding: the norms are summed apart)."""
    y = np.array([y0])
    f0 = _pendulum(0.0, y)
    ours = initial_step(_pendulum, 0.0, y, f0, 2.0, 1e-8, 1e-10, order=order)
    theirs = scipy_common.select_initial_step(
        lambda t, x: _pendulum(t, x[None])[0],
        0.0,
        y[0],
        2.0,
        np.inf,
        f0[0],
        1.0,
        order,
        1e-8,
        1e-10,
    )
    assert ours == pytest.approx(theirs, rel=1e-14)


def test_initial_step_takes_the_smallest_row():
    """Several rows: the smallest of the rows' own first steps (each checked alone)."""
    rows = np.array([[1.0, 0.0], [0.2, -3.0], [2.5, 4.0]])
    f0 = _pendulum(0.0, rows)
    alone = [
        initial_step(_pendulum, 0.0, r[None], f[None], 2.0, 1e-8, 1e-10)
        for r, f in zip(rows, f0, strict=True)
    ]
    assert initial_step(_pendulum, 0.0, rows, f0, 2.0, 1e-8, 1e-10) == min(alone)


def test_initial_step_edge_cases():
    """No length: 0; a non-finite derivative: NaN; never beyond the interval."""
    y = np.array([[1.0, 0.0]])
    f0 = _pendulum(0.0, y)
    assert initial_step(_pendulum, 1.0, y, f0, 1.0, 1e-8, 1e-10) == 0.0
    assert np.isnan(initial_step(_pendulum, 0.0, y, f0 * np.nan, 1.0, 1e-8, 1e-10))
    assert initial_step(_pendulum, 0.0, y, f0, 1e-9, 1e-3, 1e-3) <= 1e-9


@pytest.mark.parametrize("t", [0.0, 1e-300, 0.5, 1.0, 3.0, 1e6])
def test_min_step_is_ten_spacings(t: float) -> None:
    """Ten spacings of floating-point numbers at ``t`` (NumPy's ``spacing``), in float."""
    assert min_step(t) == 10.0 * float(np.spacing(t))
    assert isinstance(min_step(t), float)


def test_trial_step_cuts_on_the_bound():
    """A step ending before ``t_bound`` is kept; one reaching or passing it ends on it."""
    assert trial_step(1.0, 0.25, 2.0) == TrialStep(t_new=1.25, h=0.25, cut=False)
    assert trial_step(1.0, 1.5, 2.0) == TrialStep(t_new=2.0, h=1.0, cut=True)
    assert trial_step(1.0, 1.0, 2.0) == TrialStep(t_new=2.0, h=1.0, cut=True)
    near = trial_step(0.1, 0.2, 0.3)  # 0.1 + 0.2 > 0.3 in floating point: cut, h = 0.3 - 0.1
    assert near.cut and near.t_new == 0.3 and near.h == 0.3 - 0.1


@pytest.mark.parametrize(
    ("factor", "cut", "rejected", "expected"),
    [
        (2.0, False, False, 0.2),  # no cut: the controller's
        (2.0, True, False, 0.5),  # cut, accepted at once, growing: the size wanted
        (1.0, True, False, 0.5),  # cut, kept: the size wanted
        (0.5, True, False, 0.05),  # cut but shrinking: the controller's
        (2.0, True, True, 0.2),  # cut after a rejection: the controller's
        (8.0, True, False, 0.8),  # the controller's is longer than the size wanted
    ],
)
def test_next_step_size(factor: float, cut: bool, rejected: bool, expected: float) -> None:
    """After a step of 0.1 that was wanted 0.5 long, by hand."""
    got = next_step_size(0.1, factor, wanted=0.5, cut=cut, rejected=rejected)
    assert got == pytest.approx(expected, rel=1e-15)


@pytest.mark.parametrize("method", [Dop853, Radau5])
def test_steppers_share_the_state(method: type[Stepper]) -> None:
    """Both methods start as a Stepper: f, the counted evaluations, the first step."""
    y = np.array([[1.0, 0.0], [0.2, -3.0]])
    args = (_pendulum, lambda t, x: np.zeros((2, 2, 2))) if method is Radau5 else (_pendulum,)
    stepper = method(*args, 0.0, y, rtol=1e-8, atol=1e-10, t_bound=2.0)
    assert isinstance(stepper, Stepper)
    np.testing.assert_array_equal(stepper.f, _pendulum(0.0, y))
    assert stepper.nfev == 2  # f0 and the first step's second evaluation
    f0 = _pendulum(0.0, y)
    first = initial_step(_pendulum, 0.0, y, f0, 2.0, 1e-8, 1e-10, order=method.error_order)
    assert stepper.h_abs == first
    assert (stepper.t, stepper.t_old, stepper.message) == (0.0, 0.0, "")
