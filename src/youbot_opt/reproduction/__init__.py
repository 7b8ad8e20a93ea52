"""Reproduction of study 1, both halves (spec ``trajopt.md``), kept out of the main API.

* :mod:`~youbot_opt.reproduction.study1` -- the study's own transcription with
  its four deviations, each switchable (:class:`StudyTranscription`,
  :class:`StudyDeviations`);
* :mod:`~youbot_opt.reproduction.runs` -- :func:`reproduce_study1`: base case,
  deviations one at a time, weight extremes, Pareto front and refinement, for
  the study's and the correct transcriptions, every solution certified;
* :mod:`~youbot_opt.reproduction.report` -- the comparison tables (markdown + JSON).

Command line: ``youbot-opt reproduce-study1 [--quick] [--out DIR]``.
"""

from __future__ import annotations

from youbot_opt.reproduction.report import markdown_report, pareto_knee, write_report
from youbot_opt.reproduction.runs import (
    VARIANTS,
    ReproductionConfig,
    Study1Reproduction,
    Variant,
    ablation_variant,
    reproduce_study1,
)
from youbot_opt.reproduction.study1 import (
    DEVIATION_NAMES,
    STUDY_DAMPING,
    StudyDeviations,
    StudyTranscription,
)

__all__ = [
    "DEVIATION_NAMES",
    "STUDY_DAMPING",
    "VARIANTS",
    "ReproductionConfig",
    "Study1Reproduction",
    "StudyDeviations",
    "StudyTranscription",
    "Variant",
    "ablation_variant",
    "markdown_report",
    "pareto_knee",
    "reproduce_study1",
    "write_report",
]
