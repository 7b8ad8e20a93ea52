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
    inf_pr = np.asarray(solver._solver.stats()["iterations"]["inf_pr"])
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
