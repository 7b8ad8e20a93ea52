"""Stiff joint damping: the damping rate, the implicit integrator of certify, refine's reason."""

from __future__ import annotations

import math
import sys

import numpy as np
import pinocchio as pin
import pytest
from test_certify import exact_trajectory

from youbot_opt.dynamics.numeric import STIFF_RATIO, damping_rate
from youbot_opt.dynamics.radau5 import Radau5
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.robot.load import load_model
from youbot_opt.sweeps.forked import can_fork
from youbot_opt.trajopt import simulate as simulate_module
from youbot_opt.trajopt.certify import TRACKING_ATOL, TRACKING_RTOL, certify
from youbot_opt.trajopt.mesh import predicted_knots
from youbot_opt.trajopt.refine import RefinementBudget, refine
from youbot_opt.trajopt.simulate import integrate_intervals, integration_method, simulate_batch
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.trajectory import Trajectory

MASS = 0.17  # [kg] xarm7's last link
OFFSET = 0.02  # [m] its centre of mass from the axis
I_COM = 1.3e-4  # [kg m^2] about the axis through the centre of mass


def _hinge(damping: float, armature: float = 0.0) -> pin.Model:
    """One horizontal revolute joint (no gravity torque about z) carrying one body."""
    model = pin.Model()
    model.name = "hinge"
    joint = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "hinge_joint")
    inertia = pin.Inertia(MASS, np.array([OFFSET, 0.0, 0.0]), np.diag([1e-4, 1e-4, I_COM]))
    model.appendBodyToJoint(joint, inertia, pin.SE3.Identity())
    model.addFrame(pin.Frame("tip", joint, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
    model.lowerPositionLimit[:] = -3.0
    model.upperPositionLimit[:] = 3.0
    model.velocityLimit[:] = 5.0
    model.effortLimit[:] = 10.0
    model.damping[:] = damping
    model.armature[:] = armature
    return model


def test_damping_rate_of_one_joint_is_damping_over_inertia() -> None:
    """rate = b / (I_com + m r^2 + armature), by hand (parallel-axis theorem), to 1e-12."""
    axis_inertia = I_COM + MASS * OFFSET**2  # [kg m^2]
    for b, armature in ((2.0, 0.0), (2.0, 0.01), (0.5, 0.0)):
        rate = damping_rate(_hinge(b, armature), np.zeros((3, 1)))
        np.testing.assert_allclose(rate.rate, b / (axis_inertia + armature), rtol=1e-12)
        assert rate.joint == "hinge_joint"
    assert damping_rate(_hinge(2.0), np.zeros(1), damping=False).rate == 0.0


def _coasting_plan(model: pin.Model, h: float, n: int) -> Trajectory:
    """Knots of the damped hinge coasting from 1 rad/s under zero torque (v = exp(-rate t))."""
    rate = damping_rate(model, np.zeros(1)).rate
    t = np.linspace(0.0, h * (n - 1), n)
    v = np.exp(-rate * t)[:, None]
    q = ((1.0 - np.exp(-rate * t)) / rate)[:, None]
    return Trajectory(t=t, q=q, v=v, tau=np.zeros((n, 1)), a=-rate * v)


def test_stiff_damping_is_integrated_implicitly_and_agrees_with_the_explicit_method() -> None:
    """rate * h = 2.2e3 picks Radau; its one-interval ends match DOP853's and the exact decay.

    Under zero torque the hinge's velocity decays as exp(-rate t) from every knot,
    so the exact end state of an interval from knot k is known in closed form.
    """
    model = _hinge(2.0)
    rate = damping_rate(model, np.zeros(1)).rate  # [1/s] about 1.04e4
    plan = _coasting_plan(model, h=0.2, n=4)
    assert rate * 0.2 > STIFF_RATIO
    assert integration_method("auto", plan, model) == "Radau"
    q_auto, v_auto = integrate_intervals(plan, model, rtol=1e-10, atol=1e-12)
    q_exp, v_exp = integrate_intervals(plan, model, method="DOP853", rtol=1e-10, atol=1e-12)
    decay = np.exp(-rate * 0.2)
    q_exact = plan.q[:-1] + plan.v[:-1] * (1.0 - decay) / rate
    v_exact = plan.v[:-1] * decay
    np.testing.assert_allclose(q_auto, q_exact, rtol=0, atol=1e-10)  # [rad]; atol 1e-12 per step
    np.testing.assert_allclose(v_auto, v_exact, rtol=0, atol=1e-10)  # [rad/s]
    np.testing.assert_allclose(q_auto, q_exp, rtol=0, atol=1e-10)
    mild = _coasting_plan(_hinge(0.002), h=0.2, n=4)  # rate * h = 2.2: explicit
    assert integration_method("auto", mild, _hinge(0.002)) == "DOP853"


def test_predicted_knots_count_pieces_at_each_exponent() -> None:
    """By hand: errors 7e-3, 1e-4, 2.65e-2, tolerance 1e-3, exponents 3, 3, 1: 2 + 1 + 27 pieces."""
    errors = np.array([7e-3, 1e-4, 2.65e-2])  # 7^(1/3) = 1.91, 26.5: no ceiling at an integer
    assert predicted_knots(errors, 1e-3, np.array([3.0, 3.0, 1.0])) == 2 + 1 + 27 + 1


def test_refinement_of_a_stiff_arm_says_why_with_numbers() -> None:
    """youBot with 5 N m s/rad damping on 8 knots: the reason names the stiff joint and its rate."""
    problem = study1_problem(8, damping=5.0)
    result, refinement = refine(TrajOptSolver(problem), budget=RefinementBudget(max_rounds=1))
    assert not refinement.certified
    reason = refinement.reason
    rate = damping_rate(problem.robot, result.trajectory.q).rate  # type: ignore[union-attr]
    assert rate > 1e3  # [1/s]: stiff on a 0.3 s grid
    assert f"stiff joint damping: arm_joint_3 relaxes at up to {rate:.3g} 1/s" in reason
    assert "knots would be needed" in reason and "(budget: " in reason


STIFF_DAMPING = 1.0  # [N m s/rad] on every youBot joint: rate 1.46e3 1/s, rate * h = 292


@pytest.fixture(scope="module")
def stiff_youbot():
    """The planar youBot with stiff joint damping."""
    return load_model("youbot", damping=STIFF_DAMPING)


@pytest.fixture(scope="module")
def stiff_plan(stiff_youbot):
    """test_certify's dynamically exact youBot motion, 16 knots over 3 s, under that damping."""
    plan = exact_trajectory(stiff_youbot, 16)
    assert integration_method("auto", plan, stiff_youbot) == "Radau"
    return plan


def _central_differences(fun, t: float, y: np.ndarray) -> np.ndarray:
    """Full d fun / d y of the flattened state by central differences."""
    flat = y.reshape(-1)
    out = np.empty((flat.size, flat.size))
    for j in range(flat.size):
        step = 1e-6 * (1.0 + abs(flat[j]))
        up, down = flat.copy(), flat.copy()
        up[j] += step
        down[j] -= step
        diff = fun(t, up.reshape(y.shape)) - fun(t, down.reshape(y.shape))
        out[:, j] = diff.reshape(-1) / (2.0 * step)
    return out


def test_the_analytic_jacobians_are_the_finite_differences(
    stiff_youbot, stiff_plan, monkeypatch
) -> None:
    """Every Jacobian the simulations hand to Radau5 is d f / d y by central differences.

    Checked where the integrator asks for it (its first five calls in the
    stacked interval ODE, and in the stacked tracking and open-loop simulation),
    over the whole flattened state, so the blocks off the diagonal are zero too.
    Central differences with steps 1e-6 (1 + |y|) are accurate to about
    1e-12 |f'''| + 1e-16 |f| / 1e-6, far below 1e-6 of the largest entry
    (3e2 for the intervals, whose time is scaled by h; 1.5e3 for the simulations).
    Measured: 3e-10 to 1e-9 of it; the bound is 1e-6.
    """
    checked: list[float] = []

    class Checked(Radau5):
        def __init__(self, fun, jac, *args, **kwargs) -> None:
            def checking(t: float, y: np.ndarray) -> np.ndarray:
                blocks = jac(t, y)
                if len(checked) < 5:
                    nb = blocks.shape[1]
                    full = np.zeros((y.size, y.size))
                    for b, block in enumerate(blocks):
                        full[b * nb : (b + 1) * nb, b * nb : (b + 1) * nb] = block
                    fd = _central_differences(fun, t, y)
                    checked.append(float(np.max(np.abs(full - fd)) / np.max(np.abs(fd))))
                return blocks

            super().__init__(fun, checking, *args, **kwargs)

    monkeypatch.setattr(simulate_module, "Radau5", Checked)
    integrate_intervals(stiff_plan, stiff_youbot)
    intervals = checked.copy()
    checked.clear()
    simulate_batch(
        stiff_plan, stiff_youbot, gains=(simulate_module.PDGains(), None),
        stop_deviation=(None, 0.1), rtol=TRACKING_RTOL, atol=TRACKING_ATOL,
    )  # fmt: skip
    assert intervals and checked
    assert max(intervals + checked) < 1e-6, (intervals, checked)


def test_a_stiff_certificate_is_scipys_radaus_without_scipy(
    stiff_youbot, stiff_plan, monkeypatch
) -> None:
    """certify() of a stiff plan runs without scipy.integrate; its figures are SciPy Radau's.

    (Before Radau5 the stiff path imported ``scipy.integrate``: this failed.)
    Both integrators hold each step to the tolerances, so each simulated state
    is within about 10 (atol + rtol |x|) of the exact one (|x| < 3 here):
    3e-9 for the one-interval integrations (rtol 1e-10), 3e-7 for the tracking
    and open-loop simulations (rtol 1e-8). The figures are differences of such
    states from the plan, so ours and SciPy's agree within twice that: 1e-8 and
    1e-6 absolute. The feedback ratios are the PD law times the tracking error
    (1.1e-2 rad here), so they agree within 1e-6 / 1.1e-2 = 1e-4 relative
    (bound 1e-3). Measured: 6e-14, 7e-11 and 4e-10 (ratios 4e-10 relative).
    """
    with monkeypatch.context() as patch:
        patch.setitem(sys.modules, "scipy.integrate", None)  # importing it raises
        ours = certify(stiff_plan, robot=stiff_youbot)
    monkeypatch.setattr(simulate_module, "_OWN_METHODS", ("DOP853",))  # "Radau": SciPy's
    scipys = certify(stiff_plan, robot=stiff_youbot)
    assert ours.ok == scipys.ok and ours.incomplete == scipys.incomplete == ""
    for name in ("local_position_error", "local_velocity_error"):
        np.testing.assert_allclose(getattr(ours, name), getattr(scipys, name), rtol=0, atol=1e-8)
    for name in ("tracking_position_error", "tracking_velocity_error", "open_loop_final_error"):
        assert getattr(ours, name) == pytest.approx(getattr(scipys, name), rel=0, abs=1e-6), name
    for name in ("feedback_rms_ratio", "feedback_peak_ratio"):
        np.testing.assert_allclose(getattr(ours, name), getattr(scipys, name), rtol=1e-3, atol=0)
    assert math.isinf(ours.open_loop_divergence_time)
    assert math.isinf(scipys.open_loop_divergence_time)


@pytest.mark.skipif(not can_fork(), reason="the forked integrations need fork (Linux)")
def test_a_stiff_certificate_in_two_processes_is_the_same(stiff_youbot, stiff_plan) -> None:
    """Radau5's one-interval integrations in a forked process: the same figures, bit for bit."""
    one = certify(stiff_plan, robot=stiff_youbot)
    two = certify(stiff_plan, robot=stiff_youbot, processes=2)
    for name in ("local_position_error", "local_velocity_error", "feedback_rms_ratio",
                 "feedback_peak_ratio"):  # fmt: skip
        np.testing.assert_array_equal(getattr(one, name), getattr(two, name))
    assert one.tracking_position_error == two.tracking_position_error
    assert one.ok == two.ok and two.incomplete == ""
