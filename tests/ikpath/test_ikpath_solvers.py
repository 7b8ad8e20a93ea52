"""Both IK-path methods against an enumerated global optimum and against each other."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError, SolveFailed, UnreachableTarget
from youbot_opt.ikpath.examples import example_problem
from youbot_opt.ikpath.methods.al import (
    ALOptions,
    solve_augmented_lagrangian,
)
from youbot_opt.ikpath.methods.ipopt import IpoptIKSolver, IpoptOptions
from youbot_opt.ikpath.methods.sqp import first_order_multipliers
from youbot_opt.ikpath.multistart import configuration_distance
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.solve import solve
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.planar import PlanarChain
from youbot_opt.sweeps.options import SweepOptions

LA, LB = 1.0, 0.8
TARGETS_2 = [(1.2, 0.5), (0.3, 1.1), (-0.9, 0.6), (0.4, -1.0)]


def _two_link_optimum(targets):
    """Global optimum of a 2-link cyclic path by enumeration (independent of both solvers).

    A 2-link arm has two IK solutions per target (elbow +/-) up to 2 pi windings, so
    E is minimised over 2^s elbow choices and, joint by joint (E separates), over
    windings m_j in {-2..2} of every configuration but the first.
    """
    sols = []
    for px, py in targets:
        c = (px * px + py * py - LA * LA - LB * LB) / (2 * LA * LB)
        pair = []
        for b in (np.arccos(c), -np.arccos(c)):
            a = np.arctan2(py, px) - np.arctan2(LB * np.sin(b), LA + LB * np.cos(b))
            pair.append(np.array([a, b]))
        sols.append(pair)
    s = len(targets)
    best = (np.inf, None)
    for elbows in itertools.product((0, 1), repeat=s):
        q = np.array([sols[j][e] for j, e in enumerate(elbows)])
        total, chosen = 0.0, q.copy()
        for i in range(2):
            col_best = (np.inf, None)
            for m in itertools.product(range(-2, 3), repeat=s - 1):
                col = q[:, i] + 2 * np.pi * np.r_[0, m]
                e = 0.5 * np.sum((np.roll(col, -1) - col) ** 2)
                if e < col_best[0]:
                    col_best = (e, col)
            total += col_best[0]
            chosen[:, i] = col_best[1]
        if total < best[0]:
            best = (total, chosen)
    return best


@pytest.fixture(scope="module")
def two_link():
    prob = CyclicIKProblem(robot=PlanarChain(lengths=[LA, LB]), targets=TARGETS_2)
    return prob, _two_link_optimum(TARGETS_2)


@pytest.mark.parametrize("method", ["al", "ipopt"])
def test_methods_reach_enumerated_optimum(two_link, method, rng):
    """From a start 0.1 rad off the enumerated optimum each method converges to it.

    Tolerances: E to 1e-9 (stationarity 1e-8 gives E errors ~1e-16; 1e-9 absorbs
    the constraint tolerance 1e-10 times multipliers O(1)); configurations to 1e-6 rad.
    """
    prob, (e_star, q_star) = two_link
    x0 = q_star + rng.uniform(-0.1, 0.1, q_star.shape)
    res = solve(prob, method=method, x0=x0)
    assert res.status is SolveStatus.SOLVED, res.message
    assert res.objective == pytest.approx(e_star, abs=1e-9)
    assert configuration_distance(res.configurations, q_star) < 1e-6
    assert res.max_position_error() < 1e-9


def test_al_kkt_with_independent_jacobian():
    """At example A's AL optimum grad E = sum_j J_j^T lambda_j, numpy Jacobian (1e-7)."""
    prob = example_problem("A")
    res = solve_augmented_lagrangian(prob)
    assert res.success
    q = res.configurations
    lengths = prob.chain.lengths
    grad = (2 * q - np.roll(q, 1, axis=0) - np.roll(q, -1, axis=0)).ravel()
    jt_lam = []
    for qj, lam in zip(q, res.multipliers, strict=True):
        phi = np.cumsum(qj)
        # dF/dq_k = sum_{i >= k} l_i (-sin phi_i, cos phi_i)
        jx = -np.cumsum((lengths * np.sin(phi))[::-1])[::-1]
        jy = np.cumsum((lengths * np.cos(phi))[::-1])[::-1]
        jt_lam.append(jx * lam[0] + jy * lam[1])
    # the AL stops at projected-gradient 1e-8 of L_A, which is this residual
    np.testing.assert_allclose(grad, np.ravel(jt_lam), atol=1e-7)


