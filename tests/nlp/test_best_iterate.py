"""A failed trajectory solve returns its best iterate, ranked as documented, not its last."""

from __future__ import annotations

import numpy as np
import pytest

from youbot_opt import TrajOptSolver, study1_problem
from youbot_opt.nlp.best_iterate import Iterate, better
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.trajopt.result import SolveStatus


def _it(violation: float, objective: float) -> Iterate:
    z = np.zeros(1)
    return Iterate(z, z, z, objective, violation, 0)


def test_ranking_prefers_feasible_then_objective_then_violation() -> None:
    """Feasible beats infeasible; then the lower f among feasible, the smaller violation else."""
    tol = 1e-6
    assert better(_it(1e-7, 9.0), _it(1e-3, 1.0), tol)  # feasible first, whatever f
    assert not better(_it(1e-3, 1.0), _it(1e-7, 9.0), tol)
    assert better(_it(1e-7, 8.0), _it(0.0, 9.0), tol)  # both feasible: lower objective
    assert better(_it(1e-3, 20.0), _it(1e-2, 1.0), tol)  # both infeasible: smaller violation
    assert better(_it(1.0, 1.0), None, tol)


@pytest.mark.parametrize("max_iter", [5, 12])
def test_failed_solve_returns_the_least_infeasible_iterate(max_iter: int) -> None:
    """At the iteration cap the result is the iterate with IPOPT's smallest inf_pr, not the last."""
    solver = TrajOptSolver(study1_problem(50), "trapezoidal", IpoptOptions(max_iter=max_iter))
    result = solver.solve(beta=0.5)
    assert result.status is SolveStatus.MAX_ITERATIONS
    # IPOPT's own per-iteration primal infeasibility (unscaled max-norm of the
    # constraint violation), an independent measure of every iterate. No iterate
    # is feasible this early, so the best is the least infeasible one.
    stats = solver._cold({}).stats()  # the youBot keeps IPOPT's own bound relaxation
    inf_pr = np.asarray(stats["iterations"]["inf_pr"])
    assert inf_pr.min() > result.feasibility_tol
    assert inf_pr.argmin() != len(inf_pr) - 1  # the last iterate is not the best here
    # Our violation also counts bound excess, which IPOPT keeps below 1e-8
    # (bound_relax_factor); the two measures agree to that.
    assert result.max_violation == pytest.approx(inf_pr.min(), abs=1e-8)
    assert result.max_violation < inf_pr[-1]
    assert f"best iterate, {inf_pr.argmin()} of {len(inf_pr) - 1}" in result.message
    assert result.trajectory is not None  # a usable (infeasible) plan comes back


def test_converged_solve_keeps_ipopts_final_iterate() -> None:
    """A solved problem returns IPOPT's KKT point (no best-iterate substitution)."""
    result = TrajOptSolver(study1_problem(50), "trapezoidal").solve(beta=0.5)
    assert result.status is SolveStatus.SOLVED
    assert "best iterate" not in result.message
    assert result.objective == pytest.approx(8.269796, abs=5e-7)  # documented base case


@pytest.mark.parametrize("method", ["ipopt", "al"])
def test_failed_ik_path_returns_the_least_violating_iterate(method: str) -> None:
    """Stopped early on example A, both IK methods return their least-violating iterate."""
    from youbot_opt.ikpath import ALOptions, SolveStatus, example_problem, solve
    from youbot_opt.ikpath import IpoptOptions as IKIpoptOptions

    options = (
        IKIpoptOptions.for_ikpath(max_iter=4)
        if method == "ipopt"
        else ALOptions(max_outer_iterations=2)
    )
    problem = example_problem("A")
    result = solve(problem, method=method, options=options)
    assert result.status is SolveStatus.MAX_ITERATIONS
    # The history keeps every iterate's max |c| (IPOPT: each iteration; AL: each outer
    # one); none meets the 1e-10 m tolerance this early, so the best is the least violating.
    violations = np.array([h.violation for h in result.history])
    assert violations.min() > 1e-6 and violations.argmin() != len(violations) - 1
    returned = float(np.max(np.abs(problem.constraints(result.configurations.ravel()))))
    # IPOPT's iterates are projected onto the (here absent) limits: identical; the
    # recorded violation and Pinocchio's recomputation differ only by rounding.
    assert returned == pytest.approx(violations.min(), rel=1e-12, abs=1e-12)
    assert "returned the best iterate" in result.message


class _Buffers:
    """An iterate laid out as CasADi hands it to ``eval_buffer`` (one buffer per output)."""

    def __init__(self, nx: int, ng: int) -> None:
        self.arrays = {"x": np.zeros(nx), "f": np.zeros(1), "g": np.zeros(ng)}
        self.arrays.update(lam_x=np.zeros(nx), lam_g=np.zeros(ng))
        self.flag = np.ones(1)

    def feed(self, recorder, x, f, g, lam=0.0) -> None:  # type: ignore[no-untyped-def]
        a = self.arrays
        a["x"][:], a["f"][:], a["g"][:] = x, f, g
        a["lam_x"][:], a["lam_g"][:] = lam, -lam
        # lam_p is not provided by IPOPT: CasADi passes None for it
        args = [memoryview(a[k]) for k in ("x", "f", "g", "lam_x", "lam_g")] + [None]
        assert recorder.eval_buffer(args, [memoryview(self.flag)]) == 0
        assert self.flag[0] == 0.0  # never asks IPOPT to stop


