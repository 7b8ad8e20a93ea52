"""One SolveStatus for both optimisers; the old IK-path values are carried by the migration."""

from __future__ import annotations

import pytest

from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.nlp.status import SolveStatus, status_from_ipopt
from youbot_opt.trajopt.result import SolveStatus as TrajOptSolveStatus


def test_one_enum_for_both_optimisers() -> None:
    """trajopt re-exports it; the IKStatus alias of 0.1.0 is gone."""
    import youbot_opt.ikpath as ikpath
    import youbot_opt.ikpath.result as ikpath_result

    assert TrajOptSolveStatus is SolveStatus
    assert not hasattr(ikpath, "IKStatus") and not hasattr(ikpath_result, "IKStatus")


@pytest.mark.parametrize(
    ("old", "new"),
    [
        ("max_iterations", SolveStatus.MAX_ITERATIONS),
        ("stalled", SolveStatus.STALLED),
        ("infeasible", SolveStatus.INFEASIBLE),
        ("crashed", SolveStatus.CRASHED),
        ("solved", SolveStatus.SOLVED),
        ("constraint_violation", SolveStatus.CONSTRAINT_VIOLATION),
    ],
)
def test_values_of_saved_files_load(old: str, new: SolveStatus) -> None:
    """Files of both optimisers store SolveStatus values."""
    assert SolveStatus(old) is new


@pytest.mark.parametrize("old", ["success", "time_limit", "numerical_error", "check_failed"])
def test_old_ik_values_are_refused(old: str) -> None:
    """The IKStatus values of 0.1.0 files no longer load (scripts/migrate_0_1_0.py carries them)."""
    with pytest.raises(ValueError):
        SolveStatus(old)


def test_old_names_are_gone_and_success() -> None:
    """The IKStatus names of 0.1.0 (SUCCESS, ...) are gone; success only for the two solved ones."""
    for old in ("SUCCESS", "TIME_LIMIT", "NUMERICAL_ERROR", "CHECK_FAILED"):
        assert not hasattr(SolveStatus, old)
    assert len(list(SolveStatus)) == 10
    assert {s for s in SolveStatus if s.success} == {
        SolveStatus.SOLVED,
        SolveStatus.SOLVED_ACCEPTABLE,
    }
    with pytest.raises(ValueError):
        SolveStatus("nonsense")


def test_status_from_ipopt() -> None:
    """IPOPT strings map to statuses; unknown ones to ``otherwise``."""
    assert status_from_ipopt("Solve_Succeeded") is SolveStatus.SOLVED
    assert status_from_ipopt("Maximum_WallTime_Exceeded") is SolveStatus.MAX_TIME
    assert status_from_ipopt("Restoration_Failed") is SolveStatus.FAILED
    got = status_from_ipopt("Restoration_Failed", otherwise=SolveStatus.NON_FINITE)
    assert got is SolveStatus.NON_FINITE


def test_one_ipopt_options_class_serves_both() -> None:
    """Trajectory defaults by default; IK-path defaults from for_ikpath; old dicts unchanged."""
    trajopt = IpoptOptions()
    assert trajopt.tol == 1e-8 and trajopt.constr_viol_tol is None
    assert set(trajopt.to_dict()) == {
        "tol", "max_iter", "max_cpu_time", "print_level", "linear_solver", "hessian",
        "mu_strategy", "extra",
    }  # fmt: skip
    ik = IpoptOptions.for_ikpath(max_wall_time=2.0)
    assert (ik.tol, ik.constr_viol_tol, ik.mu_strategy) == (1e-12, 1e-11, "monotone")
    ipopt = ik.to_casadi(True, solver_settings={"slack_move": 1e-14})["ipopt"]
    assert ipopt["max_wall_time"] == 2.0 and ipopt["constr_viol_tol"] == 1e-11
    assert ipopt["slack_move"] == 1e-14
    over = IpoptOptions.for_ikpath(extra={"slack_move": 1e-12})
    assert (
        over.to_casadi(True, solver_settings={"slack_move": 1e-14})["ipopt"]["slack_move"] == 1e-12
    )
    with pytest.raises(Exception, match="constr_viol_tol"):
        IpoptOptions(constr_viol_tol=-1.0)