@pytest.mark.parametrize("name", ["A", "B"])
def test_methods_agree_on_study_examples(name, rng):
    """AL (from zero) and IPOPT (from a perturbed AL optimum) agree on E, q and multipliers.

    Both stop at stationarity ~1e-8 with constraints ~1e-10: E agrees to 1e-9, q to
    1e-6 rad, multipliers to 1e-6 (measured ~1e-10, 1e-8, 4e-9).
    """
    prob = example_problem(name)
    al = solve(prob, method="al")
    x0 = np.clip(
        al.configurations.ravel() + rng.uniform(-0.02, 0.02, prob.n_variables),
        prob.lower,
        prob.upper,
    )
    ip = solve(prob, method="ipopt", x0=x0)
    assert al.success and ip.success
    assert al.objective == pytest.approx(ip.objective, abs=1e-9)
    assert configuration_distance(al.configurations, ip.configurations) < 1e-6
    np.testing.assert_allclose(al.multipliers, ip.multipliers, atol=1e-6)


def test_example_b_optimum_satisfies_limits():
    """Example B: the AL optimum meets the targets (1e-9 m) and the limits exactly, one active."""
    prob = example_problem("B")
    res = solve(prob, method="al")
    assert res.success
    assert res.max_position_error() < 1e-9
    assert res.limit_violation == 0.0
    assert np.all(np.abs(res.configurations) <= np.pi / 2)
    assert np.isclose(np.abs(res.configurations), np.pi / 2, atol=1e-12).any()  # a limit is active
    assert res.objective == pytest.approx(15.6058914, abs=1e-6)


def test_al_history_records_outer_iterations():
    """The AL history has one entry per outer iteration ending at the returned iterate."""
    res = solve_augmented_lagrangian(example_problem("A"))
    assert len(res.history) == res.iterations >= 2
    last = res.history[-1]
    np.testing.assert_array_equal(last.x, res.configurations)
    assert last.violation <= 1e-10
    assert [h.iteration for h in res.history] == list(range(res.iterations))


def test_lbfgsb_inner_solver_reaches_the_default_optimum():
    """With SciPy's L-BFGS-B inside, the AL solves example B to the default inner solver's E."""
    prob = example_problem("B")
    default = solve_augmented_lagrangian(prob)
    # L-BFGS-B's function-value line search cannot resolve the AL gradient much below
    # 1e-6 at the penalties needed (docs/ikpath.md, "Stopping test"), so it is asked for
    # 1e-6 instead of 1e-8.
    res = solve_augmented_lagrangian(prob, options=ALOptions(inner="lbfgsb", stationarity_tol=1e-6))
    assert default.success, default.message
    assert res.status is SolveStatus.SOLVED, res.message
    assert res.limit_violation == 0.0
    assert np.all(np.abs(res.configurations) <= np.pi / 2)
    # |c|_inf <= 1e-10 m per coordinate, so |c_j|_2 <= sqrt(2) 1e-10 m
    assert res.max_position_error() <= np.sqrt(2) * 1e-10
    # Both points meet |c| <= 1e-10 m with multipliers |lambda| <= 1.3 (E error
    # |lambda . c| ~ 1e-10, first order) and are stationary to 1e-6 resp. 1e-8 (E
    # error second order, ~1e-12); measured 8e-12.
    assert res.objective == pytest.approx(default.objective, abs=1e-9)
    # a projected gradient of 1e-6 leaves q within ~1e-6 / curvature O(1) of the optimum
    assert configuration_distance(res.configurations, default.configurations) < 1e-5


def test_first_order_multipliers_match_the_kkt_point():
    """At the default solver's optimum of A, the least-squares multipliers equal its own."""
    prob = example_problem("A")
    res = solve_augmented_lagrangian(prob)
    assert res.success, res.message
    x = res.configurations.ravel()
    lam, residual = first_order_multipliers(prob.evaluate(x), x, prob.lower, prob.upper)
    # Stationary to omega* = 1e-8 with |c| <= 1e-10 m and J of full rank (sigma_min
    # ~0.5 m/rad), so both estimates agree to ~1e-8 / sigma_min; measured 3e-9.
    np.testing.assert_allclose(lam, np.ravel(res.multipliers), atol=5e-8)
    assert residual <= 1e-8
    # an iterate moved off the optimum along the tangent space is not stationary
    moved = x + 1e-3 * np.random.default_rng(0).standard_normal(x.size)
    _, off = first_order_multipliers(prob.evaluate(moved), moved, prob.lower, prob.upper)
    assert off > 1e-4


