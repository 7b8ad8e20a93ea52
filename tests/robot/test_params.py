"""Tests of youbot_opt.robot.params: the study's tables, SI conversions and validation."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.params import (
    STUDY_Q_GOAL,
    STUDY_Q_START,
    YOUBOT_PLANAR,
    ArmParameters,
    JointLimits,
    LinkParameters,
    PlatformMounting,
)

# Spec trajopt.md, "The arm" and "Joint limits" tables, transcribed independently here.
SPEC_LENGTH = [0.155, 0.135, 0.2175]
SPEC_COM = [0.0775, 0.0675, 0.10875]
SPEC_MASS = [1.318, 0.821, 0.769]
SPEC_INERTIA = [0.0031145, 0.00172767, 0.0006764]
SPEC_LOWER_DEG = [-65.0, -151.0, -102.5]
SPEC_UPPER_DEG = [90.0, 146.0, 102.5]
SPEC_SPEED_DEG_S = [90.0, 90.0, 90.0]
SPEC_TORQUE = [9.5, 6.0, 2.0]


def test_tables_match_spec() -> None:
    """YOUBOT_PLANAR holds exactly the spec's link, limit and mounting values."""
    p = YOUBOT_PLANAR
    # Exact equality: both sides are the same decimal literals.
    assert list(p.lengths) == SPEC_LENGTH
    assert list(p.com_distances) == SPEC_COM
    assert list(p.masses) == SPEC_MASS
    assert list(p.inertias) == SPEC_INERTIA
    assert [x.lower_deg for x in p.limits] == SPEC_LOWER_DEG
    assert [x.upper_deg for x in p.limits] == SPEC_UPPER_DEG
    assert [x.speed_deg_s for x in p.limits] == SPEC_SPEED_DEG_S
    assert [x.torque_nm for x in p.limits] == SPEC_TORQUE
    assert p.mounting.a == pytest.approx(0.184, abs=1e-15)  # 0.151 + 0.033 in binary
    assert p.mounting.h == 0.147
    assert p.gravity == 9.81
    assert p.damping == 0.0


def test_si_conversions() -> None:
    """The SI properties equal deg * pi / 180 (1e-15, one rounding of a product)."""
    p = YOUBOT_PLANAR
    deg = np.pi / 180.0
    np.testing.assert_allclose(p.q_lower, np.array(SPEC_LOWER_DEG) * deg, rtol=1e-15)
    np.testing.assert_allclose(p.q_upper, np.array(SPEC_UPPER_DEG) * deg, rtol=1e-15)
    np.testing.assert_allclose(p.velocity_limit, np.array(SPEC_SPEED_DEG_S) * deg, rtol=1e-15)
    np.testing.assert_array_equal(p.effort_limit, SPEC_TORQUE)


def test_study_boundary_configurations() -> None:
    """The study's start and goal are (-pi/6, -pi/6, -pi/3) and its mirror, inside the limits."""
    np.testing.assert_array_equal(STUDY_Q_START, [-math.pi / 6, -math.pi / 6, -math.pi / 3])
    np.testing.assert_array_equal(STUDY_Q_GOAL, -np.asarray(STUDY_Q_START))
    for q in (STUDY_Q_START, STUDY_Q_GOAL):
        assert np.all(YOUBOT_PLANAR.q_lower < q) and np.all(q < YOUBOT_PLANAR.q_upper)


def test_scaled_limits() -> None:
    """scaled(0.85) multiplies every bound by 0.85 and leaves the links alone."""
    s = 0.85
    scaled = YOUBOT_PLANAR.scaled(s)
    # 1e-15 relative: one floating-point multiplication on each side.
    np.testing.assert_allclose(scaled.q_lower, s * YOUBOT_PLANAR.q_lower, rtol=1e-15)
    np.testing.assert_allclose(scaled.q_upper, s * YOUBOT_PLANAR.q_upper, rtol=1e-15)
    np.testing.assert_allclose(scaled.velocity_limit, s * YOUBOT_PLANAR.velocity_limit, rtol=1e-15)
    np.testing.assert_allclose(scaled.effort_limit, s * YOUBOT_PLANAR.effort_limit, rtol=1e-15)
    assert scaled.links == YOUBOT_PLANAR.links
    speed_only = YOUBOT_PLANAR.scaled(s, position=False)
    np.testing.assert_array_equal(speed_only.q_lower, YOUBOT_PLANAR.q_lower)
    with pytest.raises(ParameterError, match="scale s must be in"):
        YOUBOT_PLANAR.limits[0].scaled(1.5)


def test_inertia_completion_is_physical() -> None:
    """Each 3-D inertia tensor is positive definite, obeys the triangle inequality, Iyy = I."""
    for link in YOUBOT_PLANAR.links:
        tensor = link.inertia_tensor
        eig = np.linalg.eigvalsh(tensor)
        assert eig.min() > 0
        assert eig[0] + eig[1] >= eig[2]
        assert tensor[1, 1] == link.inertia


def test_arrays_are_read_only() -> None:
    """Returned parameter arrays cannot be modified in place."""
    with pytest.raises(ValueError, match="read-only"):
        YOUBOT_PLANAR.masses[0] = 2.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        YOUBOT_PLANAR.gravity = 1.0  # type: ignore[misc]


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"mass": -1.0}, "mass"),
        ({"length": 0.0}, "length"),
        ({"inertia": float("nan")}, "inertia"),
        ({"com_distance": -0.1}, "com_distance"),
        ({"radius": 1.0}, "radius"),
    ],
)
def test_link_validation(kwargs: dict[str, float], field: str) -> None:
    """A bad link value raises ParameterError naming the field."""
    base = {"length": 0.1, "com_distance": 0.05, "mass": 1.0, "inertia": 1e-3}
    with pytest.raises(ParameterError, match=field) as info:
        LinkParameters(**{**base, **kwargs})
    assert info.value.name == field


def test_limit_and_arm_validation() -> None:
    """Inverted limits, non-positive speeds, wrong link counts and bad damping are refused."""
    with pytest.raises(ParameterError, match="upper_deg"):
        JointLimits(lower_deg=10.0, upper_deg=-10.0, speed_deg_s=90.0, torque_nm=1.0)
    with pytest.raises(ParameterError, match="speed_deg_s"):
        JointLimits(lower_deg=-10.0, upper_deg=10.0, speed_deg_s=0.0, torque_nm=1.0)
    with pytest.raises(ParameterError, match="links"):
        ArmParameters(links=YOUBOT_PLANAR.links[:2], limits=YOUBOT_PLANAR.limits)
    with pytest.raises(ParameterError, match="damping"):
        dataclasses.replace(YOUBOT_PLANAR, damping=-0.1)
    with pytest.raises(ParameterError, match="h must be finite"):
        PlatformMounting(a=0.1, h=float("inf"))
