"""Spatial reachability (issue 14, item 3): interval forward kinematics and its certificates."""

from __future__ import annotations

import json
import math

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.cli import main
from youbot_opt.exceptions import ParameterError, UnreachableTarget
from youbot_opt.ikpath.dls import random_theta
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability import Reachability
from youbot_opt.ikpath.reachability.general import (
    check_reachability_3d,
    interval_search,
    joint_box,
)
from youbot_opt.ikpath.reachability.interval import IntervalChain, sin_cos
from youbot_opt.ikpath.reachability.planar import decide_reachability
from youbot_opt.ikpath.solve import solve
from youbot_opt.ikpath.targets import Target
from youbot_opt.robot.load import load_model
from youbot_opt.robot.planar import PlanarChain

_INERTIAL = (  # the loader checks that M(q) is positive definite
    '<inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" '
    'izz="0.1"/></inertial>'
)
_BUDGET = {"max_boxes": 300_000, "max_seconds": 600.0}  # boxes decide, never the clock


def _joint(name, kind, parent, child, xyz, axis, limit=(-2.5, 2.5), rpy="0 0 0"):
    lim = f'<limit lower="{limit[0]}" upper="{limit[1]}" effort="1" velocity="1"/>'
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>{lim}</joint>'
        f'<link name="{child}">{_INERTIAL}</link>'
    )


def _robot(tmp_path, name, joints, tip_xyz):
    parent = joints[-1].split('<child link="')[1].split('"')[0]
    urdf = (
        f'<robot name="{name}"><link name="base"/>{"".join(joints)}'
        f'<joint name="tip_joint" type="fixed"><parent link="{parent}"/><child link="tip"/>'
        f'<origin xyz="{tip_xyz}"/></joint><link name="tip"/></robot>'
    )
    path = tmp_path / f"{name}.urdf"
    path.write_text(urdf)
    return load_model(path, tip_frame="tip").model


def _planar(tmp_path, lengths, limit):
    """Planar chain about z, link i of length l_i along x (as in test_ikpath_spatial)."""
    offsets = [0.0, *lengths[:-1]]
    joints = [
        _joint(
            f"j{i}",
            "revolute",
            "base" if i == 0 else f"l{i - 1}",
            f"l{i}",
            f"{o} 0 0",
            "0 0 1",
            (-limit, limit),
        )
        for i, o in enumerate(offsets)
    ]
    return _robot(tmp_path, f"planar{len(lengths)}", joints, f"{lengths[-1]} 0 0")


def _yaw_pitch_pitch(tmp_path):
    """A 3-DOF arm: its tool orientations are R_z(a) R_y(b), never a roll about the tool."""
    joints = [
        _joint("yaw", "revolute", "base", "l0", "0 0 0", "0 0 1"),
        _joint("shoulder", "revolute", "l0", "l1", "0 0 0.3", "0 1 0"),
        _joint("elbow", "revolute", "l1", "l2", "0 0 0.4", "0 1 0"),
    ]
    return _robot(tmp_path, "ypp", joints, "0 0 0.35")


def _mixed(tmp_path):
    """Every supported joint type: continuous, unaligned revolute, prismatic, rotated origins."""
    joints = [
        _joint("c0", "continuous", "base", "l0", "0 0 0.1", "0 0 1"),
        _joint("u1", "revolute", "l0", "l1", "0.1 0 0.2", "0 0.6 0.8", rpy="0.3 -0.2 0.1"),
        _joint("p2", "prismatic", "l1", "l2", "0 0.1 0.3", "1 0 0", (-0.2, 0.4)),
        _joint("x3", "revolute", "l2", "l3", "0.2 0 0", "1 0 0", (-3.0, 3.0), rpy="0 0.5 0"),
        _joint("q4", "prismatic", "l3", "l4", "0 0 0.1", "0.48 0.6 0.64", (-0.1, 0.3)),
        _joint("y5", "revolute", "l4", "l5", "0 0.05 0.1", "0 1 0", (-1.0, 2.0)),
    ]
    return _robot(tmp_path, "mixed", joints, "0.05 0.02 0.12")


