"""Figures of one trajectory solve (youbot_opt.viz.plots.trajopt), drawn headless from real solves.

Each test reads the artists back from the figure and compares them with the
result they were drawn from and with independent references (the data-sheet
limits times the bound scale, the planar tip formula of the study).
"""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from _analytic import tip_pose_analytic
from youbot_opt.exceptions import ParameterError
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.robot.params import YOUBOT_PLANAR
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.multistart import run_multistart
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.trajectory import Trajectory
from youbot_opt.viz.plots import plot_arm_2d, plot_convergence, plot_trajectory
from youbot_opt.viz.plots.trajopt import plan_times

N_KNOTS = 20  # small problem: the figures, not the study's numbers, are under test
SCALE = 0.9  # bound scale of the solve drawn (the bounds drawn must follow it)


@pytest.fixture(scope="module")
def solver(study1_solver: TrajOptSolver) -> TrajOptSolver:
    """The session's 20-knot study-1 solver (conftest), built once for all modules."""
    assert study1_solver.problem.n_knots == N_KNOTS
    return study1_solver


@pytest.fixture(scope="module")
def result(solver):
    """A converged solve at beta = 0.5 with every bound scaled by 0.9."""
    res = solver.solve(beta=0.5, bound_scale=SCALE)
    assert res.success
    return res


def _render(fig) -> None:
    """Draw the figure on an Agg canvas, as saving it would (layout and text included)."""
    FigureCanvasAgg(fig).draw()


def _lines(ax, prefix: str = "") -> dict[str, object]:
    """Lines of ``ax`` by label, those whose label starts with ``prefix``."""
    return {ln.get_label(): ln for ln in ax.get_lines() if ln.get_label().startswith(prefix)}


def test_plot_trajectory_draws_every_joint_and_the_scaled_bounds(result):
    """q, v, tau curves are the knots; dashed bounds sit at 0.9 x the data sheet."""
    fig = plot_trajectory(result)
    _render(fig)
    traj, robot = result.trajectory, result.problem.robot
    names = list(robot.joint_names)
    assert len(fig.axes) == 3
    limits = {  # data-sheet limits x scale: the reference, read from the robot model
        "q": (SCALE * robot.q_lower, SCALE * robot.q_upper),
        "v": (-SCALE * robot.velocity_limit, SCALE * robot.velocity_limit),
        "tau": (-SCALE * robot.effort_limit, SCALE * robot.effort_limit),
    }
    units = ("[rad]", "[rad/s]", "[N m]")
    for ax, key, unit in zip(fig.axes, ("q", "v", "tau"), units, strict=True):
        assert unit in ax.get_ylabel()
        curves = _lines(ax, "arm_joint")
        assert sorted(curves) == names
        for j, name in enumerate(names):
            np.testing.assert_array_equal(curves[name].get_xdata(), traj.t)
            np.testing.assert_array_equal(curves[name].get_ydata(), getattr(traj, key)[:, j])
        bounds = _lines(ax, "_bound")
        lo, hi = limits[key]
        if np.ptp(hi) == 0.0:  # the youBot's speed limits are equal: one grey pair of lines
            assert sorted(bounds) == [f"_bound {key} all lower", f"_bound {key} all upper"]
            assert bounds[f"_bound {key} all lower"].get_ydata()[0] == pytest.approx(lo[0])
            assert bounds[f"_bound {key} all upper"].get_ydata()[0] == pytest.approx(hi[0])
        else:  # one pair per joint, in the joint's colour
            assert len(bounds) == 2 * len(names)
            for j, name in enumerate(names):
                low, up = bounds[f"_bound {key} {name} lower"], bounds[f"_bound {key} {name} upper"]
                assert low.get_ydata()[0] == pytest.approx(lo[j], rel=1e-12)
                assert up.get_ydata()[0] == pytest.approx(hi[j], rel=1e-12)
                assert low.get_linestyle() == "--" and low.get_color() == curves[name].get_color()
    assert "[s]" in fig.axes[-1].get_xlabel()
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend == [*names, "bounds (90%)"]
    assert f"T = {result.duration:.3f} s" in fig.axes[0].get_title()


