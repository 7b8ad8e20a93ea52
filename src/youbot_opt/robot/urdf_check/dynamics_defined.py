"""The loaded model's dynamics are defined: checked on the numbers Pinocchio computes (issue 16).

:func:`check_dynamics_defined` runs the algorithms users call -- RNEA, CRBA, ABA
and ``M(q)^-1`` -- at the neutral configuration and at :data:`N_SAMPLES` seeded
random states, and requires every result finite and ``M(q)`` well conditioned.
Called by :func:`youbot_opt.robot.urdf_check.loader.check_model`; why the rules on
the file's text do not suffice is in docs/design.md, "Module notes".

Example: ``check_dynamics_defined(model, "arm.urdf")`` returns None or raises.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from youbot_opt.exceptions import InvalidModelError
from youbot_opt.robot.urdf_check.xml import Site, fail

__all__ = ["MAX_CONDITION", "N_SAMPLES", "check_dynamics_defined"]

#: Random states checked besides the neutral configuration at rest.
N_SAMPLES: int = 4
#: Largest accepted condition number of M(q) (the loader's singularity bound,
#: 1e-12 relative, seen from the other side): beyond it ``M^-1 tau`` loses
#: every digit to round-off (~1e-16 relative per operation).
MAX_CONDITION: float = 1e12
_RULE = "RNEA, CRBA, ABA and M(q)^-1 are finite and M(q) is well conditioned (dynamics defined)"


def _states(
    model: pin.Model, samples: int, seed: int
) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    neutral, zero = pin.neutral(model), np.zeros(model.nv)
    states = [("the neutral configuration at rest", neutral, zero, zero)]
    for k in range(1, samples + 1):
        q = pin.integrate(model, neutral, rng.uniform(-np.pi, np.pi, model.nv))
        v, a = rng.uniform(-1.0, 1.0, model.nv), rng.uniform(-1.0, 1.0, model.nv)
        states.append((f"random state {k} (seed {seed})", q, v, a))
    return states


def check_dynamics_defined(
    model: pin.Model, path: str, *, samples: int = N_SAMPLES, seed: int = 0
) -> None:
    """Require finite RNEA, CRBA, ABA and ``M^-1`` and a well-conditioned ``M(q)``.

    The algorithms (RNEA, CRBA, ABA and ``pin.computeMinverse``) run at the
    neutral configuration and at ``samples`` seeded random states
    ``(q, v, a)``; every result must be finite and ``M(q)`` well conditioned
    with eigenvalues in the normal floating-point range.

    Parameters
    ----------
    model : pinocchio.Model
        The loaded model.
    path : str
        Its file, for error messages.
    samples : int
        Random states ``(q, v, a)`` besides the neutral configuration at rest;
        velocities in [rad/s] or [m/s] and accelerations in [rad/s^2] or
        [m/s^2] uniform in [-1, 1], configurations uniform in [-pi, pi] from neutral.
    seed : int
        Seed of the random states (the check is reproducible).

    Raises
    ------
    InvalidModelError
        Naming the algorithm, the state and the values (e.g. ABA returning
        NaN for a subnormal mass), or the condition number of ``M(q)``.
    """
    if model.nv == 0:
        return
    data = model.createData()
    where = Site(path, "<robot>", None)
    # ABA and M^-1 do not support JointModelMimic (a model built with mimic=True);
    # there the mimicked coordinates enter M(q) through CRBA, which is checked.
    recursive = not any("Mimic" in joint.shortname() for joint in model.joints)
    for state, q, v, a in _states(model, samples, seed):
        with np.errstate(all="ignore"):
            tau = np.array(pin.rnea(model, data, q, v, a))
            upper = np.array(pin.crba(model, data, q))
            mass_matrix = np.triu(upper) + np.triu(upper, 1).T
            checked = [("RNEA (joint torques)", tau), ("CRBA (M(q))", mass_matrix)]
            if recursive:
                checked += [
                    ("ABA (joint accelerations)", np.array(pin.aba(model, data, q, v, tau))),
                    ("M(q)^-1", np.array(pin.computeMinverse(model, data, q))),
                ]
        for name, value in checked:
            if not np.all(np.isfinite(value)):
                bad = int(np.sum(~np.isfinite(value)))
                problem = (
                    f"{name} is not finite at {state}: {bad} of {value.size} entries are "
                    f"NaN or infinite (masses and inertias too small or too large for "
                    f"floating point, e.g. subnormal values below 2.2e-308)"
                )
                raise fail(InvalidModelError, where, problem, _RULE)
        eigenvalues = np.linalg.eigvalsh(mass_matrix)
        tiny = np.finfo(float).tiny
        if eigenvalues[0] < tiny or eigenvalues[-1] > MAX_CONDITION * eigenvalues[0]:
            problem = (
                f"M(q) at {state} has eigenvalues from {eigenvalues[0]:.3g} to "
                f"{eigenvalues[-1]:.3g} (condition number above {MAX_CONDITION:.0e}, or "
                f"values below the smallest normal number {tiny:.3g})"
            )
            raise fail(InvalidModelError, where, problem, _RULE)
