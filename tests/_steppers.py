"""Test-only stepping of the adaptive integrators (:mod:`youbot_opt.dynamics.stepper`).

The tests of ``Dop853`` and ``Radau5`` drive a stepper to its end the same way:
one accepted step after another, each asserted, recording the step times.
"""

from __future__ import annotations

from youbot_opt.dynamics.stepper import Stepper


def step_to_end(stepper: Stepper, t_end: float) -> list[float]:
    """Step ``stepper`` until ``t_end`` [s], asserting every step; return the step times [s]."""
    times = [stepper.t]
    while stepper.t < t_end:
        assert stepper.step(t_end), stepper.message
        times.append(stepper.t)
    return times