def _problem(model, targets, **kw):
    return CyclicIKProblem(robot=model, frame="tip", targets=tuple(targets), **kw)


def _point_targets(*points):
    return [Target(position=(*p, 0.0)[:3]) for p in points]


def test_sin_cos_intervals_contain_numpy_on_dense_samples():
    """sin/cos intervals contain np.sin/np.cos at 1e4 points of each range (extrema included)."""
    rng = np.random.default_rng(0)
    lo = rng.uniform(-8.0, 8.0, 200)
    hi = lo + rng.uniform(0.0, 7.0, 200) * (rng.uniform(size=200) < 0.9)
    s, c = sin_cos(lo, hi)
    for k in range(lo.size):
        x = np.linspace(lo[k], hi[k], 10_000)
        assert s.lo[k] <= np.sin(x).min() and np.sin(x).max() <= s.hi[k]
        assert c.lo[k] <= np.cos(x).min() and np.cos(x).max() <= c.hi[k]
    # Not vacuous: each bound within 2e-7 of the sampled extreme. Samples are <= 7e-4 rad
    # apart, so a true extreme is missed by at most 1 - cos(3.5e-4) < 6.2e-8; plus 1e-14.
    for got, fn in ((s, np.sin), (c, np.cos)):
        for k in range(lo.size):
            y = fn(np.linspace(lo[k], hi[k], 10_000))
            assert got.hi[k] - y.max() <= 2e-7 and y.min() - got.lo[k] <= 2e-7


@pytest.mark.parametrize("robot", ["ur5", "panda", "mixed"])
def test_interval_fk_contains_pinocchio_fk_at_random_points_of_random_boxes(robot, tmp_path):
    """framesForwardKinematics at 5 random points of each of 400 random boxes lies in the box's
    interval placement, exactly (the only slack is the stated outward widening); so do the
    joint origins, and the frame is within each origin's reach bound."""
    if robot == "mixed":
        model, frame = _mixed(tmp_path), "tip"
    else:
        loaded = load_model(robot)
        model, frame = loaded.model, loaded.tip_frame
    problem = CyclicIKProblem(
        robot=model, frame=frame, targets=tuple(_point_targets((0.3, 0.0, 0.3)) * 2)
    )
    chain = IntervalChain.from_model(model, problem.frame_id)
    lo0, hi0 = joint_box(problem)
    if robot == "mixed":  # the continuous joint over several turns: the extrema logic
        lo0[0], hi0[0] = -7.0, 9.0
    rng = np.random.default_rng(1)
    a, b = rng.uniform(lo0, hi0, (2, 400, lo0.size))
    shrink = rng.uniform(0.0, 1.0, (400, 1)) ** 3  # widths from 0 to the whole box
    shrink[:40] = 0.0  # point boxes: the widening alone must cover Pinocchio's rounding
    shrink[40:60] = 1.0
    mid = 0.5 * (a + b)
    lower = np.where(shrink == 1.0, lo0, mid - shrink * np.abs(a - b) / 2)
    upper = np.where(shrink == 1.0, hi0, mid + shrink * np.abs(a - b) / 2)
    bounds = chain.placement(lower, upper)
    rot, pos = bounds.rotation, bounds.translation
    data = model.createData()
    for k in range(400):
        for _ in range(5):
            theta = rng.uniform(lower[k], upper[k])
            pin.framesForwardKinematics(model, data, problem.configuration(theta))
            placement = data.oMf[problem.frame_id]
            assert np.all(pos.lo[k] <= placement.translation)
            assert np.all(placement.translation <= pos.hi[k])
            assert np.all(rot.lo[k] <= placement.rotation)
            assert np.all(placement.rotation <= rot.hi[k])
            for i, j in enumerate(problem.active):  # joint origins and their reach
                parent = data.oMi[model.parents[int(j)]]
                origin = (parent * model.jointPlacements[int(j)]).translation
                assert np.all(bounds.origins.lo[k, i] <= origin)
                assert np.all(origin <= bounds.origins.hi[k, i])
                assert np.linalg.norm(placement.translation - origin) <= bounds.reach[k, i]
    # Not vacuous: a point box is an interval of width <= 1e-12 (the widening accumulated
    # over <= 8 joints: 1e-14 per sin/cos times lever arms of ~1 m).
    assert np.max(pos.hi[:40] - pos.lo[:40]) <= 1e-12
    assert np.max(rot.hi[:40] - rot.lo[:40]) <= 1e-12


