"""Collocation-error estimate and mesh refinement (trajopt.mesh, trajopt.refine).

References: the estimate against closed forms on a double integrator (a
prismatic slider, ``pin.aba`` gives ``a = tau / m``); refined plans against
the forward-simulation certificate (``certify``, re-run here) and the converged
study-1 optimum f = 8.074944, T = 2.313 s (Hermite-Simpson, 800 knots, README).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError, ResultFileError, SolveFailed
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.sweeps.forked import can_fork
from youbot_opt.trajopt.certify import certify, check_bounds
from youbot_opt.trajopt.io import load_refined, load_result, save_result
from youbot_opt.trajopt.mesh import (
    collocation_error,
    interval_errors,
    observed_exponents,
    solution_moved,
    split_grid,
    switching_intervals,
)
from youbot_opt.trajopt.refine import RefinementBudget, refine
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.transcription import HermiteSimpsonCollocation

MASS = 2.0  # [kg] of the slider (tests/trajopt/conftest.py)
F_CONVERGED, T_CONVERGED = 8.074944, 2.313  # study-1 base case, HS 800 knots (README)


def _slider_knots(rng, n, hs):
    """Knots satisfying the collocation equations exactly (a = tau / m) on random steps."""
    t = np.concatenate(([0.0], np.cumsum(rng.uniform(0.1, 0.5, n - 1))))
    h = np.diff(t)
    tau = rng.uniform(-3.0, 3.0, (n, 1))
    a = tau / MASS
    q, v = np.zeros((n, 1)), np.zeros((n, 1))
    taum = rng.uniform(-3.0, 3.0, (n - 1, 1))
    am, qm, vm = taum / MASS, np.zeros((n - 1, 1)), np.zeros((n - 1, 1))
    for k in range(n - 1):
        if hs:
            v[k + 1] = v[k] + h[k] / 6 * (a[k] + 4 * am[k] + a[k + 1])
            vm[k] = 0.5 * (v[k] + v[k + 1]) + h[k] / 8 * (a[k] - a[k + 1])
            q[k + 1] = q[k] + h[k] / 6 * (v[k] + 4 * vm[k] + v[k + 1])
            qm[k] = 0.5 * (q[k] + q[k + 1]) + h[k] / 8 * (v[k] - v[k + 1])
        else:
            v[k + 1] = v[k] + h[k] / 2 * (a[k] + a[k + 1])
            q[k + 1] = q[k] + h[k] / 2 * (v[k] + v[k + 1])
    return t, q, v, tau, a, (qm, vm, taum), am


def test_trapezoidal_error_equals_the_closed_form(slider):
    """Trapezoid on a double integrator: position error |a1 - a0| h^2 / 12, velocity error 0.

    With linear v_lin and the quadratic velocity whose slope is linear in a,
    v_lin - v = (a1 - a0) s (h - s) / (2 h), whose integral is |a1 - a0| h^2 / 12.
    The residual is a quadratic without sign change, so 5-point Gauss-Legendre
    is exact: only round-off remains (1e-12 relative).
    """
    t, q, v, tau, a, _, _ = _slider_knots(np.random.default_rng(0), 7, hs=False)
    err = interval_errors("trapezoidal", t, q, v, tau, slider, damping=False)
    h = np.diff(t)
    np.testing.assert_allclose(err.absolute[:, 0], np.abs(np.diff(a[:, 0])) * h**2 / 12, rtol=1e-12)
    np.testing.assert_allclose(err.absolute[:, 1], 0.0, atol=1e-13)
    scale = 1.0 + max(np.abs(q).max(), np.abs(v).max())
    np.testing.assert_allclose(err.relative, err.absolute[:, 0] / scale, rtol=1e-12)


def test_constant_acceleration_has_no_trapezoidal_error(slider):
    """Constant torque: the trapezoid is exact, the estimate vanishes (round-off, 1e-13)."""
    t, q, v, tau, _, _, _ = _slider_knots(np.random.default_rng(1), 6, hs=False)
    tau[:] = 1.7
    a = tau / MASS
    v = np.concatenate(([[0.3]], 0.3 + np.cumsum(np.diff(t) * a[1:, 0])[:, None]))
    q = 0.3 * t[:, None] + 0.5 * a * t[:, None] ** 2
    err = interval_errors("trapezoidal", t, q, v, tau, slider, damping=False)
    assert err.max < 1e-13


def test_hermite_simpson_error_equals_the_closed_form(slider):
    """HS on a double integrator: position error |a0 - 2 am + a1| h^2 / 48, velocity error 0.

    The quadratic through (v0, vm, v1) minus the cubic velocity is
    c s (s - h/2) (s - h) with c = -2 (a0 - 2 am + a1) / (3 h^2); the integral
    of its modulus is |c| h^4 / 32. Its sign changes at h/2, a node of the
    composite rule's 4 pieces, so the quadrature is exact (1e-12 relative).
    """
    t, q, v, tau, a, mid, am = _slider_knots(np.random.default_rng(2), 6, hs=True)
    err = interval_errors("hermite_simpson", t, q, v, tau, slider, mid=mid, damping=False)
    h = np.diff(t)
    expected = np.abs(a[:-1, 0] - 2 * am[:, 0] + a[1:, 0]) * h**2 / 48
    np.testing.assert_allclose(err.absolute[:, 0], expected, rtol=1e-12)
    np.testing.assert_allclose(err.absolute[:, 1], 0.0, atol=1e-13)
    with pytest.raises(ParameterError, match="midpoint"):
        interval_errors("hermite_simpson", t, q, v, tau, slider, damping=False)


def test_split_grid_pieces_follow_the_error_exponent():
    """e / tol = 8 with e ~ h^3 needs 2 pieces, 27 needs 3, 1e6 is capped at 4; others stay."""
    t = np.array([0.0, 1.0, 3.0, 4.0, 4.5])
    fractions, parent = split_grid(t, np.array([8.0, 27.0, 0.5, 1e6]), 1.0, 3, 4)
    np.testing.assert_array_equal(parent, [0, 0, 1, 1, 1, 2, 3, 3, 3, 3])
    np.testing.assert_allclose(fractions * 4.5, [0.5, 0.5, *[2 / 3] * 3, 1.0, *[0.125] * 4])


def test_split_grid_takes_one_exponent_per_interval():
    """e / tol = 8 needs 2 pieces at m = 3 but 8 at m = 1 (capped by max_pieces)."""
    t = np.array([0.0, 1.0, 2.0])
    _, parent = split_grid(t, np.array([8.0, 8.0]), 1.0, np.array([3.0, 1.0]), 16)
    np.testing.assert_array_equal(np.bincount(parent), [2, 8])
    _, parent = split_grid(t, np.array([8.0, 8.0]), 1.0, np.array([3.0, 1.0]), 4)
    np.testing.assert_array_equal(np.bincount(parent), [2, 4])


def test_observed_exponents_measure_the_fall_of_the_error():
    """Hand numbers: e 8 -> 1 over 2 pieces is m = 3, 8 -> 2 is m = 2; clipped to [1, m].

    Interval 0 (error 8) was split in 2 (pieces 1 and 2 of the error), interval 1
    kept (it inherits its exponent 2.5), interval 2 (error 4) split in 4: one piece
    grew (clipped to 1), one vanished (clipped to the method's 3), two fell by
    4^1.5 = 8 (m = 1.5).
    """
    parent = np.array([0, 0, 1, 2, 2, 2, 2])
    errors = np.array([1.0, 2.0, 0.3, 5.0, 0.0, 0.5, 0.5])
    m = observed_exponents(np.array([8.0, 0.5, 4.0]), errors, parent, np.array([3.0, 2.5, 3.0]))
    np.testing.assert_allclose(m, [3.0, 2.0, 2.5, 1.0, 3.0, 1.5, 1.5], rtol=1e-12)


def test_observed_exponents_carry_the_parent_error_to_the_new_duration():
    """T grew by 1.25: the pieces are 1.25 times longer, so 8 * 1.25^3 -> 1.953 over 2 is m = 3.

    Without the stretch the same fall reads as m = 2.03 (the order reduction
    the iiwa's refinement saw in every round whose T moved).
    """
    parent = np.array([0, 0])
    errors = np.full(2, 8.0 * 1.25**3 / 8.0)
    m = observed_exponents(np.array([8.0]), errors, parent, 3.0, stretch=1.25)
    np.testing.assert_allclose(m, [3.0, 3.0], rtol=1e-12)
    m_plain = observed_exponents(np.array([8.0]), errors, parent, 3.0)
    np.testing.assert_allclose(m_plain, np.log2(8.0 / errors), rtol=1e-12)


def test_a_solution_whose_duration_changed_by_more_than_one_percent_moved():
    """solution_moved: |T_new / T_old - 1| > 1 % (MOVED); a bad old T counts as moved."""
    assert not solution_moved(2.0, 2.0 * 1.009)
    assert solution_moved(2.0, 2.0 * 1.011) and solution_moved(2.0, 2.0 / 1.02)
    assert solution_moved(0.0, 1.0) and solution_moved(1.0, float("nan"))


def test_switching_intervals_are_where_the_active_bounds_change():
    """A velocity bound active at knots 3-5 only: intervals 2 and 5 switch, no other.

    Positions at mid-range and zero torques are inactive everywhere; the
    solved plan's own values are replaced, so the answer is known by construction.
    """
    r = TrajOptSolver(study1_problem(12), "trapezoidal").solve()
    b = r.bounds()
    v = np.zeros((12, 3))
    v[3:6, 1] = b.v_upper[1]
    variables = {**r.variables, "q": np.tile(0.5 * (b.q_lower + b.q_upper), (12, 1)),
                 "v": v, "tau": np.zeros((12, 3))}  # fmt: skip
    flagged = switching_intervals(dataclasses.replace(r, variables=variables))
    np.testing.assert_array_equal(np.nonzero(flagged)[0], [2, 5])


def test_on_grid_shares_the_dynamics_and_reproduces_the_uniform_grid():
    """on_grid(equal fractions) solves the uniform NLP again (round-off) with shared kernels."""
    solver = TrajOptSolver(study1_problem(20), "trapezoidal")
    uniform = solver.solve(beta=0.5).raise_for_status()
    other = solver.on_grid(np.ones(19))
    assert other.dynamics is solver.dynamics and other.problem.n_knots == 20
    assert other.method.fractions is not None and solver.method.fractions is None
    again = other.solve(beta=0.5).raise_for_status()
    assert again.objective == pytest.approx(uniform.objective, rel=1e-9)
    np.testing.assert_allclose(again.trajectory.q, uniform.trajectory.q, atol=1e-7)
    with pytest.raises(ParameterError, match="fractions"):
        solver.on_grid([0.5, -0.5])


@pytest.fixture(scope="module")
def base_refined():
    return refine(TrajOptSolver(study1_problem(50), "trapezoidal"), beta=0.5)


def test_refinement_certifies_the_base_case(base_refined):
    """50-knot trapezoid (certificate fails) -> a certified plan near the converged optimum.

    Re-checked here, not read from the record: the certificate re-run on the
    final plan passes, and every interval's recomputed error is within the
    tolerance. f is within 0.5 % of the converged optimum (the 50-knot grid is
    2.4 % above it), T within 1 %. The 50-knot plan's errors are over the
    tolerance, so refinement does not simulate it (its record has no
    certificate); certified here, it fails.
    """
    r, record = base_refined
    assert base_refined.certified and record.reason == "certified" and r.success
    assert record.rounds[0].n_knots == 50 and record.rounds[0].certificate_passed is None
    assert not certify(TrajOptSolver(study1_problem(50), "trapezoidal").solve(beta=0.5)).ok
    assert certify(r).ok
    assert collocation_error(r).max <= record.budget.tolerance
    assert r.grid is not None and r.problem.n_knots > 50
    assert r.objective == pytest.approx(F_CONVERGED, rel=5e-3)
    assert r.duration == pytest.approx(T_CONVERGED, rel=1e-2)
    assert [x.n_knots for x in record.rounds] == sorted(x.n_knots for x in record.rounds)


@pytest.mark.skipif(not can_fork(), reason="the forked integrations need fork (Linux)")
def test_two_certificate_processes_refine_the_same_way(base_refined):
    """``processes=2`` changes where the certificate's integrations run, nothing else:
    the same rounds, plan and verdict, the final certificate's figures bit for bit."""
    again = refine(TrajOptSolver(study1_problem(50), "trapezoidal"), beta=0.5, processes=2)
    _same_rounds(base_refined, again)
    one, two = base_refined.refinement.certificate, again.refinement.certificate
    assert one is not None and two is not None and two.ok
    np.testing.assert_array_equal(one.local_position_error, two.local_position_error)
    np.testing.assert_array_equal(one.feedback_rms_ratio, two.feedback_rms_ratio)
    with pytest.raises(ParameterError, match="processes"):
        refine(TrajOptSolver(study1_problem(50), "trapezoidal"), processes=0)


def test_refined_result_round_trips_through_a_file(base_refined, tmp_path):
    """Grid and refinement record are saved; the loaded plan is certified again.

    Every round's scalars and arrays come back exactly (JSON floats and npz
    arrays are lossless), and the certificate re-run on load passes. The
    same plan saved without its record (a fixed-grid result) loads as a bare
    result, and has no record to load as refined.
    """
    path = save_result(base_refined.result, tmp_path / "r.npz", refinement=base_refined.refinement)
    loaded = load_refined(path)
    result = base_refined.result
    np.testing.assert_array_equal(loaded.result.grid, result.grid)
    np.testing.assert_array_equal(loaded.result.trajectory.t, result.trajectory.t)
    assert loaded.result.success and loaded.result.check().passed
    assert loaded.certified and loaded.refinement.certificate.ok
    assert load_result(path).summary() == loaded.result.summary() | {"certified": False}
    saved, back = base_refined.refinement, loaded.refinement
    assert back.reason == saved.reason and back.budget == saved.budget
    assert len(back.rounds) == len(saved.rounds)
    for a, b in zip(saved.rounds, back.rounds, strict=True):
        assert a.summary() == b.summary()
        np.testing.assert_array_equal(a.t, b.t)
        np.testing.assert_array_equal(a.errors, b.errors)
        np.testing.assert_array_equal(a.objective_history, b.objective_history)
    assert loaded.require_certified() is loaded.result
    fixed_path = save_result(result, tmp_path / "f")
    assert not load_result(fixed_path).summary()["certified"]
    with pytest.raises(ResultFileError, match="no refinement record"):
        load_refined(fixed_path)


def test_refinement_plot_shows_every_round(base_refined):
    """plot_refinement: one error curve per round, labelled with its knots."""
    from youbot_opt.viz.plots.trajopt import plot_refinement

    fig = plot_refinement(base_refined)
    labels = [line.get_label() for line in fig.axes[1].get_legend().get_texts()]
    assert len(labels) == len(base_refined.refinement.rounds) + 1  # + the tolerance line
    with pytest.raises(ParameterError, match="not refined"):
        plot_refinement(base_refined.result)  # type: ignore[arg-type]


def test_refinement_drives_the_coarse_grid_exploit_to_the_true_family():
    """8 trapezoidal knots: f 23 % below the true optimum (the grid is exploited) -> certified.

    The coarse solve is 'solved' with T = 4.1 s and one-interval re-simulation
    errors of ~15 rad; refinement must land in the true family (f within 1 %
    of the converged optimum, T within 2 %) and pass the certificate. Every
    round is certified here (``certify_every_round``), for round 0's figures.
    """
    budget = RefinementBudget(certify_every_round=True)
    refined = refine(TrajOptSolver(study1_problem(8), "trapezoidal"), beta=0.5, budget=budget)
    r = refined.result
    first = refined.refinement.rounds[0]
    assert first.status == "solved" and first.objective < 0.8 * F_CONVERGED
    assert first.certificate_passed is False and first.local_position > 1.0
    assert refined.certified and certify(r).ok
    assert r.objective == pytest.approx(F_CONVERGED, rel=1e-2)
    assert r.duration == pytest.approx(T_CONVERGED, rel=2e-2)


def test_exhausted_budget_says_which_check_failed():
    """One round allowed on the 50-knot grid: not certified, and the reason names the budget."""
    budget = RefinementBudget(tolerance=1e-3, max_rounds=1)
    refined = refine(TrajOptSolver(study1_problem(50), "trapezoidal"), beta=0.5, budget=budget)
    r = refined.result
    assert r.success and not refined.certified
    reason = refined.refinement.reason
    assert reason.startswith("not certified: max error") and "at most 1 rounds" in reason
    assert reason in r.message
    assert r.raise_for_status() is r  # the solve itself succeeded
    with pytest.raises(SolveFailed, match="solved, NOT certified: max error .* rounds"):
        refined.require_certified()
    with pytest.raises(ParameterError, match="max_rounds"):
        RefinementBudget(max_rounds=0)
    with pytest.raises(ParameterError, match="safety"):
        RefinementBudget(safety=0.0)
    with pytest.raises(ParameterError, match="fallback must be True or False, got 1"):
        RefinementBudget(fallback=1)  # type: ignore[arg-type]


def test_a_hermite_simpson_torque_overshoot_falls_back_to_the_trapezoid():
    """UR5 point-to-point at beta = 1 on 10 Hermite-Simpson knots (docs/refinement.md).

    A torque switches between its 150 N m bounds inside an interval: no
    Hermite-Simpson grid passes the between-knots torque check (measured: 8
    rounds to 74 knots, not certified). The default budget re-solves the same 10
    knots with the trapezoid from that plan and splits on its error: certified
    (measured 10 HS, 10 and 145 trapezoidal knots). Without the fallback the
    reason names the scheme to use; a transcription that needs none keeps its own.
    """
    from youbot_opt.robot.load import load_model
    from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem

    q0 = np.array([0.0, -1.2, 1.0, -0.5, 0.3, 0.0])
    q1 = np.array([0.8, -0.6, 0.4, -1.2, -0.3, 0.5])
    problem = TrajOptProblem(
        robot=load_model("ur5"), start=BoundaryState(q=q0), goal=BoundaryState(q=q1), n_knots=10
    )
    solver = TrajOptSolver(problem, "hermite_simpson")
    refined = refine(solver, beta=1.0)
    rounds = refined.refinement.rounds
    assert refined.certified, refined.refinement.reason
    assert [r.method for r in rounds[:2]] == ["hermite_simpson", "trapezoidal"]
    assert rounds[1].n_knots == rounds[0].n_knots == 10 and rounds[0].certificate_passed is False
    assert refined.result.method == "trapezoidal" and refined.result.problem.n_knots > 10
    np.testing.assert_allclose(refined.result.trajectory.q[[0, -1]], [q0, q1], atol=1e-6)
    budget = RefinementBudget(max_rounds=1, fallback=False)
    alone = refine(solver, first=solver.solve(beta=1.0), budget=budget)
    assert not alone.certified and "--transcription trapezoidal" in alone.refinement.reason
    assert [r.method for r in alone.refinement.rounds] == ["hermite_simpson"]


def test_a_knot_budget_shrinks_the_split_before_it_stops():
    """max_knots = 120 from 50 knots at 1e-4 (the full split wants 225): round 1 fits the budget.

    Halving the pieces per interval down to 2 always fits here (at most 99
    knots), so the refinement goes on to round 1 instead of stopping.
    """
    budget = RefinementBudget(tolerance=1e-4, max_knots=120, max_rounds=2)
    r = refine(TrajOptSolver(study1_problem(50), "trapezoidal"), beta=0.5, budget=budget)
    rounds = r.refinement.rounds
    assert len(rounds) == 2 and 50 < rounds[1].n_knots <= 120
    assert "after 2 rounds" in r.refinement.reason or r.certified


def test_a_time_limit_leaves_the_certificate_incomplete():
    """certify(time_limit) stops its simulations: NaN figures, an 'incomplete' failure.

    1e-6 s runs out before the first right-hand side is evaluated, so every
    simulation is skipped; without a limit the same plan gets every figure.
    refine() passes what is left of its time budget; a budget spent before
    round 0's certificate starts skips it, and the reason says so (never a
    certificate "limited" to a nonsensical remainder).
    """
    solver = TrajOptSolver(study1_problem(12), "trapezoidal")
    plan = solver.solve(beta=0.5).raise_for_status()
    cert = certify(plan, time_limit=1e-6)
    assert cert.incomplete == "time limit 1e-06 s reached during the one-interval integrations"
    assert not cert.ok and cert.failures()[0] == f"incomplete: {cert.incomplete}"
    assert np.isnan(cert.feedback_rms) and np.isnan(cert.local_position_max)
    assert str(cert).splitlines()[0].endswith(f"INCOMPLETE, {cert.incomplete}")
    assert certify(plan).incomplete == "" and np.isfinite(certify(plan).feedback_rms)
    budget = RefinementBudget(time_limit=1e-6, tolerance=1.0)  # errors pass: only the certificate
    r = refine(solver, first=plan, budget=budget)
    assert not r.certified and len(r.refinement.rounds) == 1
    assert r.refinement.rounds[0].certificate_passed is None
    assert r.refinement.rounds[0].failures == ()
    assert "no time left for the certificate after" in r.refinement.reason
    with pytest.raises(ParameterError, match="time_limit"):
        certify(plan, time_limit=0.0)


def test_hermite_simpson_position_bound_holds_between_knots():
    """HS keeps the whole position cubic within its bounds (Bernstein hull rows).

    A base case with positions scaled to 60 % makes a position bound active.
    Sampling the plan's interpolant 50 times per interval (the certificate's
    bound check) finds no excess beyond the NLP's feasibility (1e-6 relative);
    the previous formulation, bounding q only at knots and midpoints, exceeds
    it by 1 % of the half range between knots at 12 knots.
    """

    class KnotsOnly(HermiteSimpsonCollocation):
        unbounded = ("v_mid",)

        def path_constraints(self, sym, accel):
            return [row for row in super().path_constraints(sym, accel) if row[1] == "v"]

    problem = dataclasses.replace(study1_problem(12), scaled_bounds=("position",))
    excess = {}
    for method in (HermiteSimpsonCollocation(), KnotsOnly()):
        r = TrajOptSolver(problem, method).solve(beta=0.5, bound_scale=0.6).raise_for_status()
        checks = check_bounds(r.trajectory, r.bounds(), samples_per_interval=50)
        excess[type(method).__name__] = {
            c.where: c.relative for c in checks if c.quantity == "position"
        }
    assert excess["HermiteSimpsonCollocation"]["knots"] > -1e-6  # the bound is active
    assert excess["HermiteSimpsonCollocation"]["between"] <= 1e-6
    assert excess["KnotsOnly"]["between"] > 1e-3


@pytest.mark.parametrize("method", ["trapezoidal", "hermite_simpson"])
def test_identity_transfer_restarts_at_the_solution(method):
    """Transferred onto the same grid, the primal-dual start is the solution: IPOPT stops at once.

    Knot values are the previous knots (1e-12: the trajectory interpolates them),
    multipliers the previous ones up to the density round trip (1e-12 relative);
    the warm-started solve then needs at most 2 iterations (a cold start: 18+)
    and returns the same objective (1e-8 relative, IPOPT's tolerance).
    """
    from youbot_opt.trajopt.refine import transfer_start

    solver = TrajOptSolver(study1_problem(20), method)
    first = solver.solve(beta=0.5).raise_for_status()
    parent = np.arange(19)
    x0, lam_x0, lam_g0 = transfer_start(first, solver, parent, first.trajectory.t)
    np.testing.assert_allclose(
        solver.nlp.variables.unpack(x0)["q"], first.variables["q"], atol=1e-12
    )
    lam_g = solver.nlp.constraints.pack(
        {k: first.multipliers[k] for k in solver.nlp.constraints.blocks}
    )
    np.testing.assert_allclose(lam_g0, lam_g, rtol=1e-12, atol=1e-14)
    again = solver.solve(beta=0.5, initial=(x0, lam_x0, lam_g0)).raise_for_status()
    assert again.iterations <= 2 < first.iterations
    assert again.objective == pytest.approx(first.objective, rel=1e-8)


def test_the_time_limit_caps_a_rounds_solve_and_keeps_the_last_plan(monkeypatch):
    """A round's IPOPT solve gets what is left of the budget as max_wall_time.

    Two parts, neither depending on the machine's speed: IPOPT itself stops a
    solve capped at 1e-6 s (it checks the wall clock every iteration, and one
    iteration takes longer) with status MAX_TIME; and refine(), seeing a round
    end so, returns the previous round's plan, uncertified, naming the round,
    instead of the unfinished iterate (the solve is replaced by one that
    reports MAX_TIME, so the branch is taken whatever the clock says).
    """
    solver = TrajOptSolver(study1_problem(12), "trapezoidal")
    plan = solver.solve(beta=0.5).raise_for_status()
    capped = solver.on_grid(np.full(11, 1 / 11), max_wall_time=1e-6)
    assert capped.options.max_wall_time == 1e-6 and solver.options.max_wall_time is None
    assert capped.solve(beta=0.5).status is SolveStatus.MAX_TIME
    with pytest.raises(ParameterError, match="max_wall_time"):
        solver.on_grid(np.full(11, 1 / 11), max_wall_time=0.0)

    caps: list[float | None] = []
    on_grid = TrajOptSolver.on_grid

    def timed_out(self, fractions, *, max_wall_time=None):  # type: ignore[no-untyped-def]
        new = on_grid(self, fractions, max_wall_time=max_wall_time)
        caps.append(new.options.max_wall_time)
        monkeypatch.setattr(
            new, "solve", lambda **kw: dataclasses.replace(plan, status=SolveStatus.MAX_TIME)
        )
        return new

    monkeypatch.setattr(TrajOptSolver, "on_grid", timed_out)
    budget = RefinementBudget(tolerance=1e-6, time_limit=600.0)  # round 0 fails its errors
    r = refine(solver, first=plan, budget=budget)
    assert len(caps) == 1 and caps[0] is not None and 0.0 < caps[0] <= 600.0
    assert r.result.success and not r.certified and r.result.problem.n_knots == 12  # round 0's
    assert len(r.refinement.rounds) == 1
    assert "the time limit ran out in round 1's solve" in r.refinement.reason
    assert "round 0's plan is returned" in r.refinement.reason


def _same_rounds(cheap, every):
    """The two refinements made the same solves: grids, schemes, iterations, f, plan bit for bit."""
    a, b = cheap.refinement.rounds, every.refinement.rounds
    assert [(r.n_knots, r.method, r.iterations) for r in a] == [
        (r.n_knots, r.method, r.iterations) for r in b
    ]
    assert [r.objective for r in a] == [r.objective for r in b]
    for name, x in cheap.result.variables.items():
        np.testing.assert_array_equal(x, every.result.variables[name])
    assert cheap.certified == every.certified and cheap.refinement.reason == every.refinement.reason


def test_the_certificate_is_simulated_only_where_the_plan_may_pass():
    """Issue 27: the error estimate first, the forward simulation where the errors pass.

    The study's base case (50 -> 86 -> 123 trapezoidal knots, f = 8.090279):
    rounds 0 and 1 are over the tolerance and get no certificate; the final
    plan gets the full one (its figures are in its record and
    ``refinement.certificate``). Certifying every round changes none of the
    solves (same grids, iterations and plan bit for bit), only the history.
    A budget that stops over the tolerance still certifies the plan it returns.
    """
    solver = TrajOptSolver(study1_problem(50), "trapezoidal")
    cheap = refine(solver, beta=0.5)
    every = refine(solver, beta=0.5, budget=RefinementBudget(certify_every_round=True))
    rounds = cheap.refinement.rounds
    assert [r.n_knots for r in rounds] == [50, 86, 123]
    assert round(cheap.result.objective, 6) == 8.090279 and cheap.certified
    assert [r.certificate_passed for r in rounds] == [None, None, True]
    assert all(np.isnan(r.feedback_rms) for r in rounds[:2]) and np.isfinite(rounds[2].feedback_rms)
    assert cheap.refinement.certificate is not None and cheap.refinement.certificate.ok
    assert [r.certificate_passed for r in every.refinement.rounds] == [False, True, True]
    _same_rounds(cheap, every)
    stopped = refine(solver, beta=0.5, budget=RefinementBudget(max_rounds=2))
    last = stopped.refinement.rounds[-1]
    assert not stopped.certified and last.max_error > 1e-3 and last.certificate_passed is True
    assert stopped.refinement.certificate is not None and np.isfinite(last.feedback_rms)


@pytest.mark.slow
def test_the_cheap_decision_keeps_the_hermite_simpson_fallback():
    """UR5, beta = 1, 10 Hermite-Simpson knots: the bound checks alone find the overshoot.

    Round 0 is over the tolerance (no simulation) but its between-knots
    torque check fails (``certificate_passed`` False, the check named), so
    the trapezoidal fallback comes in the same round as with every round
    certified, and every solve is the same.
    """
    from youbot_opt.robot.load import load_model
    from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem

    q0 = np.array([0.0, -1.2, 1.0, -0.5, 0.3, 0.0])
    q1 = np.array([0.8, -0.6, 0.4, -1.2, -0.3, 0.5])
    problem = TrajOptProblem(
        robot=load_model("ur5"), start=BoundaryState(q=q0), goal=BoundaryState(q=q1), n_knots=10
    )
    solver = TrajOptSolver(problem, "hermite_simpson")
    first = solver.solve(beta=1.0)
    cheap = refine(solver, first=first)
    every = refine(solver, first=first, budget=RefinementBudget(certify_every_round=True))
    zero = cheap.refinement.rounds[0]
    assert zero.max_error > 1e-3 and zero.certificate_passed is False
    assert np.isnan(zero.feedback_rms)
    assert any(f.startswith("bound torque, between knots") for f in zero.failures)
    assert [r.method for r in cheap.refinement.rounds[:2]] == ["hermite_simpson", "trapezoidal"]
    _same_rounds(cheap, every)
