"""youbot_opt: Pinocchio-backed trajectory and IK-path optimisation with CasADi.

The public names are listed once, in ``__init__.pyi``; ``lazy_loader`` imports
each from its module on first access, so ``import youbot_opt`` (and the command
line's ``--help``) stays fast. Meshcat replay lives in :mod:`youbot_opt.viz`,
IK paths in :mod:`youbot_opt.ikpath`. See the README for a tour::

    import youbot_opt as yo
    result = yo.TrajOptSolver(yo.study1_problem(50)).solve(beta=0.5)
"""

import logging

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)

logging.getLogger(__name__).addHandler(logging.NullHandler())
