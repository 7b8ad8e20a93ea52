"""Trajectory interpolants: exact on the polynomials each transcription assumes."""

from __future__ import annotations

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt.trajectory import Trajectory


def _constant_acceleration(n: int, acc: float = 1.7) -> Trajectory:
    t = np.linspace(0.0, 2.0, n)
    q = 0.3 + 0.2 * t + 0.5 * acc * t**2
    v = 0.2 + acc * t
    return Trajectory(t=t, q=q[:, None], v=v[:, None], a=np.full((n, 1), acc), tau=np.c_[t])


def test_trapezoidal_interpolant_exact_for_constant_acceleration() -> None:
    """Quadratic q / linear v / linear tau reproduce a constant-acceleration motion (1e-13)."""
    traj = _constant_acceleration(6)
    ts = np.linspace(0.0, 2.0, 101)
    np.testing.assert_allclose(traj(ts)[:, 0], 0.3 + 0.2 * ts + 0.85 * ts**2, atol=1e-13)
    np.testing.assert_allclose(traj.velocity(ts)[:, 0], 0.2 + 1.7 * ts, atol=1e-13)
    np.testing.assert_allclose(traj.torque(ts)[:, 0], ts, atol=1e-13)


def test_hermite_simpson_interpolant_exact_for_cubic_and_quadratic_torque() -> None:
    """Cubic Hermite q and quadratic tau are exact for cubic q and quadratic tau (1e-12)."""
    t = np.linspace(0.0, 1.0, 4)
    tm = 0.5 * (t[:-1] + t[1:])
    q, v, a = t**3 - t, 3 * t**2 - 1, 6 * t
    traj = Trajectory(
        t=t,
        q=q[:, None],
        v=v[:, None],
        a=a[:, None],
        tau=(t**2)[:, None],
        tau_mid=(tm**2)[:, None],
        interpolation="hermite_simpson",
    )
    ts = np.linspace(0.0, 1.0, 77)
    np.testing.assert_allclose(traj(ts)[:, 0], ts**3 - ts, atol=1e-12)
    np.testing.assert_allclose(traj.torque(ts)[:, 0], ts**2, atol=1e-12)
    # velocity is a cubic Hermite of (v, a): exact for a quadratic v.
    np.testing.assert_allclose(traj.velocity(ts)[:, 0], 3 * ts**2 - 1, atol=1e-12)


def test_scalar_query_and_clamping() -> None:
    """A scalar time returns shape (nq,); times beyond the ends clamp to the end knots."""
    traj = _constant_acceleration(5)
    assert traj(0.5).shape == (1,)
    np.testing.assert_allclose(traj(10.0), traj.q[-1], rtol=1e-15, atol=1e-15)
    assert traj.duration == pytest.approx(2.0)
    assert traj.n_knots == 5


def test_trapezoidal_interpolant_passes_through_inconsistent_knots() -> None:
    """Knots that violate the position defect are still interpolated (1e-15)."""
    t = np.array([0.0, 1.0, 2.0])
    traj = Trajectory(
        t=t, q=np.c_[[0.0, 5.0, -1.0]], v=np.zeros((3, 1)), a=np.zeros((3, 1)), tau=np.zeros((3, 1))
    )
    np.testing.assert_allclose(traj(t)[:, 0], [0.0, 5.0, -1.0], atol=1e-15)


def test_arrays_are_read_only() -> None:
    """Knot arrays cannot be modified in place."""
    traj = _constant_acceleration(5)
    with pytest.raises(ValueError):
        traj.q[0, 0] = 1.0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"t": [0.0, 0.0, 1.0]}, "strictly increasing"),
        ({"q": np.zeros((2, 1))}, "q must have shape"),
        ({"tau": np.full((3, 1), np.nan)}, "non-finite"),
        ({"interpolation": "euler"}, "interpolation must be one of"),
        ({"interpolation": "hermite_simpson"}, "need tau_mid"),
    ],
)
def test_bad_input_names_the_field(kwargs: dict, match: str) -> None:
    """Malformed trajectories raise ParameterError naming the field."""
    base = dict(
        t=[0.0, 0.5, 1.0],
        q=np.zeros((3, 1)),
        v=np.zeros((3, 1)),
        a=np.zeros((3, 1)),
        tau=np.zeros((3, 1)),
    )
    base.update(kwargs)
    with pytest.raises(ParameterError, match=match):
        Trajectory(**base)
