"""The clearance figure: the closest pair per group (each obstacle, self) and the margin (#28)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import matplotlib
import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.collision.clearance import Clearance
from youbot_opt.collision.scene import Obstacle, Scene
from youbot_opt.collision.shapes import Sphere
from youbot_opt.robot.load import load_model
from youbot_opt.trajopt.trajectory import Trajectory

matplotlib.use("Agg")


@pytest.fixture(autouse=True)
def _fit_cache(fit_cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Sphere fits are cached in a temporary folder during each test, never the user's."""
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(fit_cache))


def test_clearance_figure_names_the_closest_pair_per_group_and_the_margin():
    from youbot_opt.viz.plots.trajopt import plot_clearance

    ur5 = load_model("ur5")
    scene = Scene((Obstacle(name="ball", shape=Sphere(radius=0.05), xyz=(0.4, 0.3, 0.4)),))
    t = np.linspace(0.0, 1.0, 4)
    q0 = pin.neutral(ur5.model)
    q = np.outer(1 - t, q0) + np.outer(t, q0 + 0.5)
    zeros = np.zeros_like(q)
    result = SimpleNamespace(
        problem=SimpleNamespace(robot=ur5, clearance=Clearance(scene=scene, margin=0.02)),
        trajectory=Trajectory(t=t, q=q, v=zeros, a=zeros, tau=zeros),
    )
    fig = plot_clearance(result, samples=20)
    ax = fig.axes[0]
    labels = [text.get_text() for text in ax.get_legend().get_texts()]
    assert labels[-1] == "margin"
    ball, own = labels[0], labels[1]
    assert ball.startswith("ball: ") and " - ball, " in ball and ball.endswith(" s")
    assert own.startswith("self-collision: ") and "_link_0 - " in own
    (margin_line,) = [line for line in ax.get_lines() if line.get_label() == "margin"]
    assert margin_line.get_ydata()[0] == pytest.approx(0.02)
    curve = [line for line in ax.get_lines() if line.get_label() == ball][0]
    distance = float(ball.split(", ")[1].split(" m")[0])
    assert min(curve.get_ydata()) == pytest.approx(distance, rel=1e-2)  # 3 significant digits
