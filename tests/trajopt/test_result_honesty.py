"""No silent wrong answers: forced failures and corrupted results are never a success.

Each test forces one way a solve can go wrong (iteration cap, CPU-time cap,
torque bounds that cannot hold the arm up, a NaN in the robot file, a result
edited after the fact) and checks that the status says so, with a message,
and that ``raise_for_status`` raises :class:`SolveFailed` carrying the result.
"""

from __future__ import annotations

import dataclasses
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.exceptions import InvalidModelError, SolveFailed
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.robot.load import load_model
from youbot_opt.trajopt.check import check_result, checked
from youbot_opt.trajopt.result import SolveStatus, TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver

URDF = Path(__file__).resolve().parents[2] / "urdf" / "youbot_arm_planar.urdf"


@pytest.fixture(scope="module")
def youbot():
    """The planar youBot with the study code's joint damping."""
    return load_model("youbot", damping=0.1)


@pytest.fixture(scope="module")
def solved(youbot) -> TrajOptResult:
    """A converged 10-knot study-1 solve (trapezoidal)."""
    result = TrajOptSolver(study1_problem(10, robot=youbot)).solve(beta=0.5)
    return result.raise_for_status()


def _assert_failed(result: TrajOptResult, status: SolveStatus) -> None:
    assert result.status is status, (result.status, result.message)
    assert not result.success and result.message
    assert check_result(result).status is status
    with pytest.raises(SolveFailed, match=status.value) as info:
        result.raise_for_status()
    assert info.value.result is result


# ------------------------------------------------------------------ forced solver failures
def test_converged_solve_passes_the_independent_check(solved) -> None:
    """A converged solve: defects by pin.aba and bounds within feasibility_tol."""
    check = check_result(solved)
    assert check.passed and check.finite and check.status is SolveStatus.SOLVED
    # pin.aba and the NLP's CasADi dynamics agree to rounding; IPOPT's defects are
    # below its tolerance (1e-8), far inside feasibility_tol (1e-6).
    assert check.defect < 1e-8
    assert check.boundary_violation < 1e-8
    assert check.bound_violation <= solved.feasibility_tol


@pytest.mark.parametrize("max_iter", [0, 1])
def test_iteration_cap_is_a_failure_with_the_last_iterate(youbot, max_iter) -> None:
    """max_iter = 0 or 1: status max_iterations, the (finite) iterate is returned."""
    problem = study1_problem(10, robot=youbot)
    result = TrajOptSolver(problem, options=IpoptOptions(max_iter=max_iter)).solve()
    _assert_failed(result, SolveStatus.MAX_ITERATIONS)
    assert result.iterations == max_iter
    assert result.variables["q"].shape == (10, 3) and np.all(np.isfinite(result.variables["q"]))
    assert result.trajectory is not None


def test_cpu_time_cap_is_a_failure(youbot) -> None:
    """max_cpu_time = 1 ms (below one iteration's cost): status max_time."""
    problem = study1_problem(30, robot=youbot)
    result = TrajOptSolver(problem, options=IpoptOptions(max_cpu_time=1e-3)).solve(beta=0.2)
    _assert_failed(result, SolveStatus.MAX_TIME)


def test_wall_time_cap_through_extra_is_a_failure(youbot) -> None:
    """IPOPT's max_wall_time (passed through ``extra``) maps to max_time as well."""
    options = IpoptOptions(extra={"max_wall_time": 1e-3})
    result = TrajOptSolver(study1_problem(30, robot=youbot), options=options).solve()
    _assert_failed(result, SolveStatus.MAX_TIME)


def test_torque_bounds_below_gravity_are_infeasible(youbot) -> None:
    """Torque bounds at 5 % of the data sheet cannot hold the arm at the start: infeasible."""
    problem = study1_problem(10, robot=youbot, scaled_bounds=("torque",))
    result = TrajOptSolver(problem).solve(bound_scale=0.05)
    # The gravity torque of joint 2 at the start exceeds 5 % of its limit, so no
    # point satisfies the defects and the bounds together (checked here directly).
    from youbot_opt.dynamics import build_dynamics

    gravity = build_dynamics(youbot).inverse_dynamics(problem.start.q, np.zeros(3), np.zeros(3))
    assert np.any(np.abs(np.asarray(gravity).ravel()) > problem.bounds(0.05).tau_upper)
    _assert_failed(result, SolveStatus.INFEASIBLE)


def test_nan_inertia_is_refused_by_the_loader(tmp_path) -> None:
    """A NaN inertia (which Pinocchio would drop silently) never reaches a solver."""
    text = URDF.read_text()
    assert 'ixx="0.0031145"' in text
    path = tmp_path / "youbot_nan.urdf"
    path.write_text(text.replace('ixx="0.0031145"', 'ixx="nan"', 1))
    for mesh_dir in ("meshes",):
        if (URDF.parent / mesh_dir).is_dir():
            shutil.copytree(URDF.parent / mesh_dir, tmp_path / mesh_dir)
    with pytest.raises(InvalidModelError, match="nan"):
        load_model(path)


# ----------------------------------------------------------------------- corrupted results
def _corrupt(result: TrajOptResult, **changes) -> TrajOptResult:
    """A copy with ``changes``, passed through the check the solver and loader apply."""
    return checked(dataclasses.replace(result, **changes))


