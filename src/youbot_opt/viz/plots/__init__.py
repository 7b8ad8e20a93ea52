"""Matplotlib figures of trajectory solves and of the study-1 sweeps.

Every function takes a result object and returns a new
:class:`matplotlib.figure.Figure`, made without :mod:`matplotlib.pyplot` so
that it works headless (``MPLBACKEND=Agg``) and leaves no global state; save
it with ``fig.savefig("name.png")``, or let a notebook show it.

* One solve (:mod:`youbot_opt.viz.plots.trajopt`): :func:`plot_trajectory`
  (angles, speeds, torques with the bounds dashed), :func:`plot_convergence`
  (objective against IPOPT iteration for several starts) and
  :func:`plot_arm_2d` (the arm on its platform, stroboscopic).
* Sweeps (:mod:`youbot_opt.viz.plots.studies`): :func:`plot_multistart`,
  :func:`plot_pareto` and :func:`plot_bound_scaling`.

The IK-path figures of study 2 live in :mod:`youbot_opt.viz.plots.ikpath`.
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