def test_planar_example_unreachable_targets_agree_with_the_planar_decision(tmp_path):
    """Planar example B's arm (|theta| <= pi/2) as a URDF: (0, 7.1) beyond the sphere, (-6, 0)
    inside the annulus but outside the limits (interval certificate), as the planar solver says."""
    limit = math.pi / 2
    model = _planar(tmp_path, (3.0, 2.0, 2.0), limit)
    chain = PlanarChain(lengths=[3.0, 2.0, 2.0], q_lower=-limit, q_upper=limit)
    points = [(0.0, 7.1), (-6.0, 0.0), (-5.0, -3.0), (-3.0, -4.0), (0.0, 7.0)]
    problem = _problem(model, _point_targets(*points))
    verdicts = check_reachability_3d(problem, interval_boxes=100_000, interval_seconds=600.0)
    expected = [decide_reachability(chain, p).status for p in points]  # the independent oracle
    assert expected == [Reachability.UNREACHABLE] * 3 + [Reachability.REACHABLE] * 2
    assert [v.method for v in verdicts[:3]] == ["reach_sphere", "interval", "interval"]
    assert all(v.status is Reachability.UNREACHABLE for v in verdicts[:3])
    assert verdicts[1].distance < verdicts[1].reach  # inside the sphere: only the interval proof
    assert verdicts[1].boxes > 0 and "excludes every box" in verdicts[1].message
    data = model.createData()
    for v, p in zip(verdicts[3:], points[3:], strict=True):  # witnesses checked by Pinocchio
        assert v.status is Reachability.REACHABLE
        assert np.all(np.abs(v.witness) <= limit)
        pin.framesForwardKinematics(model, data, problem.configuration(v.witness))
        assert np.linalg.norm(data.oMf[problem.frame_id].translation - (*p, 0.0)) <= 1e-6


def test_annulus_hole_is_certified_without_limits(tmp_path):
    """Links (5, 1.5, 1.5), no limits: (1.9, 0) lies in the hole of radius 2 (planar: unreachable),
    (2.05, 0) does not; the interval search decides both (certificate and witness)."""
    model = _planar(tmp_path, (5.0, 1.5, 1.5), 3.0)
    inf = np.full(3, np.inf)
    for p, status in (
        ((1.9, 0.0), Reachability.UNREACHABLE),
        ((2.05, 0.0), Reachability.REACHABLE),
    ):
        assert decide_reachability(PlanarChain(lengths=[5.0, 1.5, 1.5]), p).reachable is (
            status is Reachability.REACHABLE
        )
        problem = _problem(model, _point_targets(p, p), q_lower=-inf, q_upper=inf)
        found = interval_search(problem, 0, **_BUDGET)
        assert found.status is status
        if found.witness is not None:  # unlimited joints: any angle is within the limits
            assert problem.targets[0].met(problem.placement(found.witness))


