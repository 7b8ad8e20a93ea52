"""Clearance in the cyclic IK path (#28 item 4, IK half): a planar arm and a disc.

The 3-link arm (capsules of radius 0.05 m) visits (2, 1) and (2, -1); its free
optimum turns the base the short way, and its links sweep through a disc at
(1.2, 0). With the clearance the path must turn the long way round: the legs
then clear the disc by the margin in coal, and E is larger.
"""

from __future__ import annotations

import dataclasses
import pickle
from collections.abc import Iterator
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.collision import Cylinder, Obstacle, Scene
from youbot_opt.collision.clearance import Clearance
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.clearance import certify_path_clearance
from youbot_opt.ikpath.multistart import run_multistart
from youbot_opt.ikpath.problem import _BUILT_ROWS, CyclicIKProblem
from youbot_opt.ikpath.result import build_result
from youbot_opt.ikpath.solve import solve
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.planar import PlanarChain

TARGETS = [(2.0, 1.0), (2.0, -1.0)]
LIMITS = {"q_lower": -2 * np.pi, "q_upper": 2 * np.pi}
MARGIN = 0.02  # [m]


@pytest.fixture(autouse=True)
def _fit_cache(fit_cache: Path) -> Iterator[None]:
    """Ball fits go to a temporary folder, never the user's cache."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("YOUBOT_OPT_CACHE", str(fit_cache))
        yield


def _arm(lengths: tuple[float, ...] = (1.0, 1.0, 1.0), radius: float = 0.05) -> RobotModel:
    """A planar chain whose links are capsules (collision geometry)."""
    robot = PlanarChain(lengths=list(lengths)).robot()
    geometry = pin.GeometryModel()
    for j, length in enumerate(lengths, start=1):
        placement = pin.SE3(pin.utils.rotate("y", np.pi / 2), np.array([length / 2, 0.0, 0.0]))
        capsule = coal.Capsule(radius, length)
        geometry.addGeometryObject(pin.GeometryObject(f"link{j}", j, j, placement, capsule))
    return dataclasses.replace(robot, collision_model=geometry)


def _disc(x: float, y: float, radius: float = 0.1) -> Scene:
    return Scene((Obstacle(name="disc", shape=Cylinder(radius=radius, length=1.0), xyz=(x, y, 0)),))


@pytest.fixture(scope="module")
def arm() -> RobotModel:
    return _arm()


def _problem(arm: RobotModel, scene: Scene, leg_samples: int = 8) -> CyclicIKProblem:
    clearance = Clearance(scene=scene, margin=MARGIN, self_collision=False)
    return CyclicIKProblem(
        robot=arm, targets=TARGETS, clearance=clearance, leg_samples=leg_samples, **LIMITS
    )


def _free_optimum(arm: RobotModel) -> tuple[CyclicIKProblem, np.ndarray]:
    free = CyclicIKProblem(robot=arm, targets=TARGETS, **LIMITS)
    x0 = np.array([[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]])
    result = solve(free, method="ipopt", x0=x0, planar=False)
    assert result.status.name == "SOLVED"
    return free, result.configurations


#: The known answer's E [rad^2] (IPOPT and the AL, docs/ikpath.md "Clearance").
LONG_WAY_E = 17.988196943


def _long_way_starts(q_free: np.ndarray) -> list[np.ndarray]:
    """The free optimum with the base the long way round, and 11 copies moved by 0.05 rad."""
    start = q_free.copy()
    start[0, 0] -= 2 * np.pi
    rng = np.random.default_rng(0)
    return [start] + [start + rng.normal(0.0, 0.05, start.shape) for _ in range(11)]


def test_known_answer_the_path_turns_the_long_way(arm: RobotModel) -> None:
    """IPOPT's solves from the long way round all end at the known answer, certified.

    IPOPT from these colliding starts converges from a few of them only (3 of 12
    with each row built once, 4 of 12 when the two legs' rows were built twice,
    the first start among them; the others end infeasible, lost in the restoration
    phase; the AL converges from all 12): the test asks one, and that every solved
    one is the known answer.
    """
    free, q_free = _free_optimum(arm)
    problem = _problem(arm, _disc(1.2, 0.0))
    crossing = certify_path_clearance(problem, q_free)
    assert crossing is not None and not crossing.certified
    assert crossing.closest_distance < 0  # the free legs cross the disc
    runs = [solve(problem, method="ipopt", x0=start) for start in _long_way_starts(q_free)]
    solved = [run for run in runs if run.status.name == "SOLVED"]
    assert solved, [run.message for run in runs]
    for run in solved:  # stationary to 1e-8 at one minimum: E to ~1e-9 (measured 1e-13)
        assert run.objective == pytest.approx(LONG_WAY_E, abs=1e-8)
    result = solved[0]
    x = result.configurations.ravel()
    assert np.max(problem.residuals(x)) < 1e-9
    assert problem.clearance_rows is not None
    assert np.min(problem.clearance_rows.rows(x)) >= MARGIN - 1e-8
    certificate = certify_path_clearance(problem, x)
    assert certificate is not None and certificate.certified
    assert certificate.lower_bound >= MARGIN
    assert result.objective >= free.objective(q_free.ravel())
    assert result.clearance == certificate  # the result carries coal's certificate


def test_a_success_whose_path_crosses_the_disc_is_downgraded(arm: RobotModel) -> None:
    """A hand-moved path (the free optimum, through the disc) claimed solved: downgraded."""
    _, q_free = _free_optimum(arm)
    problem = _problem(arm, _disc(1.2, 0.0))
    moved = build_result(
        problem,
        method="ipopt",
        status=SolveStatus.SOLVED,
        x=q_free,
        multipliers=np.zeros((2, 2)),
        iterations=1,
        wall_time=0.0,
        message="claimed",
        start=q_free,
    )
    assert moved.clearance == certify_path_clearance(problem, q_free)
    assert moved.clearance is not None and not moved.clearance.certified
    assert moved.status is SolveStatus.CONSTRAINT_VIOLATION and not moved.success
    assert "clearance margin 0.02 m (coal): link" in moved.message and "/ disc at" in moved.message


def test_rows_gradients_match_central_differences(arm: RobotModel) -> None:
    problem = _problem(arm, _disc(1.2, 0.0), leg_samples=3)
    rows = problem.clearance_rows
    assert rows is not None
    assert len(rows.labels) == 4 * rows.n_pairs  # two targets: leg 0's steps hold both legs
    rng = np.random.default_rng(7)
    h = 1e-6
    for _ in range(3):
        x = rng.uniform(-1.5, 1.5, problem.n_variables)
        numeric = np.column_stack(
            [(rows.rows(x + h * e) - rows.rows(x - h * e)) / (2 * h) for e in np.eye(x.size)]
        )
        np.testing.assert_allclose(rows.rows_jacobian(x), numeric, atol=1e-6)


def test_rows_never_exceed_coal_along_a_leg(arm: RobotModel) -> None:
    """A step's row is a lower bound on coal's distance anywhere on the step, on both legs.

    Two targets: the rows are leg 0's; leg 1 (leg 0 walked back) takes step ``k``'s
    bound from leg 0's step ``K - k``.
    """
    problem = _problem(arm, _disc(1.2, 0.0), leg_samples=2)
    rows = problem.clearance_rows
    assert rows is not None and rows.legs == (0,)
    x = np.array([[0.3, 0.2, -0.4], [1.4, -0.3, 0.5]])
    bound = rows.rows(x.ravel()).reshape(3, rows.n_pairs)
    legs = [(x[0], x[1], bound), (x[1], x[0], bound[::-1])]
    for qa, qb, steps in legs:
        for k in range(3):
            for f in np.linspace(k / 3, (k + 1) / 3, 7):
                theta = qa + f * (qb - qa)
                exact = rows.checker.distances(problem.robot_model, problem.configuration(theta))
                assert np.all(steps[k] <= exact + 1e-9)


@pytest.mark.parametrize("n_targets", [2, 3, 6])
def test_each_distinct_row_is_built_once(arm: RobotModel, n_targets: int) -> None:
    """No two rows are the same function of x: legs joining the same two targets share rows.

    Two targets: leg 1 is leg 0 walked back, so ``K + 1`` steps per pair (was twice
    that, each row twice: their multipliers were then determined only as a sum).
    """
    angles = 0.3 + 2 * np.pi * np.arange(n_targets) / n_targets
    targets = [(2.0 * np.cos(a), 2.0 * np.sin(a)) for a in angles]
    clearance = Clearance(scene=_disc(4.0, 4.0), margin=MARGIN, self_collision=False)
    problem = CyclicIKProblem(robot=arm, targets=targets, clearance=clearance, **LIMITS)
    rows = problem.clearance_rows
    assert rows is not None and rows.n_pairs == 3  # each link / the disc
    rng = np.random.default_rng(3)
    x = rng.uniform(-1.5, 1.5, problem.n_variables)
    values = np.column_stack([rows.rows(x), rows.rows_jacobian(x)])
    gaps = np.linalg.norm(values[:, None, :] - values[None, :, :], axis=2)
    np.fill_diagonal(gaps, np.inf)
    # a repeated row differs by rounding only (leg 1's rows from leg 0's: 4e-16); the
    # closest distinct rows here, two steps of link1 far from the disc, by 1e-6
    assert gaps.min() > 1e-10
    n_legs = 1 if n_targets == 2 else n_targets
    assert len(rows.labels) == n_legs * 9 * rows.n_pairs == len(set(rows.labels))
    assert rows.legs == tuple(range(n_legs))


def test_target_inside_obstacle_refused(arm: RobotModel) -> None:
    with pytest.raises(ParameterError, match=r"target 0 .* inside obstacle 'disc'"):
        _problem(arm, _disc(2.0, 1.0))


def test_start_inside_obstacle_refused(arm: RobotModel) -> None:
    _, q_free = _free_optimum(arm)
    problem = _problem(arm, _disc(1.2, 0.0))
    inside = q_free.copy()
    inside[0] = [0.0, 0.0, 0.0]  # the stretched arm lies across the disc
    with pytest.raises(ParameterError, match=r"start configuration 0: link geometry 'link2'"):
        problem.check_start(inside)


def test_clearance_refuses_the_planar_methods(arm: RobotModel) -> None:
    problem = _problem(arm, _disc(1.2, 0.0))
    for method in ("al", "ipopt"):
        with pytest.raises(ParameterError, match="general methods only .* planar methods do not"):
            solve(problem, method=method, planar=True)  # type: ignore[arg-type]


def test_known_answer_by_the_augmented_lagrangian(arm: RobotModel) -> None:
    """The AL (general, PHR clearance rows) from the long way round returns IPOPT's path."""
    free, q_free = _free_optimum(arm)
    problem = _problem(arm, _disc(1.2, 0.0))
    starts = _long_way_starts(q_free)
    ipopt = next(
        run
        for run in (solve(problem, method="ipopt", x0=start) for start in starts)
        if run.status.name == "SOLVED"
    )
    al = solve(problem, method="al", x0=starts[0])
    assert al.status.name == "SOLVED", al.message
    x = al.configurations.ravel()
    assert np.max(problem.residuals(x)) < 1e-9
    assert problem.clearance_rows is not None
    assert np.min(problem.clearance_rows.rows(x)) >= MARGIN - 1e-10
    certificate = certify_path_clearance(problem, x)
    assert certificate is not None and certificate.certified
    # both meet the targets to 1e-10 m and stationarity to 1e-8: E agrees to ~1e-9
    assert al.objective == pytest.approx(ipopt.objective, abs=1e-8)
    np.testing.assert_allclose(al.configurations, ipopt.configurations, atol=1e-6)


