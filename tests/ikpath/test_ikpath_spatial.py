"""Spatial cyclic IK paths (issue 14): planar special case, AL vs IPOPT, FK check, certificate."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.exceptions import ParameterError, UnreachableTarget
from youbot_opt.ikpath.dls import dls_ik, greedy_path
from youbot_opt.ikpath.examples import EXAMPLES, example_problem
from youbot_opt.ikpath.methods.al import ALOptions, solve_augmented_lagrangian
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability import Reachability
from youbot_opt.ikpath.reachability.general import check_reachability_3d
from youbot_opt.ikpath.solve import solve
from youbot_opt.ikpath.starts import make_starts_3d
from youbot_opt.ikpath.targets import Target
from youbot_opt.robot.load import load_model

_INERTIAL = (  # the loader checks that M(q) is positive definite
    '<inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" '
    'izz="0.1"/></inertial>'
)


def _planar_urdf(lengths: tuple[float, ...], limit: float | None, continuous: bool = False) -> str:
    """A planar chain as URDF: revolute joints about z, link i of length l_i along x."""
    lim = 3.0 if limit is None else limit  # unlimited: overridden by the problem below
    parts = ['<robot name="planar">', '<link name="base"/>']
    parent, offset = "base", 0.0
    for i, length in enumerate(lengths):
        kind = "continuous" if continuous else "revolute"
        parts.append(
            f'<joint name="j{i}" type="{kind}"><parent link="{parent}"/><child link="l{i}"/>'
            f'<origin xyz="{offset} 0 0"/><axis xyz="0 0 1"/>'
            f'<limit lower="{-lim}" upper="{lim}" effort="1" velocity="1"/></joint>'
        )
        parts.append(f'<link name="l{i}">{_INERTIAL}</link>')
        parent, offset = f"l{i}", length
    parts.append(
        f'<joint name="tip_joint" type="fixed"><parent link="{parent}"/><child link="tip"/>'
        f'<origin xyz="{offset} 0 0"/></joint><link name="tip"/></robot>'
    )
    return "".join(parts)


def _planar_as_spatial(name: str, tmp_path, use_limits: bool) -> CyclicIKProblem:
    data = EXAMPLES[name]
    path = tmp_path / f"planar_{name}.urdf"
    path.write_text(_planar_urdf(data.lengths, data.limit))
    robot = load_model(path, tip_frame="tip")
    n = len(data.lengths)
    inf = np.full(n, np.inf)
    targets = tuple(Target(position=(x, y, 0.0)) for x, y in data.targets)
    if data.limit is None:
        return CyclicIKProblem(
            robot=robot.model, frame="tip", targets=targets, q_lower=-inf, q_upper=inf
        )
    return CyclicIKProblem(robot=robot.model, frame="tip", targets=targets, use_limits=use_limits)


@pytest.mark.parametrize(("name", "use_limits"), [("A", False), ("B", True), ("B", False)])
def test_planar_chain_through_the_spatial_path_matches_the_planar_solver(
    name, use_limits, tmp_path
):
    # Same start (zero), same AL options: the general methods (planar=False: the 2 plane
    # rows per target from the LOCAL frame Jacobian) converge to the planar solver's KKT
    # point; 1e-8 in E and angles (both solved to |c| <= 1e-10).
    planar = example_problem(name)
    if not use_limits:
        planar = type(planar)(robot=planar.chain, targets=planar.target_points, use_limits=False)
    spatial = _planar_as_spatial(name, tmp_path, use_limits)
    ref = solve_augmented_lagrangian(planar, None, ALOptions())
    got = solve(spatial, method="al", options=ALOptions(), planar=False)
    assert ref.success and got.success
    assert abs(got.objective - ref.objective) <= 1e-8
    np.testing.assert_allclose(got.configurations, ref.configurations, atol=1e-8, rtol=0)


def _ur5_problem(seed: int) -> CyclicIKProblem:
    robot = load_model("ur5")
    model, data = robot.model, robot.model.createData()
    pin.seed(seed)
    np.random.seed(seed)  # noqa: NPY002 - pin.randomConfiguration draws from it
    targets = []
    for k in range(5):
        q = pin.randomConfiguration(model)
        pin.framesForwardKinematics(model, data, q)
        placement = data.oMf[model.getFrameId(robot.tip_frame)]
        rot = placement.rotation if k % 2 == 0 else None
        targets.append(Target(position=placement.translation, rotation=rot))
    return CyclicIKProblem(robot=model, frame=robot.tip_frame, targets=tuple(targets))


def test_al_and_ipopt_agree_on_the_best_minimum_and_poses_pass_an_independent_fk_check():
    # Each method from its own independent starts; the best minimum over both is a KKT
    # point, and the other method started there must stay on it (E to 1e-8 relative:
    # both solve |c| to 1e-10, so E moves by O(|lambda| |c|) ~ 1e-9 at most). Three
    # starts each are too few for both to find the best basin of this problem; the
    # independent-multistart agreement is test_spatial_agreement.py.
    problem = _mixed_panda_problem()
    results = {
        method: [
            solve(problem, method=method, x0=x0) for x0 in make_starts_3d(problem, 3, seed=seed)
        ]
        for method, seed in (("al", 0), ("ipopt", 1))
    }
    found = [r for rs in results.values() for r in rs if r.success]
    assert {r.method for r in found} == {"al", "ipopt"}
    best = min(found, key=lambda r: r.objective)
    other = "ipopt" if best.method == "al" else "al"
    again = solve(problem, method=other, x0=best.configurations)
    assert again.success
    assert abs(again.objective - best.objective) <= 1e-8 * best.objective
    np.testing.assert_allclose(again.configurations, best.configurations, atol=1e-6, rtol=0)
    # Orientation targets met to 1e-6 rad, positions to 1e-6 m, under framesForwardKinematics.
    model, data = problem.model, problem.model.createData()
    for r in (best, again):
        for theta, target in zip(r.configurations, problem.targets, strict=True):
            pin.framesForwardKinematics(model, data, problem.configuration(theta))
            placement = data.oMf[problem.frame_id]
            assert np.linalg.norm(placement.translation - target.position) <= 1e-6
            if target.rotation is not None:
                assert np.linalg.norm(pin.log3(target.rotation.T @ placement.rotation)) <= 1e-6
            if target.approach is not None:
                axis = placement.rotation @ target.approach_axis
                assert np.arccos(min(1.0, float(axis @ target.approach))) <= 1e-6


def test_unreachable_target_refused_with_its_reach_sphere_certificate():
    problem = _ur5_problem(1)
    far = Target(position=(3.0, 0.0, 0.5))
    bad = problem.with_targets((*problem.targets[:2], far))
    verdicts = check_reachability_3d(bad)
    assert verdicts[2].status is Reachability.UNREACHABLE
    assert verdicts[2].distance > verdicts[2].reach  # the certificate
    # UR5's reach is about 1 m: the sphere must be sound (>= the true reach) yet below 3 m.
    assert 0.9 < verdicts[2].reach < 3.0
    with pytest.raises(UnreachableTarget) as err:
        solve(bad, check_reachability=True)
    assert err.value.index == 2 and "reach sphere" in str(err.value)


def test_continuous_joints_are_never_wrapped(tmp_path):
    # One continuous joint, tip 1 m out, targets at 0, 120, 240 deg. Convention: a tour
    # returns each joint to its starting angle (no net 2 pi turn), so the steps sum to
    # zero: the optimum is steps (2pi/3, 2pi/3, -4pi/3), E = 4 pi^2 / 3. Wrapping the
    # closing step would give three steps of 2pi/3 and E = 2 pi^2 / 3 instead.
    path = tmp_path / "wheel.urdf"
    path.write_text(_planar_urdf((1.0,), None, continuous=True))
    model = load_model(path, tip_frame="tip").model
    angles = (0.0, 2 * np.pi / 3, 4 * np.pi / 3)
    targets = tuple(Target(position=(np.cos(a), np.sin(a), 0.0)) for a in angles)
    problem = CyclicIKProblem(robot=model, frame="tip", targets=targets)
    assert problem.continuous.tolist() == [True] and not problem.bounded
    result = solve(problem, x0=[0.0, 2.0, 4.0])
    assert result.success
    steps = result.leg_motion()[:, 0]
    assert abs(steps.sum()) <= 1e-12  # back at the starting angle
    assert result.objective == pytest.approx(4 * np.pi**2 / 3, rel=1e-8)


def _mixed_panda_problem() -> CyclicIKProblem:
    robot = load_model("panda")
    base = CyclicIKProblem(
        robot=robot.model,
        frame=robot.tip_frame,
        targets=(Target(position=(0, 0, 0)), Target(position=(0, 0, 0))),
    )
    rng = np.random.default_rng(7)
    placements = [base.placement(rng.uniform(base.q_lower, base.q_upper)) for _ in range(3)]
    targets = (
        Target(position=placements[0].translation),
        Target(position=placements[1].translation, rotation=placements[1].rotation),
        Target(position=placements[2].translation, approach=placements[2].rotation[:, 2]),
    )
    return base.with_targets(targets)


def test_constraint_jacobian_blocks_match_central_differences():
    # Pose and approach rows: analytic (Jlog3, skew) vs central differences; h = 1e-6 rad
    # gives truncation ~h^2 |c'''| ~ 1e-12 and rounding ~eps / h ~ 1e-10: 1e-7 is far above both.
    problem = _mixed_panda_problem()
    assert problem.n_joints == 7 and problem.block_rows == 6  # fingers are not unknowns
    theta = np.random.default_rng(1).uniform(-1.0, 1.0, problem.n_joints)
    data = problem.create_data()
    for j in range(problem.n_targets):
        _, jac = problem.block(j, theta, data)
        num = np.column_stack(
            [
                (
                    problem.block(j, theta + 1e-6 * e, data)[0]
                    - problem.block(j, theta - 1e-6 * e, data)[0]
                )
                / 2e-6
                for e in np.eye(problem.n_joints)
            ]
        )
        np.testing.assert_allclose(jac, num, atol=1e-7, rtol=0)


def test_symbolic_kinematics_of_ipopt_equal_pinocchio():
    import casadi as ca

    from youbot_opt.ikpath.methods.ipopt import frame_expression

    for problem in (_mixed_panda_problem(), _ur5_problem(0)):
        sym = ca.SX.sym("q", problem.n_joints)
        pos, rot = frame_expression(problem, sym)
        fk = ca.Function("fk", [sym], [pos, rot])
        for theta in np.random.default_rng(2).uniform(-3.0, 3.0, (5, problem.n_joints)):
            placement = problem.placement(theta)
            p, r = (np.array(v) for v in fk(theta))
            # Two evaluations of the same product of ~10 rotations: rounding ~1e-15 per metre.
            np.testing.assert_allclose(p.ravel(), placement.translation, atol=1e-12)
            np.testing.assert_allclose(r, placement.rotation, atol=1e-12)


def test_approach_and_pose_targets_are_met_by_both_methods():
    problem = _mixed_panda_problem()
    x0 = make_starts_3d(problem, 1, seed=0)[0]
    al = solve(problem, method="al", x0=x0)
    ip = solve(problem, method="ipopt", x0=x0)
    assert al.success and ip.success
    assert max(al.orientation_errors) <= 1e-6 and max(ip.orientation_errors) <= 1e-6


def test_targets_from_csv_and_json_files(tmp_path):
    from youbot_opt.exceptions import ParameterError
    from youbot_opt.ikpath.targets import load_targets

    (tmp_path / "t.csv").write_text(
        "x,y,z,qx,qy,qz,qw,ax,ay,az\n1,2,3,,,,,0,0,-2\n4,5,6,0,0,1,1,,,\n"
    )
    a, b = load_targets(tmp_path / "t.csv", position_tol=1e-4)
    assert a.kind == "approach" and a.approach.tolist() == [0, 0, -1] and a.position_tol == 1e-4
    assert b.kind == "pose"
    np.testing.assert_allclose(b.rotation, pin.utils.rotate("z", np.pi / 2), atol=1e-15)
    (tmp_path / "t.json").write_text(
        '{"targets": [{"position": [1, 2, 3]}, {"position": [0, 0, 1], '
        '"quaternion_xyzw": [0, 0, 0, 1], "orientation_tol": 0.01}]}'
    )
    c, d = load_targets(tmp_path / "t.json")
    assert c.kind == "position" and d.kind == "pose" and d.orientation_tol == 0.01
    (tmp_path / "bad.csv").write_text("x,y\n1,2\n")
    with pytest.raises(ParameterError, match="x, y, z"):
        load_targets(tmp_path / "bad.csv")


def test_standalone_replay_draws_targets_triads_and_unwrapped_legs(tmp_path):
    from youbot_opt.viz.meshcat.ikpath import (
        export_ikpath_html,
        replay_robot,
        replay_track,
    )
    from youbot_opt.viz.plots.ikpath import plot_leg_motion, plot_path

    path = tmp_path / "wheel.urdf"
    path.write_text(_planar_urdf((1.0,), None, continuous=True))
    robot = load_model(path, tip_frame="tip")
    angles = (0.0, 2 * np.pi / 3, 4 * np.pi / 3)
    targets = (
        Target(position=(1.0, 0.0, 0.0), rotation=np.eye(3)),
        Target(position=(np.cos(angles[1]), np.sin(angles[1]), 0.0)),
        Target(position=(np.cos(angles[2]), np.sin(angles[2]), 0.0)),
    )
    problem = CyclicIKProblem(robot=robot.model, frame="tip", targets=targets)
    result = solve(problem, x0=[0.0, 2.0, 4.0])
    assert result.success
    names = [g.name for g in replay_robot(result, robot).visual_model.geometryObjects]
    assert {"target_1", "target_1_axis_0", "target_1_axis_2", "target_3"} <= set(names)
    assert "target_2_axis_0" not in names  # position targets: a sphere, no triad
    t, q = replay_track(result, segment_time=0.5, samples_per_leg=12)
    assert t[-1] == pytest.approx(1.5) and q.shape == (37, 2)  # (cos, sin) of the wheel
    # The closing leg turns back through 4 pi / 3: consecutive samples are pi / 9 apart, so
    # the viewer's shortest-arc interpolation between samples follows the unwrapped angle.
    steps = np.abs(np.diff(np.unwrap(np.arctan2(q[:, 1], q[:, 0]))))
    assert np.max(steps) <= np.pi / 9 + 1e-12
    html = export_ikpath_html(result, tmp_path / "replay.html", robot=robot)
    assert html.stat().st_size > 10_000 and "meshcat" in html.read_text()[:200_000].lower()
    assert plot_leg_motion(result).axes and plot_path(result).axes


def test_dls_handles_a_pose_block_the_chain_cannot_span(tmp_path):
    # A 3-joint planar chain has a 6x3 pose Jacobian: J J^T is singular, and the
    # damped step must still be defined (it once raised LinAlgError). The in-plane
    # pose (a rotation about z) is met; one tilted out of the plane cannot be.
    path = tmp_path / "planar3.urdf"
    path.write_text(_planar_urdf((1.0, 1.0, 1.0), 3.0))
    robot = load_model(path, tip_frame="tip")
    half = np.sin(0.25), np.cos(0.25)  # 0.5 rad about z / about x
    in_plane = Target.pose((1.5, 1.0, 0.0), (0.0, 0.0, half[0], half[1]))
    tilted = Target.pose((1.5, 1.0, 0.0), (half[0], 0.0, 0.0, half[1]))
    problem = CyclicIKProblem(robot=robot.model, frame="tip", targets=(in_plane, tilted))
    theta, met = dls_ik(problem, 0, np.zeros(3))
    assert met
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, theta)
    placement = data.oMf[robot.model.getFrameId("tip")]
    assert np.linalg.norm(placement.translation - in_plane.position) <= 1e-6
    assert np.linalg.norm(pin.log3(in_plane.rotation.T @ placement.rotation)) <= 1e-6
    theta, met = dls_ik(problem, 1, np.zeros(3))
    assert not met and np.all(np.isfinite(theta))
    path_angles, all_met = greedy_path(problem)
    assert not all_met and np.all(np.isfinite(path_angles))


def test_a_planar_robot_has_two_rows_per_position_target_and_ipopt_solves_it(tmp_path):
    """#25 item 4: a 2-link URDF chain (6 targets) has 12 rows for 12 unknowns, IPOPT solves it.

    With 3 rows per target IPOPT met 18 equations for 12 unknowns and failed every start;
    the plane rows give the planar solver's KKT point (same start, 1e-8 in E and angles).
    """
    from youbot_opt.ikpath.problem import CyclicIKProblem
    from youbot_opt.ikpath.solve import solve
    from youbot_opt.robot.planar import PlanarChain

    lengths = (1.0, 0.8)
    path = tmp_path / "planar2.urdf"
    path.write_text(_planar_urdf(lengths, None))
    robot = load_model(path, tip_frame="tip")
    angles = np.linspace(0.0, 2.0 * np.pi, 6, endpoint=False)
    points = [(1.5 * np.cos(a), 1.2 * np.sin(a)) for a in angles]
    inf = np.full(2, np.inf)
    spatial = CyclicIKProblem(
        robot=robot.model,
        frame="tip",
        targets=tuple(Target(position=(x, y, 0.0)) for x, y in points),
        q_lower=-inf,
        q_upper=inf,
    )
    assert spatial.plane is not None
    np.testing.assert_array_equal(spatial.plane.basis, np.eye(3)[:, :2])
    assert spatial.block_rows == 2 and spatial.n_constraints == spatial.n_variables == 12
    planar = CyclicIKProblem(robot=PlanarChain(lengths=lengths), targets=points)
    start = np.tile([0.3, 0.5], 6)
    ref = solve(planar, method="ipopt", x0=start, check_reachability=False)
    got = solve(spatial, method="ipopt", x0=start, planar=False)
    assert ref.success and got.success, got.message
    assert abs(got.objective - ref.objective) <= 1e-8
    np.testing.assert_allclose(got.configurations, ref.configurations, atol=1e-8, rtol=0)
    ref_al = solve(planar, method="al", x0=start, check_reachability=False)
    al = solve(spatial, method="al", x0=start, options=ALOptions(), planar=False)
    assert ref_al.success and al.success
    assert abs(al.objective - ref_al.objective) <= 1e-8


def test_a_target_off_the_planar_robot_plane_is_refused(tmp_path):
    """A planar robot's position target must lie in its plane (ParameterError names it)."""
    path = tmp_path / "planar2.urdf"
    path.write_text(_planar_urdf((1.0, 0.8), None))
    robot = load_model(path, tip_frame="tip")
    targets = (Target(position=(1.0, 0.5, 0.0)), Target(position=(1.0, 0.5, 0.2)))
    with pytest.raises(ParameterError, match="target 1 lies 0.2 m off it"):
        CyclicIKProblem(robot=robot.model, frame="tip", targets=targets)


