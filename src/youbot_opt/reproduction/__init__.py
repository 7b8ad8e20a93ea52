"""Reproduction of study 1, both halves (spec ``trajopt.md``), kept out of the main API.

:mod:`~youbot_opt.reproduction.study1` (the study's transcription and problem),
:mod:`~youbot_opt.reproduction.records`, :mod:`~youbot_opt.reproduction.runs`
(:func:`reproduce_study1`), :mod:`~youbot_opt.reproduction.study_guess` and
:mod:`~youbot_opt.reproduction.search` (the study's starts, its second
optimum), :mod:`~youbot_opt.reproduction.report` (tables) and
:mod:`~youbot_opt.reproduction.figures`.

Command line: ``youbot-opt reproduce-study1 [--quick] [--out DIR]``.
"""

from __future__ import annotations

from youbot_opt.reproduction.records import VARIANTS, Variant, ablation_variant
from youbot_opt.reproduction.report import ParetoPoint, markdown_report, pareto_knee, write_report
from youbot_opt.reproduction.runs import ReproductionConfig, Study1Reproduction, reproduce_study1
from youbot_opt.reproduction.search import cluster_optima, vertex_multistart
from youbot_opt.reproduction.study1 import (
    DEVIATION_NAMES,
    STUDY_DAMPING,
    StudyDeviations,
    StudyTranscription,
)
from youbot_opt.reproduction.study_guess import vertex_spline_guess

__all__ = [
    "DEVIATION_NAMES",
    "STUDY_DAMPING",
    "VARIANTS",
    "ParetoPoint",
    "ReproductionConfig",
    "Study1Reproduction",
    "StudyDeviations",
    "StudyTranscription",
    "Variant",
    "ablation_variant",
    "cluster_optima",
    "markdown_report",
    "pareto_knee",
    "reproduce_study1",
    "vertex_multistart",
    "vertex_spline_guess",
    "write_report",
]