def _with(result: TrajOptResult, block: str, edit) -> TrajOptResult:
    arr = np.array(result.variables[block])
    edit(arr)
    return _corrupt(result, variables={**result.variables, block: arr})


def test_construction_does_no_work_and_check_reruns(solved) -> None:
    """dataclasses.replace keeps the claimed status; result.check() and checked() refute it."""
    arr = np.array(solved.variables["q"])
    arr[4, 1] = math.nan
    raw = dataclasses.replace(solved, variables={**solved.variables, "q": arr})
    assert raw.status is SolveStatus.SOLVED  # constructing a result runs no check
    assert raw.check().status is SolveStatus.NON_FINITE
    assert check_result(raw) == raw.check()
    assert checked(raw).status is SolveStatus.NON_FINITE
    assert checked(solved) is solved  # a confirmed success is returned unchanged


def test_loaded_dishonest_result_is_downgraded(solved, tmp_path) -> None:
    """A saved success claim with a wrong objective loads as failed (the loader checks)."""
    from youbot_opt.trajopt.io import load_result, save_result

    raw = dataclasses.replace(solved, objective=solved.objective * (1 + 1e-6))
    assert raw.status is SolveStatus.SOLVED
    loaded = load_result(save_result(raw, tmp_path / "dishonest.npz"), robot=solved.problem.robot)
    _assert_failed(loaded, SolveStatus.FAILED)


def test_nan_position_is_non_finite(solved) -> None:
    """q with a NaN (built via dataclasses.replace) is classified non_finite."""
    bad = _with(solved, "q", lambda q: q.__setitem__((4, 1), math.nan))
    _assert_failed(bad, SolveStatus.NON_FINITE)
    assert "q" in bad.message


def test_infinite_objective_is_non_finite(solved) -> None:
    """A non-finite reported figure is a failure even with finite variables."""
    _assert_failed(_corrupt(solved, objective=math.inf), SolveStatus.NON_FINITE)


def test_torque_beyond_its_bound_is_a_constraint_violation(solved) -> None:
    """A knot torque 1e-3 N m past its bound (defects re-checked too): constraint_violation."""
    upper = solved.bounds().tau_upper

    def push(tau):
        tau[5, 0] = upper[0] + 1e-3

    bad = _with(solved, "tau", push)
    _assert_failed(bad, SolveStatus.CONSTRAINT_VIOLATION)
    assert check_result(bad).bound_violation == pytest.approx(1e-3, rel=1e-9)


def test_velocity_off_the_dynamics_is_a_constraint_violation(solved) -> None:
    """A knot velocity moved by 1e-4 rad/s breaks the collocation defects by about that much."""
    bad = _with(solved, "v", lambda v: v.__setitem__((3, 2), v[3, 2] + 1e-4))
    _assert_failed(bad, SolveStatus.CONSTRAINT_VIOLATION)
    # The position defect changes by dt/2 * 1e-4, the velocity defects by the
    # change of a (through the damping and Coriolis terms): at least 1e-4 * dt / 2.
    assert check_result(bad).defect >= 0.5 * solved.dt * 1e-4


def test_wrong_objective_is_inconsistent(solved) -> None:
    """An objective that is not beta T + (1 - beta) W of the variables is a failure."""
    bad = _corrupt(solved, objective=solved.objective * (1 + 1e-6))
    _assert_failed(bad, SolveStatus.FAILED)
    assert "objective" in bad.message


def test_missing_block_is_malformed(solved) -> None:
    """A result without its torque block is a failure, not an exception."""
    variables = {k: v for k, v in solved.variables.items() if k != "tau"}
    _assert_failed(_corrupt(solved, variables=variables), SolveStatus.FAILED)


def test_success_claim_without_convergence_is_withdrawn(solved) -> None:
    """status=SOLVED with IPOPT's return status at the iteration cap becomes max_iterations."""
    stats = dataclasses.replace(solved.stats, solver_status="Maximum_Iterations_Exceeded")
    bad = _corrupt(solved, stats=stats)
    _assert_failed(bad, SolveStatus.MAX_ITERATIONS)


def test_stricter_tolerance_withdraws_success(solved) -> None:
    """feasibility_tol below IPOPT's bound relaxation (1e-8 relative) fails the check."""
    check = check_result(solved, feasibility_tol=1e-15)
    assert check.status is SolveStatus.CONSTRAINT_VIOLATION and "1e-15" in check.message


def test_check_reads_only_the_checked_solution_members(solved) -> None:
    """check_result needs only the CheckedSolution members: a plain record of them gets the
    result's verdict, for the converged result and for a corrupted copy (check.py does not
    know TrajOptResult)."""
    from youbot_opt.trajopt.check import CheckedSolution

    names = [n for n in vars(CheckedSolution) if not n.startswith("_")]
    assert set(names) >= {"problem", "variables", "solver_status", "step_ratios"}

    def record(result: TrajOptResult):
        members = {n: getattr(result, n) for n in names if n != "step_ratios"}
        return type("Record", (), {**members, "step_ratios": lambda self: result.step_ratios()})()

    bad = _with(solved, "v", lambda v: v.__setitem__((3, 2), v[3, 2] + 1e-4))
    for result in (solved, bad):
        assert check_result(record(result)) == result.check()
    assert check_result(record(bad)).status is SolveStatus.CONSTRAINT_VIOLATION