def test_plot_trajectory_of_a_bare_trajectory_and_bad_input(result):
    """A bare trajectory has no bounds and generic joint names; mismatched names raise."""
    traj = result.trajectory
    fig = plot_trajectory(traj)
    assert not _lines(fig.axes[0], "_bound")
    assert sorted(_lines(fig.axes[0], "joint")) == ["joint 1", "joint 2", "joint 3"]
    fig = plot_trajectory(result, show_bounds=False)
    assert not any(_lines(ax, "_bound") for ax in fig.axes)
    with pytest.raises(ParameterError, match="joint_names must have 3 entries"):
        plot_trajectory(result, joint_names=["a", "b"])
    with pytest.raises(ParameterError, match="expected a TrajOptResult or a Trajectory"):
        plot_trajectory(np.zeros((3, 3)))  # type: ignore[arg-type]


def test_plot_convergence_follows_each_runs_objective_history(solver, result):
    """One line per run through its IPOPT objectives; a failed run is dotted and ends in x."""
    failed = TrajOptSolver(study1_problem(N_KNOTS), options=IpoptOptions(max_iter=3)).solve()
    assert not failed.success
    fig = plot_convergence([result, failed])
    _render(fig)
    (ax,) = fig.axes
    ok_line, bad_line = ax.get_lines()
    np.testing.assert_array_equal(ok_line.get_ydata(), result.objective_history)
    np.testing.assert_array_equal(ok_line.get_xdata(), np.arange(result.iterations + 1))
    np.testing.assert_array_equal(bad_line.get_ydata(), failed.objective_history)
    assert (ok_line.get_linestyle(), ok_line.get_marker()) == ("-", "o")
    assert (bad_line.get_linestyle(), bad_line.get_marker()) == (":", "x")
    assert ax.get_yscale() == "log"
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert texts[0].endswith(f"f = {result.objective:.4f}")
    assert failed.status.value in texts[1]
    assert ax.get_title() == "Convergence of 2 runs (1 converged)"


def test_plot_convergence_of_a_multistart_uses_a_colour_bar_beyond_max_legend(solver):
    """More runs than max_legend: a colour bar numbers them and the legend counts the styles."""
    ms = run_multistart(
        solver, 3, beta=0.5, seed=0, include_straight=True, sweep=SweepOptions(executor="serial")
    )
    fig = plot_convergence(ms, max_legend=2)
    _render(fig)
    ax, bar = fig.axes
    assert len(ax.get_lines()) == ms.n_starts
    for line, start in zip(ax.get_lines(), ms.starts, strict=True):
        np.testing.assert_array_equal(line.get_ydata(), start.result.objective_history)
    assert [t.get_text() for t in ax.get_legend().get_texts()] == [f"converged ({ms.n_starts})"]
    assert bar.get_ylabel() == "start number"  # a multistart's runs are its starts
    with pytest.raises(ParameterError, match="no result with an objective history"):
        plot_convergence([])


def test_plot_arm_2d_draws_the_study_tip_positions(result):
    """Pose lines end at the tip of the study's planar formula; the tip path is dashed."""
    fig = plot_arm_2d(None, result, n_frames=4)
    _render(fig)
    ax = fig.axes[0]
    poses = [line for line in ax.get_lines() if str(line.get_gid()).startswith("pose")]
    assert len(poses) == 4
    traj = result.trajectory
    times = np.linspace(traj.t[0], traj.t[-1], 4)
    for line, time in zip(poses, times, strict=True):
        tip = tip_pose_analytic(YOUBOT_PLANAR, traj(time)).position  # platform (x, z) [m]
        # Pinocchio FK against the study's trigonometry: equal to rounding (1e-12 m).
        np.testing.assert_allclose([line.get_xdata()[-1], line.get_ydata()[-1]], tip, atol=1e-12)
    (path,) = [line for line in ax.get_lines() if line.get_label() == "tip path"]
    assert path.get_linestyle() == "--"
    start = tip_pose_analytic(YOUBOT_PLANAR, traj.q[0]).position
    np.testing.assert_allclose([path.get_xdata()[0], path.get_ydata()[0]], start, atol=1e-12)
    assert ax.get_xlabel() == "platform x [m]" and ax.get_ylabel() == "platform z [m]"
    with pytest.raises(ParameterError, match="plane must be two distinct axes"):
        plot_arm_2d(None, result, plane="xx")
    with pytest.raises(ParameterError, match="robot is required"):
        plot_arm_2d(None, Trajectory(t=traj.t, q=traj.q, v=traj.v, a=traj.a, tau=traj.tau))


def test_plot_convergence_title_of_one_run(result):
    """One run is "the solve" in the default title, not "1 run" (nor "1 runs")."""
    fig = plot_convergence([result])
    title = fig.axes[0].get_title()
    assert title == "Convergence of the solve (converged)"