def test_orientation_out_of_reach_is_certified(tmp_path):
    """Targets within the reach sphere whose orientation no joint values produce: a planar chain
    asked for an out-of-plane pose or approach axis, and a yaw-pitch-pitch arm asked for a roll."""
    planar = _planar(tmp_path, (3.0, 2.0, 2.0), math.pi / 2)
    tilted = pin.rpy.rpyToMatrix(0.5, 0.0, 0.0)
    targets = [
        Target(position=(5.0, 1.0, 0.0), rotation=tilted),
        Target(position=(5.0, 1.0, 0.0), approach=(0.0, 0.5, 1.0)),
        Target(position=(5.0, 1.0, 0.0)),  # the same point: reachable
    ]
    verdicts = check_reachability_3d(_problem(planar, targets))
    assert [v.status for v in verdicts] == [Reachability.UNREACHABLE] * 2 + [Reachability.REACHABLE]
    assert all(v.method == "interval" for v in verdicts[:2])

    arm = _yaw_pitch_pitch(tmp_path)
    base = _problem(arm, _point_targets((0.3, 0.0, 0.3)) * 2)
    reached = base.placement([0.4, 0.7, -0.9])
    rolled = reached.rotation @ pin.rpy.rpyToMatrix(0.3, 0.0, 0.0)
    pose = Target(position=reached.translation, rotation=reached.rotation)
    roll = Target(position=reached.translation, rotation=rolled)
    problem = base.with_targets((pose, roll))
    assert np.linalg.norm(reached.translation - base.reach_radius()[0]) < base.reach_radius()[1]
    found = interval_search(problem, 1, **_BUDGET)
    assert found.status is Reachability.UNREACHABLE and found.by_orientation > 0
    found = interval_search(problem, 0, **_BUDGET)  # the unrolled pose: a witness
    assert found.status is Reachability.REACHABLE
    assert pose.met(problem.placement(found.witness))


def test_interval_search_never_refutes_a_reachable_target():
    """Targets made by FK at random in-limit angles of ur5 (position, pose, approach) are never
    called unreachable; every witness is within the limits and meets its target under FK."""
    robot = load_model("ur5")
    base = CyclicIKProblem(
        robot=robot.model, frame=robot.tip_frame, targets=tuple(_point_targets((0.3, 0.0, 0.3)) * 2)
    )
    rng = np.random.default_rng(3)
    for k in range(9):
        placement = base.placement(random_theta(base, rng))
        kind = [{}, {"rotation": placement.rotation}, {"approach": placement.rotation[:, 2]}][k % 3]
        target = Target(position=placement.translation, **kind)
        problem = base.with_targets((target, target))
        found = interval_search(problem, 0, max_boxes=20_000, max_seconds=600.0)
        assert found.status is not Reachability.UNREACHABLE
        if found.witness is not None:
            assert target.met(problem.placement(found.witness))
            assert np.all(found.witness >= problem.lower[:6])
            assert np.all(found.witness <= problem.upper[:6])


def test_ur5_target_between_true_reach_and_reach_sphere_is_certified():
    """A 6-DOF case: ur5's sphere has radius 1.24 m but its tool reaches about 0.95 m; a target
    1.1 m from the shoulder is certified by the interval search (and FK sampling agrees)."""
    robot = load_model("ur5")
    base = CyclicIKProblem(
        robot=robot.model, frame=robot.tip_frame, targets=tuple(_point_targets((0.3, 0.0, 0.3)) * 2)
    )
    centre, reach = base.reach_radius()
    target = Target(position=centre + np.array([0.6, 0.0, 0.0]) * 1.1 / 0.6)
    rng = np.random.default_rng(0)
    sampled = max(
        np.linalg.norm(base.placement(random_theta(base, rng)).translation - centre)
        for _ in range(2000)
    )
    assert sampled < 1.0 < 1.1 < reach
    found = interval_search(base.with_targets((target, target)), 0, **_BUDGET)
    assert found.status is Reachability.UNREACHABLE and found.pending == 0


