"""Radau IIA collocation (trajopt.radau, trajopt.transcription.radau): the L-stable scheme.

References: the closed-form Butcher table of Hairer & Wanner (*Solving ODEs II*,
Table IV.5.6); the order conditions; closed forms of the collocation error on a
double integrator; the forward-simulation certificate (``certify``) on the
study-1 youBot with a stiff joint damping, where the A-stable Hermite-Simpson
plan cannot be followed and the Radau plan can (docs/refinement.md, "Stiff
joint damping").
"""

from __future__ import annotations

from math import comb
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.dynamics.numeric import damping_rate
from youbot_opt.exceptions import ParameterError
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.trajopt import quadrature
from youbot_opt.trajopt.certify import certify
from youbot_opt.trajopt.mesh import collocation_error, interval_errors
from youbot_opt.trajopt.refine import RefinementBudget, refine
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.trajectory import Trajectory

S6 = np.sqrt(6.0)
BUTCHER = np.array(  # Hairer & Wanner, Table IV.5.6 (Radau IIA, order 5)
    [
        [(88 - 7 * S6) / 360, (296 - 169 * S6) / 1800, (-2 + 3 * S6) / 225],
        [(296 + 169 * S6) / 1800, (88 + 7 * S6) / 360, (-2 - 3 * S6) / 225],
        [(16 - S6) / 36, (16 + S6) / 36, 1 / 9],
    ]
)
MASS = 2.0  # [kg] of the slider (tests/trajopt/conftest.py)
STIFF = 5.0  # [N m s/rad] youBot joint damping that makes the damping stiff on 20 knots


def test_butcher_table_and_order_conditions() -> None:
    """A is the published table (1e-15); b . c^(k-1) = 1/k to k = 5; A c^(k-1) = c^k / k to 3."""
    np.testing.assert_allclose(quadrature.RADAU_BUTCHER, BUTCHER, rtol=0, atol=1e-15)
    np.testing.assert_allclose(
        quadrature.RADAU_NODES, [(4 - S6) / 10, (4 + S6) / 10, 1.0], atol=1e-16
    )
    c, b = quadrature.RADAU_NODES, quadrature.RADAU_WEIGHTS
    for k in range(1, 6):  # quadrature order 2s - 1 = 5
        assert b @ c ** (k - 1) == pytest.approx(1.0 / k, abs=1e-15)
    for k in range(1, 4):  # stage order s = 3
        np.testing.assert_allclose(quadrature.RADAU_BUTCHER @ c ** (k - 1), c**k / k, atol=1e-15)
    assert b @ c**5 != pytest.approx(1.0 / 6, abs=1e-6)  # and not beyond: the check can fail


def test_l_stability() -> None:
    """R(z) = 1 + z b^T (I - z A)^-1 1 tends to 0; Hermite-Simpson's tends to 1.

    |R(z)| <= 1 on the left half-plane (A-stability, sampled) and
    |R(-1e6)| ~ 6 / 1e6 (R(z) ~ 6 / z: the stiff decay of one interval).
    """

    def r(z: complex) -> complex:
        stages = np.linalg.solve(np.eye(3) - z * quadrature.RADAU_BUTCHER, np.ones(3))
        return complex(1 + z * quadrature.RADAU_WEIGHTS @ stages)

    assert abs(r(-1e6)) < 1e-5
    hs = (1 - 1e6 / 2 + 1e12 / 12) / (1 + 1e6 / 2 + 1e12 / 12)  # HS: (1 + z/2 + z^2/12) / (...)
    assert hs > 0.99
    rng = np.random.default_rng(0)
    for z in -np.abs(rng.normal(size=50) * 100) + 1j * rng.normal(size=50) * 100:
        assert abs(r(z)) <= 1.0 + 1e-12


def test_bernstein_rows_recover_a_cubics_control_points() -> None:
    """A cubic built from Bernstein points b: its values at (0, c1, c2, 1) map back to b1, b2."""
    b = np.array([0.3, -1.2, 2.5, 0.7])
    s = np.concatenate(([0.0], quadrature.RADAU_NODES))
    values = [sum(b[i] * comb(3, i) * x**i * (1 - x) ** (3 - i) for i in range(4)) for x in s]
    np.testing.assert_allclose(quadrature.radau_bernstein_inner() @ values, b[1:3], atol=1e-14)
    np.testing.assert_allclose(quadrature.radau_bernstein_inner().sum(axis=1), 1.0, atol=1e-14)


