"""Shared fixtures of the trajectory tests."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

SLIDER_MASS = 2.0  # [kg]


@pytest.fixture(scope="module")
def slider() -> pin.Model:
    """A double integrator: one prismatic joint along x of 2 kg (``a = tau / m``), limits 10."""
    model = pin.Model()
    joint = model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
    inertia = pin.Inertia(SLIDER_MASS, np.zeros(3), np.eye(3))
    model.appendBodyToJoint(joint, inertia, pin.SE3.Identity())
    for limit in ("upperPositionLimit", "velocityLimit", "effortLimit"):
        getattr(model, limit)[:] = 10.0
    model.lowerPositionLimit[:] = -10.0
    return model
