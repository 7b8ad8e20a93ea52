"""Matplotlib figures of trajectory solves and of the study-1 sweeps.

Every function returns a new Figure made without pyplot (headless, no global
state). One solve: :mod:`youbot_opt.viz.plots.trajopt`; sweeps
(:func:`plot_multistart`, :func:`plot_pareto`, :func:`plot_bound_scaling`):
:mod:`youbot_opt.viz.plots.studies`; IK paths of study 2:
:mod:`youbot_opt.viz.plots.ikpath`.

>>> plot_trajectory(result).savefig("trajectory.png")  # doctest: +SKIP
"""

from __future__ import annotations

from youbot_opt.viz.plots.studies import plot_bound_scaling, plot_multistart, plot_pareto
from youbot_opt.viz.plots.trajopt import plot_arm_2d, plot_convergence, plot_trajectory

__all__ = [
    "plot_trajectory",
    "plot_convergence",
    "plot_arm_2d",
    "plot_multistart",
    "plot_pareto",
    "plot_bound_scaling",
]