def test_the_youbot_arm_is_planar_in_its_platform_x_z_plane(youbot):
    """Joints about the platform y axis: plane coordinates (x, z), 2 rows per position."""
    data = youbot.create_data()
    pin.framesForwardKinematics(youbot.model, data, np.zeros(youbot.nq))
    tip = data.oMf[youbot.frame_id(youbot.tip_frame)].translation
    problem = CyclicIKProblem(
        robot=youbot.model,
        frame=youbot.tip_frame,
        targets=(Target(position=tip), Target(position=tip + (0.05, 0.0, -0.1))),
    )
    assert problem.plane is not None
    np.testing.assert_array_equal(problem.plane.basis, np.eye(3)[:, [0, 2]])
    assert problem.block_rows == 2
    ur5 = load_model("ur5")
    assert (
        CyclicIKProblem(
            robot=ur5.model,
            frame=ur5.tip_frame,
            targets=(Target(position=(0.3, 0, 0.3)), Target(position=(0, 0.3, 0.3))),
        ).plane
        is None
    )


def test_a_planar_urdf_chain_is_solved_by_the_planar_methods_like_the_chain(tmp_path):
    """#25 item 4: a URDF chain's problem has its PlanarChain, hence the exact verdicts and
    feasible starts of the chain (same draws to 1e-9 rad) and the same optimum (1e-8)."""
    from youbot_opt.ikpath.reachability.planar import check_reachability
    from youbot_opt.ikpath.solve import solve
    from youbot_opt.ikpath.starts import make_starts

    planar = example_problem("B")
    path = tmp_path / "planar_B.urdf"
    path.write_text(_planar_urdf(EXAMPLES["B"].lengths, EXAMPLES["B"].limit))
    robot = load_model(path, tip_frame="tip")
    urdf = CyclicIKProblem(robot=robot, targets=planar.target_points)
    assert urdf.chain is not None and urdf.block_rows == 2
    np.testing.assert_allclose(urdf.chain.lengths, planar.chain.lengths, atol=1e-15)
    np.testing.assert_array_equal(urdf.target_points, planar.target_points)
    got = [v.status for v in check_reachability(urdf)]
    assert got == [v.status for v in check_reachability(planar)]
    np.testing.assert_allclose(
        make_starts(urdf, 20, 0, verdicts=check_reachability(urdf)),
        make_starts(planar, 20, 0, verdicts=check_reachability(planar)),
        atol=1e-9,
    )
    for method in ("al", "ipopt"):
        ref = solve(planar, method=method)
        res = solve(urdf, method=method)
        assert ref.success and res.success, res.message
        assert abs(res.objective - ref.objective) <= 1e-8


