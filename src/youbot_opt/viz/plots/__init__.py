"""Matplotlib figures of trajectory solves and of the study-1 sweeps.

Every function returns a new Figure made without pyplot (headless, no global
state). One solve: :mod:`youbot_opt.viz.plots.trajopt`; sweeps
(:func:`plot_multistart`, :func:`plot_pareto`, :func:`plot_bound_scaling`):
:mod:`youbot_opt.viz.plots.studies`; IK paths of study 2:
:mod:`youbot_opt.viz.plots.ikpath`.

The names of ``__init__.pyi`` are imported on first use (``lazy_loader``), so
drawing one solve does not import the sweeps' figures.

>>> plot_trajectory(result).savefig("trajectory.png")  # doctest: +SKIP
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