def _round(index: int, errors: list[float], passed: bool | None, status: str = "solved"):
    """A refinement round on a uniform grid over 2 s with the given interval errors."""
    from youbot_opt.trajopt.refine import RefinementRound

    n = len(errors) + 1
    return RefinementRound(
        index=index, n_knots=n, status=status, objective=8.0 + 0.1 * index, duration=2.0,
        max_error=max(errors), t=np.linspace(0.0, 2.0, n), errors=np.array(errors),
        certificate_passed=passed, failures=(), feedback_rms=0.01, feedback_peak=0.02,
        local_position=1e-3, iterations=5 + index, solve_time=0.1, check_time=0.1,
        objective_history=np.linspace(9.0, 8.0 + 0.1 * index, 6 + index),
    )  # fmt: skip


@pytest.fixture(scope="module")
def refinement():
    """Three rounds as the main job's: cert. fails; error > tol but cert. passes; certified."""
    from youbot_opt.trajopt.refine import Refinement, RefinementBudget

    rounds = (
        _round(0, [5e-3, 1e-4, 1e-4, 4e-3], False),
        _round(1, [1e-4, 2e-3, 1e-4, 1e-4, 1e-4], True),
        _round(2, [1e-4, 9e-4, 5e-4, 1e-4, 1e-4, 1e-4], True),
    )
    budget = RefinementBudget(tolerance=1e-3)
    return Refinement(certified=True, reason="certified", budget=budget, rounds=rounds, elapsed=1)


def test_plot_refinement_labels_each_round_by_its_own_verdict(refinement):
    """Only a round within the tolerance with a passed certificate is called "certified"."""
    from youbot_opt.viz.plots.trajopt import plot_refinement

    fig = plot_refinement(refinement)
    _render(fig)
    labels = [t.get_text() for t in fig.axes[1].get_legend().get_texts()]
    assert labels[0].endswith("cert. fails")
    assert labels[1].endswith("error 0.002 > 0.001, cert. passes")
    assert labels[2].endswith("certified") and "certified" not in labels[0] + labels[1]
    assert labels[3] == "tolerance 0.001"


def test_plot_refinement_names_every_colour_in_a_legend(refinement):
    """The red split intervals have a legend entry, as the rounds and the tolerance do."""
    from matplotlib.colors import to_rgba

    from youbot_opt.viz.plots.trajopt import plot_refinement

    fig = plot_refinement(refinement)
    _render(fig)
    ax_grid = fig.axes[0]
    red = to_rgba("tab:red")
    split = [c for c in ax_grid.collections if tuple(c.get_colors()[0]) == red]
    assert sum(len(c.get_segments()) for c in split) == 3  # 2 in round 0, 1 in round 1
    legend = ax_grid.get_legend()
    assert legend is not None
    (text,) = [t.get_text() for t in legend.get_texts()]
    assert text == "interval error > 0.001: split in the next round"
    assert to_rgba(legend.get_lines()[0].get_color()) == red


def test_plot_convergence_of_a_refinement_shows_every_rounds_solve(refinement):
    """One line per round through its IPOPT objectives, integer iterations, titled by the rounds."""
    from youbot_opt.trajopt.refine import Refined

    for runs in (refinement, Refined(None, refinement)):  # type: ignore[arg-type]
        fig = plot_convergence(runs)
        _render(fig)
        (ax,) = fig.axes
        lines = ax.get_lines()
        assert len(lines) == len(refinement.rounds)
        for line, r in zip(lines, refinement.rounds, strict=True):
            np.testing.assert_array_equal(line.get_ydata(), r.objective_history)
            np.testing.assert_array_equal(line.get_xdata(), np.arange(r.objective_history.size))
        assert ax.get_title() == "Convergence of the solves of 3 refinement rounds (3 converged)"
        texts = [t.get_text() for t in fig.legends[0].get_texts()]
        assert texts[1] == "round 1 (6 knots): f = 8.1000"
        ticks = [t for t in ax.get_xticks() if ax.get_xlim()[0] <= t <= ax.get_xlim()[1]]
        assert ticks and all(float(t).is_integer() for t in ticks)


def test_plot_convergence_of_a_multistart_is_titled_by_its_starts(solver):
    """A multistart's figure counts starts, not runs."""
    ms = run_multistart(solver, 2, beta=0.5, seed=0, sweep=SweepOptions(executor="serial"))
    fig = plot_convergence(ms)
    n_ok = sum(s.result is not None and s.result.success for s in ms.starts)
    assert fig.axes[0].get_title() == f"Convergence of 2 starts ({n_ok} converged)"


