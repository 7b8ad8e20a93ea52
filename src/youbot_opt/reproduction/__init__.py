"""Reproduction of study 1, both halves (spec ``trajopt.md``), kept out of the main API.

:mod:`~youbot_opt.reproduction.study1` (the study's transcription and problem),
:mod:`~youbot_opt.reproduction.records`, :mod:`~youbot_opt.reproduction.runs`
(:func:`reproduce_study1`), :mod:`~youbot_opt.reproduction.study_guess` and
:mod:`~youbot_opt.reproduction.search` (the study's starts, its second
optimum), :mod:`~youbot_opt.reproduction.report` (tables) and
:mod:`~youbot_opt.reproduction.figures`.

Names of ``__init__.pyi`` are imported on first use (``lazy_loader``).
Command line: ``youbot-opt reproduce-study1 [--quick] [--out DIR]``.
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
