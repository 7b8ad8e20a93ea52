"""keep_results=False trajectory sweeps answer from their tally, equal to keep_results=True.

The reference is the same sweep with ``keep_results=True``: once solved fresh,
and once over the very same output folder (a ``keep_results=False`` rerun
resumes every start from it, so every figure, wall times included, is the
stored one and must be equal, not close). The 12-knot study-1 problem has three
optima, two of them 1e-13 apart in objective but far apart as trajectories.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from _migrate import REFUSAL, migrate
from youbot_opt.exceptions import ParameterError, ResultFileError
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.bound_scaling import bound_scaling_study
from youbot_opt.trajopt.multistart import MultistartResult, StoredStarts, run_multistart
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.sweep_store import sweep_params

N_STARTS, SEED = 10, 3  # + the straight line: 11 starts, 3 optima, one start made to fail


@pytest.fixture(scope="module")
def solver12() -> TrajOptSolver:
    """The 12-knot study-1 solver."""
    return TrajOptSolver(study1_problem(12))


@pytest.fixture
def one_start_fails(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Start 4's guess raises (in this process: the sweeps below run serially)."""
    import youbot_opt.trajopt.spline_guess as sg
    from youbot_opt.trajopt.multistart import start_seeds

    real, bad = sg.random_spline_guess, start_seeds(SEED, N_STARTS)[4]

    def flaky(robot, start, goal, n_knots, *, seed, **kw):  # type: ignore[no-untyped-def]
        if seed == bad:
            raise RuntimeError("guess exploded")
        return real(robot, start, goal, n_knots, seed=seed, **kw)

    monkeypatch.setattr(sg, "random_spline_guess", flaky)
    yield


def _run(solver: TrajOptSolver, out: Path, keep: bool) -> MultistartResult:
    sweep = SweepOptions(executor="serial", out=out, keep_results=keep)
    return run_multistart(solver, N_STARTS, seed=SEED, include_straight=True, sweep=sweep)


def _optima(ms: MultistartResult) -> list[tuple[Any, ...]]:
    return [
        (o.objective, o.count, [m.index for m in o.members], o.objective_spread, o.best.key)
        for o in ms.distinct_optima()
    ]


def _untimed(summary: dict[str, Any]) -> dict[str, Any]:
    """A summary without what differs between two fresh runs: wall times, resumed count."""
    drop = {"wall_time_s", "resumed", "solve_time_s", "guess_time_s"}

    def clean(x: Any) -> Any:  # noqa: ANN401 - a JSON value
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items() if k not in drop}
        return [clean(v) for v in x] if isinstance(x, list) else x

    return clean(summary)  # type: ignore[no-any-return]


