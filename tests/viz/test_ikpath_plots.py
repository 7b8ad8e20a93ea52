"""Plot functions draw what the result holds (Agg, no pyplot state)."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.colors import to_rgba

from youbot_opt.ikpath.examples import example_problem
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.solve import solve
from youbot_opt.robot.planar import PlanarChain
from youbot_opt.viz.plots.ikpath import plot_convergence, plot_path, plot_workspace


@pytest.fixture(scope="module")
def result():
    return solve(example_problem("B"))


def test_arm_path_draws_every_configuration(result):
    """One polyline per configuration, through the Pinocchio joint positions."""
    ax = plot_path(result).axes[0]
    arms = [line for line in ax.lines if line.get_label().startswith("q")]
    assert len(arms) == result.problem.n_targets
    pts = result.problem.chain.joint_positions(result.configurations[2])
    np.testing.assert_allclose(np.column_stack(arms[2].get_data()), pts, atol=1e-12)


def test_convergence_panels_follow_the_history(result):
    """Three panels with one point per outer iteration; E panel ends at the final E."""
    fig = plot_convergence(result)
    assert len(fig.axes) == 3
    e_line = fig.axes[1].lines[0]
    assert len(e_line.get_xdata()) == len(result.history)
    assert e_line.get_ydata()[-1] == pytest.approx(result.objective, abs=1e-12)


def test_workspace_marks_verdicts():
    """Targets are green when reachable, red when not, with a line to the nearest point."""
    chain = PlanarChain(lengths=[3, 2, 2], q_lower=-np.pi / 2, q_upper=np.pi / 2)
    prob = CyclicIKProblem(robot=chain, targets=[(0.0, 7.0), (0.0, 7.1)])
    ax = plot_workspace(prob).axes[0]
    markers = [ln for ln in ax.lines if ln.get_marker() == "x"]
    assert [to_rgba(m.get_color()) for m in markers] == [to_rgba("tab:green"), to_rgba("tab:red")]
    red_lines = [
        ln
        for ln in ax.lines
        if ln.get_marker() in ("None", "") and to_rgba(ln.get_color()) == to_rgba("tab:red")
    ]
    np.testing.assert_allclose(red_lines[0].get_xydata(), [[0.0, 7.1], [0.0, 7.0]], atol=1e-12)


def test_convergence_distance_panel_has_no_fake_points(result):
    """The distance panel plots |x_k - x*| exactly, omitting the final iterate (distance 0)."""
    ax = plot_convergence(result).axes[0]
    dist = [np.linalg.norm(h.x - result.configurations) for h in result.history]
    expected = [(h.iteration, d) for h, d in zip(result.history, dist, strict=True) if d > 0]
    assert dist[-1] == 0.0 and len(expected) < len(dist)
    line = ax.lines[0]
    np.testing.assert_array_equal(line.get_xdata(), [e[0] for e in expected])
    np.testing.assert_array_equal(line.get_ydata(), [e[1] for e in expected])
    assert any("distance 0" in t.get_text() for t in ax.texts)


def test_workspace_legend_names_every_verdict_colour():
    """The legend explains green/red/orange as reachable/unreachable/undecided."""
    prob = example_problem("B")
    legend = plot_workspace(prob).axes[0].get_legend()
    entries = {
        t.get_text(): h for t, h in zip(legend.get_texts(), legend.legend_handles, strict=True)
    }
    for verdict, color in (
        ("reachable", "tab:green"),
        ("unreachable", "tab:red"),
        ("undecided", "tab:orange"),
    ):
        assert to_rgba(entries[f"target: {verdict}"].get_color()) == to_rgba(color)


def test_one_plot_function_draws_a_3d_robot_in_3d():
    """plot_path on a robot that is not a planar chain: the frame's path in 3-D, targets marked."""
    from youbot_opt.ikpath.result import build_result
    from youbot_opt.ikpath.targets import Target
    from youbot_opt.nlp.status import SolveStatus
    from youbot_opt.robot.load import load_model

    robot = load_model("ur5")
    base = CyclicIKProblem(
        robot=robot, frame=robot.tip_frame, targets=(Target(position=(0, 0, 0)),) * 2
    )
    q = np.random.default_rng(1).uniform(-2, 2, (3, base.n_joints))
    problem = base.with_targets(
        tuple(Target(position=base.placement(theta).translation) for theta in q)
    )
    res = build_result(
        problem,
        method="al",
        status=SolveStatus.SOLVED,
        x=q.ravel(),
        multipliers=np.zeros(problem.n_constraints),
        iterations=1,
        wall_time=0.0,
        message="",
        start=q.ravel(),
    )
    ax = plot_path(res, samples_per_leg=5).axes[0]
    assert ax.name == "3d"
    x, y, z = ax.lines[0].get_data_3d()
    np.testing.assert_allclose(np.column_stack([x, y, z]), res.frame_path(5), atol=1e-12)
    assert [t.get_text() for t in ax.texts] == [" T1", " T2", " T3"]