_LBFGSB_RUN = """
from youbot_opt.ikpath.methods.al import (
    ALOptions,
    solve_augmented_lagrangian,
)
from youbot_opt.ikpath.examples import example_problem
res = solve_augmented_lagrangian(
    example_problem("B"), options=ALOptions(inner="lbfgsb", stationarity_tol=1e-6)
)
print(res.status.value, repr(res.objective), res.max_position_error())
"""


@pytest.mark.parametrize("kernel", ["Prescott", "Nehalem", "Sandybridge", "Haswell"])
def test_lbfgsb_verdict_does_not_depend_on_the_blas_kernel(kernel):
    """The L-BFGS-B solve of B succeeds under each forced OpenBLAS kernel (issue #11)."""
    # These four kernels run on any x86-64 CPU with AVX2; before the least-squares
    # stationarity test, the first three ended at the outer iteration limit.
    env = {**os.environ, "OPENBLAS_CORETYPE": kernel}
    out = subprocess.run(
        [sys.executable, "-c", _LBFGSB_RUN], env=env, capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr
    status, objective, residual = out.stdout.split()
    assert status == "solved"
    assert float(objective) == pytest.approx(15.605891397951, abs=1e-9)
    assert float(residual) <= np.sqrt(2) * 1e-10


def test_locally_infeasible_start_is_a_status():
    """A start pinned against the limits fails as INFEASIBLE with the last iterate, not a raise."""
    prob = example_problem("B")
    x0 = np.tile([-np.pi / 2, -np.pi / 2, -np.pi / 2], 5)
    res = solve(prob, method="al", x0=x0)
    assert res.status is not SolveStatus.SOLVED
    with pytest.raises(SolveFailed) as info:
        res.raise_for_status()
    assert info.value.result is res


def test_ipopt_solver_is_reused_for_other_targets():
    """One IPOPT build solves problems that differ only in their targets."""
    prob = example_problem("A")
    solver = IpoptIKSolver(prob, IpoptOptions.for_ikpath())
    moved = CyclicIKProblem(robot=prob.chain, targets=prob.target_points + 0.1)
    res = solver.solve(moved, x0=solve(moved, method="al").configurations)
    assert res.success and res.max_position_error() < 1e-9
    other = CyclicIKProblem(robot=PlanarChain(lengths=[3.0, 2.0, 2.0]), targets=prob.target_points)
    with pytest.raises(ParameterError, match="built for"):
        solver.solve(other)


def test_solve_rejects_unreachable_and_bad_method():
    """solve() stops before optimising on an unreachable target and names bad methods."""
    prob = CyclicIKProblem(robot=PlanarChain(lengths=[3.0, 2.0, 2.0]), targets=[(0, 7.1), (5, 0)])
    with pytest.raises(UnreachableTarget, match=r"target p1 = \(0, 7.1\): unreachable"):
        solve(prob)
    with pytest.raises(ParameterError, match="choose one of al, ipopt"):
        solve(example_problem("A"), method="sqp")  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="must be IpoptOptions"):
        solve(example_problem("A"), method="ipopt", options=ALOptions())


def _tips_problem(chain, n_targets, seed):
    """Targets = tips of seeded configurations inside the middle half of the limits."""
    rng = np.random.default_rng(seed)
    lo = np.maximum(chain.q_lower, -np.pi)
    hi = np.minimum(chain.q_upper, np.pi)
    mid, half = 0.5 * (lo + hi), 0.25 * (hi - lo)
    q = rng.uniform(mid - half, mid + half, (n_targets, chain.n))
    return CyclicIKProblem(robot=chain, targets=[chain.tip_position(qj) for qj in q])