def test_solve_picks_the_methods_and_defaults_of_the_robot_kind(tmp_path):
    """One solve: a planar robot gets the planar methods (reachability checked, IKPathResult),
    planar=False the general ones (IKPathResult, same optimum to 1e-8); a chain-less
    problem refuses planar=True."""
    from youbot_opt.ikpath.result import IKPathResult

    problem = _planar_as_spatial("A", tmp_path, use_limits=False)
    planar = solve(problem)
    general = solve(problem, planar=False, options=ALOptions())
    assert isinstance(planar, IKPathResult) and isinstance(general, IKPathResult)
    assert planar.success and general.success
    assert abs(planar.objective - general.objective) <= 1e-8
    far = problem.with_targets((*problem.targets[:4], Target(position=(9.0, 0.0, 0.0))))
    with pytest.raises(UnreachableTarget):
        solve(far)
    assert isinstance(solve(far, check_reachability=False, method="al"), IKPathResult)
    with pytest.raises(ParameterError, match="planar robot"):
        solve(_ur5_problem(0), planar=True)


def test_a_planar_robot_constrains_one_orientation_angle(tmp_path):
    """#25 item 4: pose and axis targets on a planar robot carry no always-zero rows.

    A pose constrains the plane position (2 rows) and the angle about the normal
    (1 row); an axis that turns in the plane 1 row, one along the normal none. The
    Jacobians match central differences (1e-6), and IPOPT, which the 3-row pose had
    overconstrained (13 equations for 9 unknowns), solves it as the AL does.
    """
    path = tmp_path / "planar3.urdf"
    path.write_text(_planar_urdf((1.0, 1.0, 1.0), 3.0))
    robot = load_model(path, tip_frame="tip")
    base = CyclicIKProblem(
        robot=robot.model, frame="tip", targets=(Target(position=(1, 1, 0)),) * 2
    )
    rng = np.random.default_rng(2)
    qs = rng.uniform(-1.5, 1.5, (3, 3))
    p = [base.placement(q) for q in qs]
    x_axis, z_axis = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    problem = base.with_targets(
        (
            Target(position=p[0].translation, rotation=p[0].rotation),
            Target(position=p[1].translation, approach=p[1].rotation[:, 0], approach_axis=x_axis),
            Target(position=p[2].translation, approach=p[2].rotation[:, 2], approach_axis=z_axis),
        )
    )
    assert [problem.rows_of(t) for t in problem.targets] == [3, 3, 2]
    assert problem.block_rows == 3 and problem.n_constraints == 9
    data = problem.create_data()
    for j in range(3):
        theta = rng.uniform(-1.0, 1.0, 3)
        _, jac = problem.block(j, theta, data)
        fd = np.column_stack(
            [
                (problem.block(j, theta + e, data)[0] - problem.block(j, theta - e, data)[0]) / 2e-6
                for e in 1e-6 * np.eye(3)
            ]
        )
        np.testing.assert_allclose(jac, fd, atol=1e-6)
    for method in ("al", "ipopt"):
        result = solve(problem, method=method, x0=(qs + 0.3).ravel())
        assert result.success, (method, result.status, result.message)
        assert result.max_position_error() <= 1e-6 and result.max_orientation_error() <= 1e-6