def _radau_slider(rng: np.random.Generator, n: int) -> tuple:
    """Knots and stages solving the Radau equations exactly (a = tau / m) on random steps."""
    t = np.concatenate(([0.0], np.cumsum(rng.uniform(0.1, 0.5, n - 1))))
    h = np.diff(t)
    tau = rng.uniform(-3.0, 3.0, (n, 1))
    tau_st = rng.uniform(-3.0, 3.0, (n - 1, 2, 1))
    q, v = np.zeros((n, 1)), np.zeros((n, 1))
    q_st, v_st = np.zeros((n - 1, 2, 1)), np.zeros((n - 1, 2, 1))
    for k in range(n - 1):
        acc = np.concatenate([tau_st[k, :, 0], tau[k + 1]]) / MASS
        vel = v[k, 0] + h[k] * BUTCHER @ acc
        pos = q[k, 0] + h[k] * BUTCHER @ vel
        v_st[k, :, 0], v[k + 1] = vel[:2], vel[2]
        q_st[k, :, 0], q[k + 1] = pos[:2], pos[2]
    return t, q, v, tau, (q_st, v_st, tau_st)


def _abs_node_polynomial() -> float:
    """Exact integral over [0, 1] of |(s - c1)(s - c2)(s - 1)| (split at its roots)."""
    poly = np.polynomial.Polynomial.fromroots(quadrature.RADAU_NODES).integ()
    edges = np.concatenate(([0.0], quadrature.RADAU_NODES))
    return float(sum(abs(poly(b) - poly(a)) for a, b in zip(edges[:-1], edges[1:], strict=True)))


def test_radau_error_on_a_double_integrator(slider: pin.Model) -> None:
    """Radau on a double integrator: velocity error 0, position error h^2 |L| / 3 int |w|.

    The velocity is the cubic ``v_k + h sum_j I_j(s) a_j`` (exact: a is the
    torque's quadratic over m), and q' of the interpolant is the quadratic
    through the stage velocities; their difference is ``-(h L / 3) w(s)`` with
    ``w = (s - c1)(s - c2)(s - 1)`` and ``L`` the leading coefficient of the
    quadratic through the stage accelerations. Its modulus kinks at c1, c2,
    inside the estimator's pieces: with the estimator's own rule the integrand
    is reproduced to round-off (1e-12); with 256 pieces the rule is within
    1e-5 of the exact integral (a kink costs O(piece^2) per piece; measured
    2e-7 relative).
    """
    rng = np.random.default_rng(4)
    assert slider.inertias[1].mass == MASS
    t, q, v, tau, stages = _radau_slider(rng, 6)
    h = np.diff(t)
    acc = np.concatenate([stages[2][:, :, 0], tau[1:]], axis=1) / MASS  # (n - 1, 3)
    lead = np.array(
        [
            1.0 / np.prod([c - d for d in quadrature.RADAU_NODES if d != c])
            for c in quadrature.RADAU_NODES
        ]
    )
    scale = h**2 * np.abs(acc @ lead) / 3.0
    fine = interval_errors(
        "radau", t, q, v, tau, slider, stages=stages, damping=False, segments=256
    )
    np.testing.assert_allclose(fine.absolute[:, 0], scale * _abs_node_polynomial(), rtol=1e-5)
    np.testing.assert_allclose(fine.absolute[:, 1], 0.0, atol=1e-13)
    err = interval_errors("radau", t, q, v, tau, slider, stages=stages, damping=False)
    x, w = np.polynomial.legendre.leggauss(5)
    nodes = np.concatenate([(j + 0.5 * (x + 1.0)) / 4 for j in range(4)])
    weights = np.concatenate([0.5 * w / 4] * 4)
    rule = float(weights @ np.abs(np.polynomial.polynomial.polyval(
        nodes, np.polynomial.polynomial.polyfromroots(quadrature.RADAU_NODES))))  # fmt: skip
    np.testing.assert_allclose(err.absolute[:, 0], scale * rule, rtol=1e-12)
    with pytest.raises(ParameterError, match="stage values"):
        interval_errors("radau", t, q, v, tau, slider, damping=False)