def test_clearance_is_checked_and_pickled(arm: RobotModel, tmp_path: Path) -> None:
    with pytest.raises(ParameterError, match="clearance must be a Clearance"):
        CyclicIKProblem(robot=arm, targets=TARGETS, clearance=0.1)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="leg_samples"):
        _problem(arm, _disc(1.2, 0.0), leg_samples=-1)
    problem = _problem(arm, _disc(1.2, 0.0))
    again = pickle.loads(pickle.dumps(problem))
    x = np.linspace(-1, 1, problem.n_variables)
    assert again.clearance == problem.clearance and again.leg_samples == problem.leg_samples
    assert problem.clearance_rows is not None and again.clearance_rows is not None
    np.testing.assert_allclose(again.clearance_rows.rows(x), problem.clearance_rows.rows(x))
    assert problem.with_targets(TARGETS[::-1]).clearance == problem.clearance


def test_generated_starts_may_collide_a_users_may_not(arm: RobotModel) -> None:
    """Start 0 (the zero vector: the stretched arm across the disc) is generated: solved."""
    problem = _problem(arm, _disc(1.2, 0.0, radius=0.5))
    inside = np.zeros(problem.n_variables)
    with pytest.raises(ParameterError, match=r"start configuration 0: link geometry"):
        solve(problem, method="ipopt", x0=inside)  # the user's start
    np.testing.assert_array_equal(problem.check_start(inside, generated=True), inside)
    np.testing.assert_array_equal(problem.check_start(None), problem.default_start())
    found = run_multistart(problem, method="ipopt", n_starts=3, starts="random", seed=0)
    assert found.n_starts == 3
    colliding = 0
    for result in found.results:
        try:
            problem.check_start(result.start)
        except ParameterError:
            colliding += 1
    assert colliding >= 1  # a generated start in collision was solved, not refused
    best = found.best.configurations.ravel()
    certificate = certify_path_clearance(problem, best)
    assert certificate is not None and certificate.certified
    with pytest.raises(ParameterError, match="general methods only"):
        run_multistart(problem, method="al", n_starts=2, starts="random", planar=True)


