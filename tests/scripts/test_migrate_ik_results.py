"""``scripts/migrate_0_1_0.py`` on IK-path result files and on stores holding IK payloads."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from _migrate import REFUSAL, migrate
from youbot_opt._files import json_digest
from youbot_opt.exceptions import ResultFileError
from youbot_opt.ikpath.examples import example_problem
from youbot_opt.ikpath.io import SCHEMA, SCHEMA_VERSION, load_result, save_result
from youbot_opt.ikpath.multistart import run_multistart
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import build_result
from youbot_opt.ikpath.targets import Target
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.load import load_model
from youbot_opt.robot.source import RobotSource
from youbot_opt.sweeps.options import SweepOptions


def _as_written_by_0_1_0(path: Path, schema: str = SCHEMA) -> None:
    """Rewrite a current IK-path file as 0.1.0 wrote it: schema 1, the IKStatus value."""
    doc = json.loads(path.read_text())
    body = doc["result"]
    body["status"] = {"solved": "success"}.get(body["status"], body["status"])
    if "chain" in body:
        del body["constraint_tol"]
    doc.update(schema=schema, schema_version=1, sha256=json_digest(body))
    path.write_text(json.dumps(doc, indent=1))


def test_a_3d_result_of_0_1_0_is_refused_then_carried(tmp_path: Path) -> None:
    """A UR5 result in 0.1.0's 3-D schema: refused naming the script; carried, loads as before."""
    robot = load_model("ur5")
    base = CyclicIKProblem(
        robot=robot.model,
        frame=robot.tip_frame,
        targets=(Target(position=(0, 0, 0)), Target(position=(0, 0, 0))),
    )
    q = np.random.default_rng(5).uniform(-2, 2, (3, base.n_joints))
    problem = base.with_targets(
        tuple(Target(position=base.placement(theta).translation) for theta in q)
    )
    result = build_result(
        problem,
        method="ipopt",
        status=SolveStatus.SOLVED,
        x=q.ravel(),
        multipliers=np.zeros(problem.n_constraints),
        iterations=3,
        wall_time=0.1,
        message="Solve_Succeeded",
        start=q.ravel(),
    )
    path = save_result(result, tmp_path / "r.json", RobotSource.of(robot))
    _as_written_by_0_1_0(path, schema="youbot_opt.spatial_ikpath_result")
    old = path.read_bytes()
    with pytest.raises(ResultFileError, match=REFUSAL + f"{path}`"):
        load_result(path)
    done = migrate(path)
    assert done.returncode == 0, done.stderr
    assert f"{path}: IK-path result of 0.1.0 carried forward" in done.stdout
    assert Path(str(path) + ".0.1.0.bak").read_bytes() == old
    doc = json.loads(path.read_text())
    assert (doc["schema"], doc["schema_version"]) == (SCHEMA, SCHEMA_VERSION)
    back = load_result(path)
    assert back.status is SolveStatus.SOLVED and back.objective == result.objective
    np.testing.assert_array_equal(back.configurations, result.configurations)


def test_a_current_ik_result_is_left_alone(tmp_path: Path) -> None:
    """A file the package wrote is current: the script says so and changes nothing."""
    result = build_result(
        example_problem("A"),
        method="al",
        status=SolveStatus.MAX_ITERATIONS,
        x=np.zeros(15),
        multipliers=np.zeros(10),
        iterations=1,
        wall_time=0.0,
        message="",
        start=np.zeros(15),
        constraint_tol=1e-10,
    )
    path = save_result(result, tmp_path / "r.json")
    data = path.read_bytes()
    done = migrate(path)
    assert done.returncode == 0, done.stderr
    assert "already current (IK-path result)" in done.stdout
    assert path.read_bytes() == data and sorted(tmp_path.iterdir()) == [path]


def test_a_current_store_with_old_ik_payloads_is_carried(tmp_path: Path) -> None:
    """A store of today's layout with IK payloads of schema 1: not current; carried, resumed."""
    out = tmp_path / "run"

    def run():
        sweep = SweepOptions(executor="serial", out=out)
        return run_multistart(example_problem("A"), method="ipopt", n_starts=2, seed=1, sweep=sweep)

    first = run()
    payloads = sorted((out / "items").rglob("*.ikpath"))
    assert len(payloads) == 2
    for payload in payloads:
        _as_written_by_0_1_0(payload)
    with pytest.raises(ResultFileError, match=REFUSAL):
        load_result(payloads[0])
    done = migrate(out)
    assert done.returncode == 0, done.stderr
    assert "sweep store of 0.1.0 carried forward" in done.stdout
    again = run()
    assert again.resumed == 2
    assert [r.objective for r in again.results] == [r.objective for r in first.results]
    assert [r.status for r in again.results] == [r.status for r in first.results]
    assert migrate(out).stdout.count("already current") == 1