def test_joint_box_and_unsupported_joints(tmp_path):
    """The box: limits, continuous joints [-pi, pi], wide ranges one turn; unboundable chains
    raise ParameterError naming the joint (and the reachability check says so)."""
    model = _mixed(tmp_path)
    problem = _problem(model, _point_targets((0.3, 0.0, 0.3)) * 2)
    lo, hi = joint_box(problem)
    np.testing.assert_array_equal(lo[[0, 2, 5]], [-math.pi, -0.2, -1.0])
    np.testing.assert_array_equal(hi[[0, 2, 5]], [math.pi, 0.4, 2.0])
    wide = _problem(model, problem.targets, q_lower=np.full(6, -4.0), q_upper=np.full(6, 4.0))
    lo, hi = joint_box(wide)
    assert lo[3] == -4.0 and hi[3] == -4.0 + 2.0 * math.pi  # revolute: one turn, in the limits
    assert (lo[2], hi[2]) == (-4.0, 4.0)  # prismatic: its travel
    free = _problem(model, problem.targets, use_limits=False)
    with pytest.raises(ParameterError, match="prismatic joint 'p2' has no finite travel"):
        joint_box(free)
    screw = pin.Model()
    joint = screw.addJoint(0, pin.JointModelHX(0.1), pin.SE3.Identity(), "screw")
    screw.addFrame(pin.Frame("tip", joint, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
    with pytest.raises(ParameterError, match="'screw' is a JointModelHX"):
        IntervalChain.from_model(screw, screw.getFrameId("tip"))


def test_solver_failure_names_the_blocking_target_with_the_certificate(tmp_path):
    """solve(check_reachability=True) refuses the out-of-plane pose: its index, the
    interval certificate (boxes, depth) and the verdict are in the error."""
    planar = _planar(tmp_path, (3.0, 2.0, 2.0), math.pi / 2)
    targets = [
        Target(position=(5.0, 1.0, 0.0)),
        Target(position=(4.0, 2.0, 0.0), rotation=pin.rpy.rpyToMatrix(0.0, 0.4, 0.0)),
    ]
    with pytest.raises(UnreachableTarget) as err:
        solve(_problem(planar, targets), check_reachability=True)
    v = err.value.verdict
    assert err.value.index == 1 and v.method == "interval" and v.boxes > 0
    msg = str(err.value)
    assert "target 1 (pose)" in msg and "interval forward kinematics excludes every box" in msg
    assert v.boxes > 1 and f"{v.boxes} boxes to bisection depth {v.depth}" in msg


def test_cli_prints_the_interval_certificate(tmp_path, monkeypatch, capsys):
    """`youbot-opt ikpath --robot URDF` exits 2 on a target outside the limits, printing the
    interval certificate; --json records who decided each verdict."""
    monkeypatch.chdir(tmp_path)
    model_path = tmp_path / "planar3.urdf"
    _planar(tmp_path, (3.0, 2.0, 2.0), math.pi / 2)
    argv = [
        "ikpath",
        "--robot",
        str(model_path),
        "--tip-frame",
        "tip",
        "--target",
        "-6",
        "0",
        "0",
        "--target",
        "5",
        "1",
        "0",
    ]
    assert main(argv) == 2
    assert "interval forward kinematics excludes every box" in capsys.readouterr().err
    assert main([*argv, "--json"]) == 2
    doc = json.loads(capsys.readouterr().out)
    first, second = doc["reachability"]
    assert (first["verdict"], first["decided_by"]) == ("unreachable", "interval")
    assert first["interval_boxes"] > 0
    assert (second["verdict"], second["decided_by"]) == ("reachable", "dls")


def test_budget_exhausted_is_undecided_and_bad_arguments_are_refused():
    """A ur5 target just beyond its true reach (1.0 m; sphere 1.24 m) with a 2 000-box budget
    stays undecided, and the verdict says how far the search got; bad budgets are refused."""
    robot = load_model("ur5")
    base = CyclicIKProblem(
        robot=robot.model, frame=robot.tip_frame, targets=tuple(_point_targets((0.3, 0.0, 0.3)) * 2)
    )
    centre, _ = base.reach_radius()
    target = Target(position=centre + np.array([1.0, 0.0, 0.0]))
    problem = base.with_targets((target, target))
    found = interval_search(problem, 0, max_boxes=2000, max_seconds=600.0)
    assert found.status is Reachability.UNDECIDED and found.witness is None
    assert found.boxes >= 2000 and found.pending > 0
    v = check_reachability_3d(problem, tries=1, interval_boxes=2000, interval_seconds=600.0)[0]
    assert v.status is Reachability.UNDECIDED and v.method == "none" and v.boxes >= 2000
    assert "interval search undecided after" in v.message
    with pytest.raises(ParameterError, match=r"j must be a target index in \[0, 1\], got 2"):
        interval_search(problem, 2)
    with pytest.raises(ParameterError, match="interval_seconds must be finite and >= 0"):
        check_reachability_3d(problem, interval_seconds=-1.0)