def test_plot_refinements_overview_names_each_mark_and_the_failed_plan(refinement):
    """A study's overview: first and final knots, rounds, a not-certified plan named in red."""
    import dataclasses

    from matplotlib.colors import to_rgba

    from youbot_opt.viz.plots.trajopt import plot_refinements

    failed = dataclasses.replace(
        refinement, certified=False, reason="at most 2 rounds", rounds=refinement.rounds[:2]
    )
    fig = plot_refinements([refinement, failed], ["beta = 0.3", "beta = 0.7"])
    _render(fig)
    ax_k, ax_r = fig.axes
    assert ax_k.get_title() == (
        "mesh refinement of 2 plans: 1/2 certified\n"
        "(error tolerance 0.001, at most 8 rounds, 1000 knots, time limit none)"
    )
    first, ok, bad = ax_k.get_lines()
    np.testing.assert_array_equal(first.get_ydata(), [5, 5])  # round 0: 5 knots each
    np.testing.assert_array_equal(ok.get_xdata(), [0])
    np.testing.assert_array_equal(ok.get_ydata(), [7])  # certified in round 2: 7 knots
    np.testing.assert_array_equal(bad.get_xdata(), [1])
    np.testing.assert_array_equal(bad.get_ydata(), [6])  # stopped after round 1: 6 knots
    assert to_rgba(bad.get_color()) == to_rgba("tab:red")
    texts = [t.get_text() for t in ax_k.get_legend().get_texts()]
    assert texts == [
        "first round's knots",
        "final knots: certified",
        "final knots: NOT certified (beta = 0.7)",
    ]
    assert [p.get_height() for p in ax_r.patches] == [3, 2]  # rounds, certified bar first
    texts = [t.get_text() for t in ax_r.get_legend().get_texts()]
    assert texts == ["rounds: certified", "rounds: not certified"]
    assert [t.get_text() for t in ax_r.get_xticklabels()] == ["beta = 0.3", "beta = 0.7"]
    with pytest.raises(ParameterError, match="1 labels for 2 refinements"):
        plot_refinements([refinement, failed], ["beta = 0.3"])
    with pytest.raises(ParameterError, match="no refinement"):
        plot_refinements([], [])


def _inside_and_apart(fig) -> None:
    """Every axes (labels, ticks, titles) and legend drawn inside the canvas, none overlapping.

    An independent check of the figures' layout: the bounding boxes the
    renderer reports after drawing, in pixels (1 px of slack for rounding).
    """
    from matplotlib.transforms import Bbox

    _render(fig)
    renderer = fig.canvas.get_renderer()
    canvas = fig.bbox.padded(1.0)
    boxes = [(f"axes {k} ({ax.get_ylabel()!r})", ax.get_tightbbox(renderer))
             for k, ax in enumerate(fig.axes)]  # fmt: skip
    boxes += [(f"legend {k}", leg.get_window_extent(renderer)) for k, leg in enumerate(fig.legends)]
    for what, box in boxes:
        assert box is not None and Bbox.union([canvas, box]).bounds == canvas.bounds, (what, box)
    for a, (what_a, box_a) in enumerate(boxes):
        for what_b, box_b in boxes[a + 1 :]:
            inter = Bbox.intersection(box_a.padded(-1.0), box_b.padded(-1.0))
            assert inter is None or inter.width * inter.height < 1.0, (what_a, what_b)


def test_the_solve_figures_are_inside_the_canvas_and_apart(result, refinement):
    """The figures a solve writes: nothing clipped by the canvas, no label over another axes."""
    from youbot_opt.viz.plots.trajopt import plot_refinement

    for fig in (
        plot_trajectory(result),
        plot_arm_2d(None, result),
        plot_convergence([result]),
        plot_convergence(refinement),
        plot_refinement(refinement),
    ):
        _inside_and_apart(fig)


def test_plan_times_span_the_plan_evenly_with_at_least_its_ends():
    """plan_times: ``samples`` times from the first knot to the last, evenly spaced; >= 2."""
    z = np.zeros((3, 1))
    plan = Trajectory(t=[0.5, 0.9, 2.5], q=z, v=z, a=z, tau=z)
    np.testing.assert_array_equal(plan_times(plan, 5), [0.5, 1.0, 1.5, 2.0, 2.5])
    for samples in (1, 0, -3):
        np.testing.assert_array_equal(plan_times(plan, samples), [0.5, 2.5])