def test_recorder_ranks_in_place_and_keeps_copies() -> None:
    """The recorder keeps the best iterate by the documented ranking, as its own copy.

    CasADi reuses its buffers between iterations, so the best iterate must be
    copied when it is found; non-finite iterates are counted but never kept.
    """
    from youbot_opt.nlp.best_iterate import BestIterateRecorder

    nx, ng, tol = 2, 1, 1e-6
    recorder = BestIterateRecorder("test_recorder", nx, ng, 1)
    lbx, ubx = np.array([-1.0, -np.inf]), np.array([1.0, np.inf])  # x[1] unbounded
    recorder.reset((lbx, ubx, np.zeros(ng), np.zeros(ng)), tol)
    buffers = _Buffers(nx, ng)
    buffers.feed(recorder, [0.0, 0.0], 5.0, 1e-2, lam=1.0)  # infeasible by 1e-2
    buffers.feed(recorder, [2.0, 0.0], 1.0, 0.0, lam=2.0)  # bound excess 1.0: worse
    assert recorder.best is not None and recorder.best.iteration == 0
    buffers.feed(recorder, [0.5, 0.5], 4.0, 1e-8, lam=3.0)  # feasible: best
    buffers.feed(recorder, [np.nan, 0.0], 0.0, 0.0, lam=4.0)  # not finite: skipped
    buffers.feed(recorder, [0.1, 0.1], np.inf, 0.0, lam=5.0)  # objective not finite: skipped
    buffers.feed(recorder, [0.2, np.inf], 1.0, 0.0, lam=6.0)  # inf where unbounded: skipped
    buffers.feed(recorder, [0.2, 0.2], 1.0, np.inf, lam=7.0)  # g not finite: skipped
    buffers.feed(recorder, [0.2, 0.2], 4.5, 0.0, lam=8.0)  # feasible, higher f: worse
    best = recorder.best
    assert recorder.count == 8
    assert best.iteration == 2 and best.objective == 4.0 and best.violation == 1e-8
    # The buffers now hold iterate 7; the kept arrays are those of iterate 2.
    np.testing.assert_array_equal(best.x, [0.5, 0.5])
    np.testing.assert_array_equal(best.lam_x, [3.0, 3.0])
    np.testing.assert_array_equal(best.lam_g, [-3.0])
    assert not np.shares_memory(best.x, buffers.arrays["x"])
    recorder.reset((lbx, ubx, np.zeros(ng), np.zeros(ng)), tol)
    assert recorder.best is None and recorder.count == 0


def test_recorder_matches_the_reference_ranking_and_keeps_earlier_runs() -> None:
    """On random iterates the recorder keeps exactly :func:`best_of`'s choice, run after run.

    The recorder skips the violation of an iterate that cannot beat a feasible
    best and writes later bests of a run into arrays it owns; neither may change
    which iterate is kept (the reference ranks every iterate in full), and a
    new run must not overwrite the best of the previous one.
    """
    from youbot_opt.nlp.best_iterate import BestIterateRecorder, Iterate, best_of, violation_of

    rng = np.random.default_rng(3)
    nx, ng, tol = 4, 3, 1e-3
    lbx, ubx = np.array([-1.0, -1.0, -np.inf, 0.0]), np.array([1.0, np.inf, 2.0, 0.0])
    bounds = (lbx, ubx, np.array([0.0, -1.0, -np.inf]), np.array([0.0, 1.0, 0.5]))
    recorder = BestIterateRecorder("test_reference", nx, ng, 1)
    buffers = _Buffers(nx, ng)
    kept = []
    for _ in range(3):
        recorder.reset(bounds, tol)
        seen = []
        for k in range(40):
            # shrinking noise: iterates drift from infeasible to feasible, as IPOPT's do
            scale = 2.0 * 0.8**k
            x, g = rng.normal(scale=scale, size=nx), rng.normal(scale=scale, size=ng)
            f = float(rng.normal(loc=5.0 - 0.1 * k))
            buffers.feed(recorder, x, f, g, lam=float(k))
            seen.append(
                Iterate(x, np.full(nx, k), np.full(ng, -k), f, violation_of(x, g, bounds), k)
            )
        reference = best_of(seen[0], seen[1:], tol)
        best = recorder.best
        assert best is not None and best.iteration == reference.iteration
        assert best.objective == reference.objective and best.violation == reference.violation
        np.testing.assert_array_equal(best.x, reference.x)
        np.testing.assert_array_equal(best.lam_x, reference.lam_x)
        kept.append((best, best.x.copy()))
    for best, x in kept:  # later runs left each earlier best as it was
        np.testing.assert_array_equal(best.x, x)


def test_violation_of_is_not_finite_for_a_non_finite_entry() -> None:
    """A NaN in x or g gives a NaN violation whatever its position (not a finite max)."""
    from youbot_opt.nlp.best_iterate import violation_of

    bounds = (np.full(2, -1.0), np.full(2, 1.0), np.zeros(1), np.zeros(1))
    assert violation_of(np.array([0.0, 3.0]), np.array([0.5]), bounds) == 2.0
    assert np.isnan(violation_of(np.array([0.0, np.nan]), np.array([0.5]), bounds))
    assert np.isnan(violation_of(np.array([0.0, 0.0]), np.array([np.nan]), bounds))