@pytest.mark.parametrize("case", ["youbot", "four_link_limited", "five_link_free"])
def test_methods_agree_on_more_problems(case, rng):
    """AL and IPOPT reach the same optimum on the youBot arm and on 4- and 5-link chains.

    IPOPT starts from a perturbed AL optimum (0.02 rad), so both must find the same
    local minimum. Tolerances as for the study examples: E 1e-9, q 1e-6 rad.
    """
    from youbot_opt.robot.planar import youbot_chain

    if case == "youbot":
        prob = _tips_problem(youbot_chain(), 4, seed=1)
    elif case == "four_link_limited":
        chain = PlanarChain(lengths=[1.0, 0.8, 0.6, 0.4], q_lower=-2.0, q_upper=2.0)
        prob = _tips_problem(chain, 5, seed=2)
    else:
        prob = _tips_problem(PlanarChain(lengths=[1.0, 0.9, 0.7, 0.5, 0.3]), 6, seed=3)
    al = solve(prob, method="al")
    assert al.success, al.message
    x0 = np.clip(
        al.configurations.ravel() + rng.uniform(-0.02, 0.02, prob.n_variables),
        prob.lower,
        prob.upper,
    )
    ip = solve(prob, method="ipopt", x0=x0)
    assert ip.success, ip.message
    assert al.max_position_error() < 1e-9 and ip.max_position_error() < 1e-9
    assert al.limit_violation == 0.0 and ip.limit_violation == 0.0
    assert al.objective == pytest.approx(ip.objective, abs=1e-9)
    assert configuration_distance(al.configurations, ip.configurations) < 1e-6


def test_one_link_chain_has_the_closed_form_optimum():
    """1 link, targets (1, 0) and (0, 1): q = 0 and pi/2, E = (pi/2)^2 (Jacobian shape (2, 1))."""
    prob = CyclicIKProblem(robot=PlanarChain(lengths=[1.0]), targets=[(1.0, 0.0), (0.0, 1.0)])
    assert prob.chain.tip_jacobian([0.3]).shape == (2, 1)
    res = solve(prob, method="al")
    assert res.success, res.message
    # E is exact up to the AL's constraint tolerance 1e-10 times multipliers O(1)
    assert res.objective == pytest.approx((np.pi / 2) ** 2, abs=1e-9)
    np.testing.assert_allclose(res.configurations.ravel(), [0.0, np.pi / 2], atol=1e-9)


def test_ipopt_acceptable_level_is_rechecked():
    """IPOPT's 'acceptable' stop with targets missed is not reported as a success."""
    prob = example_problem("A")
    loose = {"acceptable_iter": 1, "acceptable_tol": 1e20, "acceptable_constr_viol_tol": 1e20}
    loose |= {"acceptable_dual_inf_tol": 1e20, "acceptable_compl_inf_tol": 1e20}
    res = solve(prob, method="ipopt", options=IpoptOptions.for_ikpath(extra=loose))
    assert res.message == "Solved_To_Acceptable_Level"
    assert res.max_position_error() > 1e-3  # stopped early, targets missed
    assert res.status is SolveStatus.STALLED


@pytest.mark.parametrize("inner", ["bfgs", "lbfgsb"])
def test_al_wall_time_cap_is_a_time_limit_status_with_the_last_iterate(inner):
    """max_wall_time = 1 ns: TIME_LIMIT after the first inner check, a finite in-box iterate."""
    prob = example_problem("B")
    res = solve(prob, method="al", options=ALOptions(max_wall_time=1e-9, inner=inner))
    assert res.status is SolveStatus.MAX_TIME, res.message
    assert "wall-time limit 1e-09 s reached" in res.message
    assert res.iterations == 1 and res.inner_iterations <= 1  # SciPy's callback runs after one
    assert np.all(np.isfinite(res.configurations)) and res.limit_violation == 0.0
    np.testing.assert_array_equal(res.history[-1].x, res.configurations)
    with pytest.raises(SolveFailed, match="max_time"):
        res.raise_for_status()


def test_al_generous_wall_time_cap_changes_nothing():
    """A cap that is not reached gives the uncapped result (same iterates, same E)."""
    prob = example_problem("A")
    free = solve(prob, method="al")
    capped = solve(prob, method="al", options=ALOptions(max_wall_time=600.0))
    assert capped.success and capped.iterations == free.iterations
    np.testing.assert_array_equal(capped.configurations, free.configurations)


def test_ipopt_time_limits_map_to_the_time_limit_status():
    """IPOPT's wall-time and CPU-time exits are TIME_LIMIT, not NUMERICAL_ERROR."""
    from youbot_opt.ikpath.methods.ipopt import _STATUS

    assert _STATUS["Maximum_WallTime_Exceeded"] is SolveStatus.MAX_TIME
    assert _STATUS["Maximum_CpuTime_Exceeded"] is SolveStatus.MAX_TIME
    res = solve(
        example_problem("A"), method="ipopt", options=IpoptOptions.for_ikpath(max_wall_time=1e-9)
    )
    assert res.message == "Maximum_WallTime_Exceeded"
    assert res.status is SolveStatus.MAX_TIME and np.all(np.isfinite(res.configurations))