def test_trajectory_interpolates_knots_and_stages() -> None:
    """The Radau trajectory passes through knots and stages; its torque jumps at knots.

    On the exact slider solution: q and v at the stage times equal the stage
    values (1e-12), the velocity is the derivative of the position (central
    differences, 1e-6) at the nodes but not between them, ``torque`` at a
    knot is the next interval's start while ``interval_values(1)`` is
    ``tau[k + 1]``.
    """
    t, q, v, tau, (q_st, v_st, tau_st) = _radau_slider(np.random.default_rng(5), 5)
    a = tau / MASS
    traj = Trajectory(
        t=t, q=q, v=v, a=a, tau=tau, interpolation="radau",
        v_stages=v_st, a_stages=tau_st / MASS, tau_stages=tau_st,
    )  # fmt: skip
    h = np.diff(t)
    for i, c in enumerate(quadrature.RADAU_NODES[:2]):
        ts = t[:-1] + c * h
        np.testing.assert_allclose(traj(ts), q_st[:, i], atol=1e-12)
        np.testing.assert_allclose(traj.velocity(ts), v_st[:, i], atol=1e-12)
        np.testing.assert_allclose(traj.torque(ts), tau_st[:, i], atol=1e-12)
    np.testing.assert_allclose(traj(t), q, atol=1e-12)
    np.testing.assert_allclose(traj.velocity(t), v, atol=1e-12)
    ends = traj.interval_values(np.array([0.0, 1.0]))
    np.testing.assert_allclose(ends[:, 1, 2], tau[1:, 0], atol=1e-12)  # left limits
    nodes_tau = np.concatenate([tau_st[:, :, 0], tau[1:]], axis=1)
    extrapolated = nodes_tau @ quadrature.RADAU_AT_ZERO
    np.testing.assert_allclose(traj.torque(t[1:-1])[:, 0], extrapolated[1:], atol=1e-12)
    ts = (
        t[:-1] + quadrature.RADAU_NODES[0] * h
    )  # collocation: q' of the interpolant is v at the nodes
    dq = (traj(ts + 1e-6) - traj(ts - 1e-6)) / 2e-6
    np.testing.assert_allclose(dq, traj.velocity(ts), atol=1e-6)
    mid = 0.5 * (t[:-1] + t[1:])  # ... and only there (the collocation residual)
    assert np.max(np.abs((traj(mid + 1e-6) - traj(mid - 1e-6)) / 2e-6 - traj.velocity(mid))) > 1e-3
    with pytest.raises(ParameterError, match="need v_stages"):
        Trajectory(t=t, q=q, v=v, a=a, tau=tau, interpolation="radau")
    with pytest.raises(ParameterError, match="only used by radau"):
        Trajectory(t=t, q=q, v=v, a=a, tau=tau, v_stages=v_st)


@pytest.fixture(scope="module")
def stiff_plans() -> dict:
    """The study-1 motion with 5 N m s/rad joint damping on 20 knots, both schemes."""
    problem = study1_problem(20, damping=STIFF)
    return {m: TrajOptSolver(problem, m).solve(beta=0.5) for m in ("hermite_simpson", "radau")}


def test_stiff_damping_radau_plan_can_be_followed(stiff_plans: dict) -> None:
    """rate * h ~ 3e3: the Hermite-Simpson plan fails its certificate, the Radau plan passes.

    Measured: Hermite-Simpson's collocation error 18.8 and feedback peak 12 %
    (> 10 %); Radau's 0.12 and 7 %, certified. The bounds below leave a
    factor of about 2 to either side of the measured values.
    """
    hs, rd = stiff_plans["hermite_simpson"], stiff_plans["radau"]
    assert hs.success and rd.success, (hs.message, rd.message)
    rate = damping_rate(rd.problem.robot, rd.trajectory.q).rate  # [1/s]
    assert rate * rd.duration / 19 > 1e3  # the damping is stiff on this grid
    assert not certify(hs).passed()
    cert = certify(rd)
    assert cert.passed(), cert
    assert collocation_error(hs).max > 5.0 > 0.3 > collocation_error(rd).max
    assert rd.objective < hs.objective  # the same family: 33.54 against 33.96


