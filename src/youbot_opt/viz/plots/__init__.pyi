"""Public names of :mod:`youbot_opt.viz.plots`, listed once (read by ``lazy_loader``)."""

from .studies import (
    plot_bound_scaling as plot_bound_scaling,
    plot_multistart as plot_multistart,
    plot_pareto as plot_pareto,
)
from .trajopt import (
    plot_arm_2d as plot_arm_2d,
    plot_convergence as plot_convergence,
    plot_trajectory as plot_trajectory,
)
