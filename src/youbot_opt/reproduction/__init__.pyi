"""Public names of :mod:`youbot_opt.reproduction`, listed once (read by ``lazy_loader``)."""

from .records import (
    VARIANTS as VARIANTS,
    Variant as Variant,
    ablation_variant as ablation_variant,
)
from .report import (
    ParetoPoint as ParetoPoint,
    markdown_report as markdown_report,
    pareto_knee as pareto_knee,
    write_report as write_report,
)
from .runs import (
    ReproductionConfig as ReproductionConfig,
    Study1Reproduction as Study1Reproduction,
    reproduce_study1 as reproduce_study1,
)
from .search import cluster_optima as cluster_optima, vertex_multistart as vertex_multistart
from .study1 import (
    DEVIATION_NAMES as DEVIATION_NAMES,
    STUDY_DAMPING as STUDY_DAMPING,
    StudyDeviations as StudyDeviations,
    StudyTranscription as StudyTranscription,
)
from .study_guess import vertex_spline_guess as vertex_spline_guess