@pytest.mark.parametrize("value", [0.0, -1.0, np.nan, np.inf, True, "1"])
def test_bad_wall_time_caps_raise(value):
    """A wall-time cap must be None or a finite number of seconds > 0."""
    with pytest.raises(ParameterError, match="max_wall_time"):
        ALOptions(max_wall_time=value)
    with pytest.raises(ParameterError, match="max_wall_time"):
        IpoptOptions(max_wall_time=value)


def test_ipopt_refuses_chains_with_fewer_than_two_free_joints():
    """1 link (or 2 with one fixed joint): IPOPT lacks degrees of freedom; AL solves it."""
    from youbot_opt.ikpath.multistart import run_multistart

    one = CyclicIKProblem(robot=PlanarChain(lengths=[1.0]), targets=[(1.0, 0.0), (0.0, 1.0)])
    with pytest.raises(ParameterError, match=r"at least 2 free joints, got 1 .*method='al'"):
        solve(one, method="ipopt")
    with pytest.raises(ParameterError, match="at least 2 free joints"):
        run_multistart(one, method="ipopt", n_starts=2, sweep=SweepOptions(workers=1))
    fixed = PlanarChain(lengths=[1.0, 1.0], q_lower=[-3.0, 0.5], q_upper=[3.0, 0.5])
    q = np.array([[0.2, 0.5], [1.1, 0.5]])
    prob = CyclicIKProblem(robot=fixed, targets=[fixed.tip_position(qj) for qj in q])
    with pytest.raises(ParameterError, match=r"got 1 \(of 2\)"):
        solve(prob, method="ipopt")
    res = solve(prob, method="al")
    # joint 2 is fixed at 0.5 rad, so joint 1 is fixed by each target: the drawn q
    assert res.success, res.message
    np.testing.assert_allclose(res.configurations, q, atol=1e-9)
    free = CyclicIKProblem(robot=fixed, targets=prob.target_points, use_limits=False)
    assert solve(free, method="ipopt").success  # without the limits both joints are free


def _exact_ik_starts(prob, n_starts, seed):
    """The zero start plus seeded exact IK solutions of every target (SciPy least squares).

    Built here, independently of both methods and of ``ikpath.multistart``; unlimited
    joints are drawn in [-pi, pi].
    """
    from scipy.optimize import least_squares

    rng = np.random.default_rng(seed)
    chain = prob.chain
    lo = np.maximum(chain.q_lower, -np.pi) if prob.bounded else np.full(chain.n, -np.pi)
    hi = np.minimum(chain.q_upper, np.pi) if prob.bounded else np.full(chain.n, np.pi)
    starts = [prob.default_start()]
    for _ in range(n_starts - 1):
        x = []
        for p in prob.target_points:
            sol = least_squares(
                lambda q, p=p: chain.tip_position(q) - p,
                rng.uniform(lo, hi),
                jac=lambda q: chain.tip_jacobian(q),
                bounds=(lo, hi),
            )
            x.append(sol.x)
        starts.append(np.ravel(x))
    return starts


def _distance_modulo_windings(qa, qb):
    """Largest |qa - qb| [rad] after removing a common 2 pi k shift of each joint column."""
    d = np.asarray(qa) - np.asarray(qb)
    return float(np.max(np.abs(d - 2 * np.pi * np.round(d.mean(axis=0) / (2 * np.pi)))))


def _four_link_problem():
    """4 links, |q| <= 2, four targets: tips of seeded configurations in [-1, 1]^4."""
    chain = PlanarChain(lengths=[1.0, 0.8, 0.6, 0.4], q_lower=-2.0, q_upper=2.0)
    q = np.random.default_rng(4).uniform(-1.0, 1.0, (4, 4))
    return CyclicIKProblem(robot=chain, targets=[chain.tip_position(qj) for qj in q])


