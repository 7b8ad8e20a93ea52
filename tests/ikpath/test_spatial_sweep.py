"""Spatial multistart on the sweep engine (issue 14): store and resume, retry, starts, pool."""

from __future__ import annotations

import json

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.dls import dls_ik
from youbot_opt.ikpath.methods.ipopt import IpoptIKSolver3D
from youbot_opt.ikpath.multistart import run_multistart
from youbot_opt.ikpath.starts import make_starts_3d
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.resume import ShardReport


def test_starts_are_seeded_prefix_stable_and_coherent_ones_meet_their_targets(ur5_reachable):
    p = ur5_reachable
    five = make_starts_3d(p, 5, seed=4, kind="coherent")
    np.testing.assert_array_equal(make_starts_3d(p, 3, seed=4, kind="coherent"), five[:3])
    assert not np.array_equal(make_starts_3d(p, 5, seed=5, kind="coherent"), five)
    # Coherent: every configuration is a DLS solution of its target from the previous one
    # (position errors at the DLS tolerance 1e-12 m; 1e-9 leaves room for rounding).
    for x in five:
        pos, _ = p.errors(x)
        assert np.max(pos) < 1e-9
    # Random: every angle uniform in [max(l, -pi), min(u, pi)], nothing solved.
    rand = make_starts_3d(p, 4, seed=4, kind="random")
    assert np.all(np.abs(rand[1:]) <= np.pi) and np.all(rand >= p.lower) and np.all(rand <= p.upper)
    assert min(np.max(p.errors(x)[0]) for x in rand[1:]) > 1e-3
    np.testing.assert_array_equal(rand[0], five[0])  # start 0 is the greedy path for every kind
    theta, met = dls_ik(p, 0, np.zeros(p.n_joints))
    np.testing.assert_array_equal(five[0][: p.n_joints], theta)
    assert met
    with pytest.raises(
        ParameterError, match="unknown start kind 'feasible'; choose one of mixed, coherent, random"
    ):
        make_starts_3d(p, 2, seed=0, kind="feasible")


def test_shards_save_their_starts_and_reruns_resume_without_solving(ur5_reachable, tmp_path):
    def run(**kw):
        sweep = SweepOptions(executor="serial", out=tmp_path, **kw)
        return run_multistart(ur5_reachable, method="ipopt", n_starts=4, sweep=sweep)

    report = run(shard=(1, 2))  # share 1 of 2: starts 0 and 2, then a report (not a raise)
    assert isinstance(report, ShardReport) and report.shard == (1, 2)
    assert (report.ran, report.finished, report.total, report.left) == (2, 2, 4, 2)
    assert report.directory == tmp_path
    assert str(report).startswith("shard 1/2: ran 2 item(s); 2 of 4 items are finished in ")
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["kind"] == "spatial_ikpath_multistart"
    assert manifest["params"]["problem"]["joint_names"] == list(ur5_reachable.joint_names)
    calls = []
    collected = run(progress=lambda *a: calls.append(a))
    assert collected.resumed == 2 and collected.attempts == (1, 1, 1, 1)
    assert collected.output == tmp_path
    # the two loaded starts in one call, then one call per solved start
    assert [c[:2] for c in calls] == [(2, 4), (3, 4), (4, 4)]
    assert calls[-1][2] == min(r.objective for r in collected.results if r.success)
    again = run()
    assert again.resumed == 4
    fresh = run_multistart(ur5_reachable, method="ipopt", n_starts=4)
    for a, b, c in zip(fresh.results, collected.results, again.results, strict=True):
        assert a.status is b.status is c.status
        # Loaded starts keep the stored angles; every start is the same IPOPT from the
        # same start in this process, so the same iterates.
        np.testing.assert_array_equal(a.configurations, b.configurations)
        np.testing.assert_array_equal(b.configurations, c.configurations)
    with pytest.raises(ParameterError):  # another sweep in the same folder
        run_multistart(
            ur5_reachable, method="ipopt", n_starts=4, seed=1, sweep=SweepOptions(out=tmp_path)
        )


def test_a_raising_start_is_retried_then_crashed_and_stays_crashed_on_resume(
    ur5_reachable, tmp_path, monkeypatch
):
    real = IpoptIKSolver3D.solve
    x_first = make_starts_3d(ur5_reachable, 1, seed=0)[0]
    calls = []

    def flaky(self, x0=None, **kw):
        if np.array_equal(np.asarray(x0), x_first):
            calls.append(1)
            raise RuntimeError("boom")
        return real(self, x0, **kw)

    monkeypatch.setattr(IpoptIKSolver3D, "solve", flaky)
    sweep = SweepOptions(executor="serial", out=tmp_path)
    res = run_multistart(ur5_reachable, method="ipopt", n_starts=3, sweep=sweep)
    assert len(calls) == 2 and res.attempts == (2, 1, 1)
    assert res.results[0].status is SolveStatus.CRASHED
    assert res.results[0].message.startswith("RuntimeError: boom")
    assert res.status_counts()["crashed"] == 1 and res.best_index != 0
    again = run_multistart(ur5_reachable, method="ipopt", n_starts=3, sweep=sweep)
    assert len(calls) == 2 and again.resumed == 3  # out of attempts: not tried again
    assert again.results[0].status is SolveStatus.CRASHED
    assert again.results[0].message.startswith("RuntimeError: boom")


def test_process_pool_equals_serial(ur5_reachable):
    serial = run_multistart(ur5_reachable, method="ipopt", n_starts=4)
    pooled = run_multistart(
        ur5_reachable, method="ipopt", n_starts=4, sweep=SweepOptions(executor="process", workers=2)
    )
    assert serial.n_workers == 1 and pooled.n_workers == 2
    # The same IPOPT from the same starts, in worker processes: equal to rounding (1e-10 rad).
    for a, b in zip(serial.results, pooled.results, strict=True):
        assert a.status is b.status
        np.testing.assert_allclose(a.configurations, b.configurations, atol=1e-10, rtol=0)


def test_a_planar_robot_multistart_starts_where_the_planar_one_does_and_finds_its_optimum(
    ur5_reachable,
):
    """#25 item 4: the documented planar example (lengths 3 2 2, limits, targets (4, 1),
    (3, -2)) as a RobotModel: the 3-D multistart's default starts are the planar
    feasible ones (same draws, 1e-9 rad) and its best E is the planar multistart's (1e-8)."""
    from youbot_opt.ikpath.multistart import run_multistart
    from youbot_opt.ikpath.problem import CyclicIKProblem
    from youbot_opt.robot.planar import PlanarChain

    chain = PlanarChain(lengths=[3, 2, 2], q_lower=[-1, -2, -2], q_upper=[1, 2, 2])
    targets = [(4.0, 1.0), (3.0, -2.0)]
    planar = CyclicIKProblem(robot=chain, targets=targets)
    robot = CyclicIKProblem(robot=chain.robot(), targets=targets)
    assert robot.chain is not None and not isinstance(robot.robot, PlanarChain)
    ref = run_multistart(planar, n_starts=20, seed=0)
    got = run_multistart(robot, n_starts=20, seed=0, planar=False)  # the general methods
    assert got.start_kind == "feasible"
    np.testing.assert_allclose(
        [r.start.ravel() for r in got.results], [r.start.ravel() for r in ref.results], atol=1e-9
    )
    assert ref.best.success and got.best.success
    assert abs(got.best.objective - ref.best.objective) <= 1e-8
    with pytest.raises(ParameterError, match="needs a planar robot"):
        run_multistart(ur5_reachable, n_starts=2, starts="feasible")