def test_lean_result_equals_the_full_one_and_reads_no_start(
    solver12: TrajOptSolver, one_start_fails: None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Best, counts, optima (members, counts) and summary equal keep_results=True; no start read."""
    full = _run(solver12, tmp_path / "full", True)
    fresh = _run(solver12, tmp_path / "lean", False)
    again = _run(solver12, tmp_path / "full", False)  # the full run's folder, resumed lean
    assert isinstance(fresh.starts, StoredStarts) and again.resumed == full.n_starts == 11
    counts = full.status_counts()
    assert counts["error"] == 1 and sum(counts.values()) == 11  # the injected failure
    assert len(full.distinct_optima()) == 3
    # The counts the clustering gave before its tolerances were named obj_tol / dist_tol
    # (objective_tol / traj_tol then), at the defaults and two other pairs.
    for tols, before in (
        ((1e-5, 1e-2), [1, 4, 5]),
        ((1e-3, 1e-1), [1, 4, 5]),
        ((0.1, 10.0), [1, 9]),
    ):
        assert [o.count for o in full.distinct_optima(*tols)] == before
        assert [o.count for o in full.distinct_optima(obj_tol=tols[0], dist_tol=tols[1])] == before
    for lean in (fresh, again):
        assert lean.tally is not None and full.tally is None
        assert lean.status_counts() == counts
        assert (lean.n_converged, lean.success_rate) == (full.n_converged, full.success_rate)
        assert [s.key for s in lean.converged] == [s.key for s in full.converged]
        assert len(lean.converged) == full.n_converged
        assert lean.converged[-1].key == full.converged[-1].key
        assert lean.best is not None and full.best is not None
        assert (lean.best.key, lean.best.objective) == (full.best.key, full.best.objective)
        np.testing.assert_array_equal(lean.best.result.trajectory.q, full.best.result.trajectory.q)
        assert _optima(lean) == _optima(full)
        assert lean.distinct_optima(1e-3, 1e-1) != () and [
            o.count for o in lean.distinct_optima(1e-3, 1e-1)
        ] == [o.count for o in full.distinct_optima(1e-3, 1e-1)]  # other tolerances: re-clustered
        for starts in (False, True):
            want = _untimed(full.summary(starts=starts))
            assert _untimed(lean.summary(starts=starts)) == want
    # the same folder: every figure is the stored one, so the summaries are equal outright
    assert {**again.summary(starts=True), "wall_time_s": 0, "resumed": 0} == {
        **full.summary(),
        "wall_time_s": 0,
        "resumed": 0,
    }
    assert "starts" not in fresh.summary() and "starts" in full.summary()  # default: held or not

    # The accessors answer from the tally: reading any start now fails the test.
    def no_read(self: StoredStarts, i: int) -> None:
        raise AssertionError(f"start {i} was read")

    monkeypatch.setattr(StoredStarts, "__getitem__", no_read)
    for lean in (fresh, again):
        assert lean.best is not None and lean.best.result is not None
        assert lean.n_converged == full.n_converged and len(lean.converged) == full.n_converged
        lean.summary(starts=False)
        assert [(o.count, o.objective_spread) for o in lean.distinct_optima()] == [
            (o.count, o.objective_spread) for o in full.distinct_optima()
        ]


def test_optimum_members_are_read_on_demand(solver12: TrajOptSolver, tmp_path: Path) -> None:
    """An optimum of a lean result holds its representative; members are read from the folder."""
    full = _run(solver12, tmp_path / "full", True)
    lean = _run(solver12, tmp_path / "full", False)
    for a, b in zip(full.distinct_optima(), lean.distinct_optima(), strict=True):
        assert isinstance(a.members, tuple) and not isinstance(b.members, tuple)
        assert len(b.members) == b.count == a.count
        assert b.members[0].result is not None  # the representative, kept in full
        assert all(m.result is None for m in b.members[1:])  # the others stay in the folder
        assert [m.key for m in b.members] == [m.key for m in a.members]
        assert [m.key for m in b.members[::-1]] == [m.key for m in a.members[::-1]]
        assert b.seeds == a.seeds and b.summary() == a.summary()


def test_bound_scaling_rows_hold_no_start(solver12: TrajOptSolver, tmp_path: Path) -> None:
    """keep_results=False bound scaling: each row is lean and equal to the full run's row."""

    def run(out: Path, keep: bool):  # type: ignore[no-untyped-def]
        sweep = SweepOptions(executor="serial", out=out, keep_results=keep)
        return bound_scaling_study(solver12, (1.0, 0.9), n_starts=4, seed=1, sweep=sweep)

    full = run(tmp_path / "full", True)
    lean = run(tmp_path / "full", False)  # resumed from the same folder: equal figures
    assert lean.summary() == {**full.summary(), "wall_time_s": lean.wall_time}
    for i, (a, b) in enumerate(zip(full.rows, lean.rows, strict=True)):
        assert isinstance(b.multistart.starts, StoredStarts) and b.multistart.tally is not None
        assert b.multistart.summary(starts=True) == {
            **a.multistart.summary(),
            "wall_time_s": b.multistart.wall_time,
        }
        assert _optima(b.multistart) == _optima(a.multistart)
        keys = [m.key for o in b.multistart.distinct_optima() for m in o.members]
        assert keys and all(k.startswith(f"scale{i:02d}_") for k in keys)  # this scale's only


# ------------------------------------------------------- store identity (robot by content)
def _copied_robot(folder: Path, youbot: RobotModel) -> RobotModel:
    folder.mkdir(parents=True, exist_ok=True)
    assert youbot.urdf_path is not None
    path = folder / youbot.urdf_path.name
    shutil.copyfile(youbot.urdf_path, path)
    return load_model(path)


def _small(robot: RobotModel, out: Path, n: int = 2) -> MultistartResult:
    solver = TrajOptSolver(study1_problem(6, robot=robot))
    return run_multistart(solver, n, seed=0, sweep=SweepOptions(executor="serial", out=out))


def test_store_resumes_after_the_folder_and_the_urdf_move(
    youbot: RobotModel, tmp_path: Path
) -> None:
    """The manifest names the robot by its URDF's SHA-256: moves resume, an edited file does not."""
    robot = _copied_robot(tmp_path / "a", youbot)
    first = _small(robot, tmp_path / "out")
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert "urdf_path" not in manifest["params"]["problem"]
    digest = hashlib.sha256((tmp_path / "a" / youbot.urdf_path.name).read_bytes()).hexdigest()
    assert manifest["params"]["problem"]["urdf_sha256"] == digest
    (tmp_path / "out").rename(tmp_path / "moved")  # the output folder moves ...
    shutil.rmtree(tmp_path / "a")
    moved = _copied_robot(tmp_path / "b", youbot)  # ... and the URDF too
    again = _small(moved, tmp_path / "moved")
    assert again.resumed == 2 and again.best.objective == first.best.objective
    edited = tmp_path / "b" / youbot.urdf_path.name
    edited.write_text(edited.read_text() + "\n<!-- edited -->\n")
    with pytest.raises(ParameterError, match="urdf_sha256"):
        _small(load_model(edited), tmp_path / "moved")


def _old_params(solver: TrajOptSolver) -> dict[str, Any]:
    """What sweep_params wrote before the robot was identified by content (0.1.0)."""
    new = sweep_params(solver)
    problem = {k: v for k, v in new["problem"].items() if k != "urdf_sha256"}
    return {**new, "problem": {**problem, "urdf_path": str(solver.problem.robot.urdf_path)}}


def test_old_stores_with_a_urdf_path_are_refused_then_migrated(
    youbot: RobotModel, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A store naming its URDF by path (0.1.0) is refused; migrated, it resumes.

    Migrated with the recorded file there: the same robot at the same path or a
    moved copy resumes; another file at that path is another robot. With the
    recorded file gone, the migration asks for ``--urdf``.
    """
    import youbot_opt.trajopt.multistart as ms_module

    robot = _copied_robot(tmp_path / "a", youbot)
    with monkeypatch.context() as m:
        m.setattr(ms_module, "sweep_params", _old_params)
        first = _small(robot, tmp_path / "old")
    stored = json.loads((tmp_path / "old" / "manifest.json").read_text())["params"]["problem"]
    assert stored["urdf_path"] == str(tmp_path / "a" / youbot.urdf_path.name)
    with pytest.raises(ResultFileError, match=REFUSAL):
        _small(robot, tmp_path / "old")
    for copy in ("other", "gone"):
        shutil.copytree(tmp_path / "old", tmp_path / copy)
    assert migrate(tmp_path / "old").returncode == 0
    assert _small(robot, tmp_path / "old").resumed == 2  # the same path
    moved = _copied_robot(tmp_path / "b", youbot)  # the old file still there, same content
    assert _small(moved, tmp_path / "old").resumed == 2
    (tmp_path / "a" / youbot.urdf_path.name).write_text("<robot name='other'/>")
    assert migrate(tmp_path / "other").returncode == 0  # the old path now holds another file
    with pytest.raises(ParameterError, match="urdf"):
        _small(moved, tmp_path / "other")
    shutil.rmtree(tmp_path / "a")  # gone: the migration is told the robot's URDF
    gone = migrate(tmp_path / "gone")
    assert gone.returncode == 1 and "pass --urdf" in gone.stderr
    assert migrate("--urdf", moved.urdf_path, tmp_path / "gone").returncode == 0
    again = _small(moved, tmp_path / "gone")
    assert again.resumed == 2 and again.best.objective == first.best.objective


def test_the_74bfa23_store_resumes_where_its_checkout_is_gone(tmp_path: Path) -> None:
    """The real old store (URDF path of a checkout that no longer exists), migrated, resumes."""
    old = Path(__file__).resolve().parents[1] / "fixtures" / "files_74bfa23" / "traj_multistart"
    shutil.copytree(old, tmp_path / "ms")
    assert (
        "/tmp/old74/urdf/youbot_arm_planar.urdf" in (tmp_path / "ms" / "manifest.json").read_text()
    )
    solver = TrajOptSolver(study1_problem(12))
    assert solver.problem.robot.urdf_path is not None
    done = migrate("--urdf", solver.problem.robot.urdf_path, tmp_path / "ms")
    assert done.returncode == 0, done.stderr
    sweep = SweepOptions(executor="serial", out=tmp_path / "ms")
    result = run_multistart(solver, n_starts=2, beta=0.5, seed=3, sweep=sweep)
    assert result.resumed == 2
    assert result.best is not None and result.best.objective == 8.144733342334671  # as stored