def test_stiff_damping_radau_refines_to_a_certified_plan(stiff_plans: dict) -> None:
    """From 20 knots to tolerance 1e-3: certified within 100 knots (measured 59).

    Hermite-Simpson needs 812 knots from the same start (measured, not run
    here: about 15 s). Both reach f = 33.2369; the Radau plan is re-certified
    here by ``certify``.
    """
    problem = study1_problem(20, damping=STIFF)
    result, refinement = refine(
        TrajOptSolver(problem, "radau"), beta=0.5, budget=RefinementBudget()
    )
    assert refinement.certified, refinement.reason
    assert result.problem.n_knots <= 100
    assert result.objective == pytest.approx(33.2369, abs=2e-3)
    assert certify(result).passed()
    assert collocation_error(result).max <= 1e-3


def test_command_line_solve_with_radau(tmp_path: Path) -> None:
    """``youbot-opt solve --transcription radau``: the run folder, its result and its summary.

    Reloading the saved result gives the same trajectory (the stage arrays are
    saved); the active-bound report covers the stage blocks (torque_stage*).
    """
    import json

    from youbot_opt.cli import main
    from youbot_opt.trajopt.io import load_refined

    out = tmp_path / "run"
    assert main(["solve", "--transcription", "radau", "--knots", "12", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["method"] == "radau" and summary["certified"] is True, summary.get("certified")
    result, refinement = load_refined(out / "result.npz")
    assert result.method == "radau" and refinement.certified
    assert result.objective == pytest.approx(summary["objective"], rel=1e-12)
    assert result.trajectory is not None and result.trajectory.tau_stages is not None
    assert result.trajectory.tau_stages.shape == (result.problem.n_knots - 1, 2, 3)
    families = {row.name.rsplit("_", 1)[0] for row in result.active_bounds(1e-6)}
    assert families <= {
        "position", "velocity", "torque", "torque_stage1", "torque_stage2", "dt",
        "velocity_control_left", "velocity_control_right",
        "position_control_left", "position_control_right",
    }  # fmt: skip


def test_work_weights_are_the_radau_weights_per_interval() -> None:
    """Per interval ``h_k (b_1, b_2, b_3)`` on stage 1, stage 2, end knot; no knot-midpoint rule."""
    from youbot_opt.exceptions import TranscriptionError
    from youbot_opt.trajopt.transcription import RadauCollocation

    method = RadauCollocation([1.0, 3.0])  # steps 0.5 and 1.5 times the mean step
    weights = dict(method.work_weights(3))
    b = BUTCHER[2]
    np.testing.assert_allclose(weights["tau"], [0.0, 0.5 * b[2], 1.5 * b[2]], atol=1e-15)
    np.testing.assert_allclose(weights["tau_stage1"], [0.5 * b[0], 1.5 * b[0]], atol=1e-15)
    np.testing.assert_allclose(weights["tau_stage2"], [0.5 * b[1], 1.5 * b[1]], atol=1e-15)
    with pytest.raises(TranscriptionError, match="work_weights"):
        method.quadrature(3)


def test_auto_picks_radau_where_the_damping_is_stiff_on_the_grid() -> None:
    """``method="auto"``: Radau for the 5 N m s/rad youBot on 20 knots, else Hermite-Simpson.

    With the default 4.9 s guess, 20 knots give a 0.26 s step and ``rate * h``
    about 970 (the rate is 3.8e3 1/s at the start and goal): stiff. 2000 knots
    give 2.5e-3 s and about 9; without damping the rate is 0.
    """
    from youbot_opt.dynamics.numeric import STIFF_RATIO
    from youbot_opt.trajopt.solver import auto_transcription

    stiff = study1_problem(20, damping=STIFF)
    rate = damping_rate(stiff.robot, np.stack([stiff.start.q, stiff.goal.q])).rate
    assert rate * 4.9 / 19 > 5 * STIFF_RATIO and rate * 4.9 / 1999 < STIFF_RATIO / 5
    assert auto_transcription(stiff) == "radau"
    assert TrajOptSolver(stiff, "auto").method.name == "radau"
    assert auto_transcription(study1_problem(2000, damping=STIFF)) == "hermite_simpson"
    assert auto_transcription(study1_problem(20)) == "hermite_simpson"