def test_multistart_by_the_augmented_lagrangian(arm: RobotModel) -> None:
    """``run_multistart(method="al")`` holds the rows; IPOPT from its best stays there."""
    problem = _problem(arm, _disc(1.2, 0.0))
    found = run_multistart(problem, method="al", n_starts=4, starts="random", seed=0)
    assert found.method == "al" and not found.planar and found.best.success
    x = found.best.configurations.ravel()
    assert problem.clearance_rows is not None
    assert np.min(problem.clearance_rows.rows(x)) >= MARGIN - 1e-10
    certificate = certify_path_clearance(problem, x)
    assert certificate is not None and certificate.certified
    ipopt = solve(problem, method="ipopt", x0=found.best.configurations)
    assert ipopt.status.name == "SOLVED", ipopt.message
    assert ipopt.objective == pytest.approx(found.best.objective, abs=1e-8)


def test_an_unpickled_problem_reuses_its_process_rows_only_for_an_equal_spec(
    arm: RobotModel,
) -> None:
    """Unpickling reuses rows built for an equal problem; a margin or scene change rebuilds."""
    base = _problem(arm, _disc(1.2, 0.0))
    other_margin = dataclasses.replace(
        base, clearance=Clearance(scene=_disc(1.2, 0.0), margin=0.05, self_collision=False)
    )
    other_scene = _problem(arm, _disc(1.3, 0.0))
    problems = (base, other_margin, other_scene)
    copies = [pickle.loads(pickle.dumps(p)) for p in problems]
    for p, q in zip(problems, copies, strict=True):
        assert q.clearance_rows is p.clearance_rows  # the process's rows, not rebuilt
        assert q.clearance == p.clearance
        assert pickle.loads(pickle.dumps(q)).clearance_rows is p.clearance_rows
    rows = {id(q.clearance_rows) for q in copies}
    assert len(rows) == 3  # margin and scene: each its own rows
    assert copies[1].clearance_rows.spec.margin == 0.05
    x = np.array([[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]]).ravel()
    assert not np.allclose(copies[0].clearance_rows.rows(x), copies[2].clearance_rows.rows(x))
    _BUILT_ROWS.clear()  # another process: the rows are rebuilt, equal
    fresh = pickle.loads(pickle.dumps(base))
    assert fresh.clearance_rows is not base.clearance_rows
    np.testing.assert_array_equal(fresh.clearance_rows.rows(x), base.clearance_rows.rows(x))


def test_a_rebuild_in_another_thread_does_not_lend_its_rows(arm: RobotModel) -> None:
    """The key of a problem being unpickled is per thread: a thread-pool executor may
    unpickle several problems at once, and one must not take the rows of another."""
    import threading

    from youbot_opt.ikpath import problem as problem_module

    base = _problem(arm, _disc(1.2, 0.0))
    other = _problem(arm, _disc(1.3, 0.0))
    pickle.dumps(base)  # base's rows are now in the process's cache under its key
    key = base._rows_key  # set by the pickling above
    inside, leave = threading.Event(), threading.Event()

    def unpickling_base() -> None:  # stands for a thread paused inside _rebuild_problem
        problem_module._REBUILDING.key = key
        inside.set()
        leave.wait(30)
        problem_module._REBUILDING.key = None

    thread = threading.Thread(target=unpickling_base)
    thread.start()
    try:
        assert inside.wait(30)
        built_here = dataclasses.replace(other)  # this thread builds other's own rows
    finally:
        leave.set()
        thread.join(30)
    assert built_here.clearance_rows is not base.clearance_rows
    assert built_here.clearance_rows.spec == other.clearance_rows.spec