@pytest.mark.slow
@pytest.mark.parametrize("name", ["A", "B", "four_link"])
def test_methods_find_the_same_best_minimum_from_independent_starts(name):
    """AL and IPOPT, each from the same 30 starts (zero + seeded exact IK), find the same best E.

    Neither method starts from the other's answer, so this is global agreement over
    the starts, not local. E to 1e-9 rad^2: both stop at |c| <= 1e-10 m (AL) resp.
    1e-11 m (IPOPT) with multipliers O(1), an E error ~1e-10 at first order (measured
    <= 1.3e-11). The best configurations agree to 1e-6 rad (stationarity 1e-8) up to
    the only symmetry of these problems, common 2 pi windings of a joint (example A
    has no limits; B and the 4-link chain's limits |q| <= pi/2, 2 forbid windings).
    """
    prob = _four_link_problem() if name == "four_link" else example_problem(name)
    starts = _exact_ik_starts(prob, 30, seed=0)
    al = [solve_augmented_lagrangian(prob, x0) for x0 in starts]
    solver = IpoptIKSolver(prob)
    ip = [solver.solve(prob, x0) for x0 in starts]
    best = {}
    for method, results in (("al", al), ("ipopt", ip)):
        ok = [r for r in results if r.success]
        assert ok, f"{method}: no start succeeded"
        best[method] = min(ok, key=lambda r: r.objective)
        assert best[method].limit_violation == 0.0
    assert best["al"].objective == pytest.approx(best["ipopt"].objective, abs=1e-9)
    dist = _distance_modulo_windings(best["al"].configurations, best["ipopt"].configurations)
    assert dist < 1e-6


def test_ipopt_ends_within_the_limits_at_an_active_straight_arm(rng):
    """Regression: IPOPT's optima with a limit active end inside the box, not check_failed.

    l = (3, 2, 2), |q| <= pi/2, targets (0, 7) (only q = (pi/2, 0, 0) reaches it) and
    (5, 0). IPOPT's slack_move used to leave x up to 5.7e-12 rad outside pi/2, so 5
    of 20 such starts ended check_failed. Every Solve_Succeeded must now be a success
    with the limits met exactly, at one of the two minima seen (E = 2.30788 or 6.93217,
    to 1e-7: LICQ fails at the straight arm, so E is only determined to ~1e-8).
    """
    half_pi = np.pi / 2
    chain = PlanarChain(lengths=[3.0, 2.0, 2.0], q_lower=-half_pi, q_upper=half_pi)
    prob = CyclicIKProblem(robot=chain, targets=[(0.0, 7.0), (5.0, 0.0)])
    solver = IpoptIKSolver(prob)
    converged = 0
    for x0 in rng.uniform(prob.lower, prob.upper, (20, prob.n_variables)):
        res = solver.solve(prob, x0)
        assert res.limit_violation == 0.0 and res.status is not SolveStatus.CONSTRAINT_VIOLATION
        if res.message.startswith("Solve_Succeeded"):
            converged += 1
            assert res.status is SolveStatus.SOLVED, res.message
            np.testing.assert_allclose(res.configurations[0], [half_pi, 0, 0], atol=1e-7)
            assert min(abs(res.objective - 2.30787901), abs(res.objective - 6.93217280)) < 1e-7
    assert converged >= 10  # measured 14 of 20


def test_ipopt_iterate_outside_the_limits_is_projected(rng):
    """With IPOPT's default slack_move (1.8e-12) x leaves the box; the result is projected back."""
    half_pi = np.pi / 2
    chain = PlanarChain(lengths=[3.0, 2.0, 2.0], q_lower=-half_pi, q_upper=half_pi)
    prob = CyclicIKProblem(robot=chain, targets=[(0.0, 7.0), (5.0, 0.0)])
    solver = IpoptIKSolver(
        prob, IpoptOptions.for_ikpath(extra={"slack_move": 1.8189894035458565e-12})
    )
    projected = [solver.solve(prob, x0) for x0 in rng.uniform(prob.lower, prob.upper, (20, 6))]
    projected = [r for r in projected if "projected onto the joint limits" in r.message]
    assert projected  # measured 8 of 20, moved by up to 5.7e-12 rad
    for res in projected:
        assert res.limit_violation == 0.0 and "joint limits violated" not in res.message


def test_ipopt_refuses_options_without_constraint_tolerance():
    """The IK-path IPOPT solver needs constr_viol_tol [m]; the message names for_ikpath."""
    with pytest.raises(ParameterError, match="for_ikpath"):
        IpoptIKSolver(example_problem("A"), IpoptOptions(max_iter=10))
    with pytest.raises(ParameterError, match="max_iter >= 1"):
        IpoptIKSolver(example_problem("A"), IpoptOptions.for_ikpath(max_iter=0))
