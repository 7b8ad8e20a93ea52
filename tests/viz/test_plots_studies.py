"""Figures of the study-1 sweeps (youbot_opt.viz.plots.studies), drawn headless from real sweeps.

The artists are read back and compared with the sweep results they show:
histogram counts and optimum counts, the front's points and dominance marks,
each scale's curves and its bounds at scale x data sheet.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.bound_scaling import bound_scaling_study
from youbot_opt.trajopt.multistart import MultistartResult, run_multistart
from youbot_opt.trajopt.pareto import ParetoFront, dominated_mask, pareto_sweep
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.viz.plots import plot_bound_scaling, plot_multistart, plot_pareto

N_KNOTS = 20  # small problem: at 20 knots, seed 0, four starts reach three distinct optima


@pytest.fixture(scope="module")
def solver(study1_solver: TrajOptSolver) -> TrajOptSolver:
    """The session's 20-knot study-1 solver (conftest), built once for all modules."""
    assert study1_solver.problem.n_knots == N_KNOTS
    return study1_solver


@pytest.fixture(scope="module")
def multistart(solver) -> MultistartResult:
    """Four seeded spline starts at beta = 0.5 (the study's kind of multistart)."""
    return run_multistart(solver, 4, beta=0.5, seed=0, sweep=SweepOptions(executor="serial"))


def _render(fig) -> None:
    FigureCanvasAgg(fig).draw()


def test_plot_multistart_counts_starts_and_optima(multistart):
    """Histogram bars add up to the converged starts; one bar and one line per optimum."""
    fig = plot_multistart(multistart)
    _render(fig)
    hist, bars = fig.axes
    converged = multistart.converged
    heights = [p.get_height() for p in hist.patches]
    assert sum(heights) == len(converged) > 0
    optima = sorted(multistart.distinct_optima(), key=lambda o: o.objective)
    lines = [line for line in hist.get_lines() if line.get_label().startswith("optimum")]
    assert [line.get_label() for line in lines] == [f"optimum {i + 1}" for i in range(len(optima))]
    np.testing.assert_array_equal([line.get_xdata()[0] for line in lines],
                                  [o.objective for o in optima])  # fmt: skip
    assert [p.get_height() for p in bars.patches] == [o.count for o in optima]
    assert sum(o.count for o in optima) == len(converged)
    labels = [t.get_text() for t in bars.get_xticklabels()]
    for i, (label, opt) in enumerate(zip(labels, optima, strict=True)):
        assert label.startswith(f"{i + 1}: f = {opt.objective:.6g}\nT = {opt.duration:.4g} s")
    title = fig._suptitle.get_text()
    assert f"{multistart.n_starts} starts" in title and f"{len(optima)} distinct" in title
    # marking fewer optima than found says how many are left out
    fig = plot_multistart(multistart, max_marked=1)
    assert len(fig.axes[1].patches) == 1
    if len(optima) > 1:
        assert f"{len(optima) - 1} more not marked" in fig._suptitle.get_text()


def test_plot_multistart_without_a_converged_start_raises(multistart):
    """A multistart where nothing converged has nothing to draw."""
    none = replace(multistart, starts=tuple(replace(s, success=False) for s in multistart.starts))
    with pytest.raises(ParameterError, match="no start of the multistart converged"):
        plot_multistart(none)


def test_plot_pareto_shows_the_front_and_marks_dominated_points(solver):
    """Non-dominated points joined by duration, dominated ones as crosses, betas labelled."""
    front = pareto_sweep(solver, (0.2, 0.5, 0.8), sweep=SweepOptions(executor="serial"))
    assert all(p.success for p in front.points)
    # Add a point with the middle point's duration and 10 % more work: dominated by it.
    extra = replace(front.points[1], beta=0.55, work=1.1 * front.points[1].work)
    points = [*front.points, extra]
    mask = dominated_mask([p.duration for p in points], [p.work for p in points])
    assert list(mask) == [False, False, False, True]
    marked = ParetoFront(
        points=tuple(replace(p, dominated=bool(d)) for p, d in zip(points, mask, strict=True))
    )
    fig = plot_pareto(marked)
    _render(fig)
    ax = fig.axes[0]
    lines = {line.get_label(): line for line in ax.get_lines()}
    best = sorted(front.points, key=lambda p: p.duration)
    np.testing.assert_array_equal(lines["non-dominated"].get_xdata(), [p.duration for p in best])
    np.testing.assert_array_equal(lines["non-dominated"].get_ydata(), [p.work for p in best])
    np.testing.assert_array_equal(lines["dominated"].get_xdata(), [extra.duration])
    np.testing.assert_array_equal(lines["dominated"].get_ydata(), [extra.work])
    (scatter,) = ax.collections
    np.testing.assert_array_equal(scatter.get_offsets(), [[p.duration, p.work] for p in best])
    np.testing.assert_array_equal(scatter.get_array(), [p.beta for p in best])  # colour = beta
    annotations = {t.get_text() for t in ax.texts}
    assert {"$\\beta$=0.2", "$\\beta$=0.8"} <= annotations  # the two ends are always labelled
    assert "[s]" in ax.get_xlabel() and "m$^2$ s]" in ax.get_ylabel()
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["non-dominated", "dominated"]
    assert "1 dominated" in ax.get_title()
    failed = ParetoFront(points=tuple(replace(p, success=False) for p in front.points))
    with pytest.raises(ParameterError, match="no point of the Pareto sweep converged"):
        plot_pareto(failed)


def test_plot_bound_scaling_overlays_each_scale_with_its_bounds(solver):
    """Each panel holds every scale's curve and its bounds at scale x data sheet."""
    study = bound_scaling_study(
        solver, (1.0, 0.9), beta=0.5, n_starts=0, sweep=SweepOptions(executor="serial")
    )
    fig = plot_bound_scaling(study)
    _render(fig)
    robot = solver.problem.robot
    nv = robot.nv
    assert len(fig.axes) == 3 * nv
    limits = {"q": robot.q_upper, "v": robot.velocity_limit, "tau": robot.effort_limit}
    for row in study.rows:
        res = row.best.result
        s = f"{row.bound_scale:g}"
        for r, key in enumerate(("q", "v", "tau")):
            for j in range(nv):
                ax = fig.axes[r * nv + j]
                lines = {line.get_label(): line for line in ax.get_lines()}
                np.testing.assert_array_equal(lines[f"scale {s}"].get_xdata(), res.trajectory.t)
                np.testing.assert_array_equal(
                    lines[f"scale {s}"].get_ydata(), getattr(res.trajectory, key)[:, j]
                )
                upper = lines[f"_bound scale {s} upper"].get_ydata()[0]
                assert upper == pytest.approx(row.bound_scale * limits[key][j], rel=1e-12)
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert [text.split(":")[0] for text in legend] == ["100% bounds", "90% bounds"]
    assert all("N$^2$ m$^2$ s" in text for text in legend)
    assert [fig.axes[j].get_title() for j in range(nv)] == list(robot.joint_names)
