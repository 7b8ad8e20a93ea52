"""The two worked examples of study 2 (spec ``ikpath.md``, "Examples and figures").

* Example A: ``l = (3, 2, 2)`` without joint limits, targets (5, 0), (4, 2),
  (6, 0.5), (4, -2), (5, -1). The study reported ``E = 0.905`` from the zero
  initial guess.
* Example B: the same arm with ``|theta_i| <= pi/2``, targets (-1, 5), (-3, 3),
  (-3, -4), (0, 5), (3, 2). The study's limited solver violated the limits.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.targets import position_targets
from youbot_opt.robot.planar import PlanarChain

__all__ = ["EXAMPLES", "ExampleData", "STUDY_E_A", "example_problem"]

STUDY_E_A = 0.905
"""E reported by the study for example A from the zero initial guess [rad^2]."""


class ExampleData(NamedTuple):
    """Data of one example of the study.

    Attributes
    ----------
    lengths : tuple of float
        Link lengths in [m].
    limit : float or None
        Symmetric joint limit ``|theta_i| <= limit`` in [rad], or None.
    targets : tuple of (float, float)
        Targets in [m], in visiting order.
    """

    lengths: tuple[float, ...]
    limit: float | None
    targets: tuple[tuple[float, float], ...]


EXAMPLES: dict[str, ExampleData] = {
    "A": ExampleData(
        lengths=(3.0, 2.0, 2.0),
        limit=None,
        targets=((5.0, 0.0), (4.0, 2.0), (6.0, 0.5), (4.0, -2.0), (5.0, -1.0)),
    ),
    "B": ExampleData(
        lengths=(3.0, 2.0, 2.0),
        limit=math.pi / 2.0,
        targets=((-1.0, 5.0), (-3.0, 3.0), (-3.0, -4.0), (0.0, 5.0), (3.0, 2.0)),
    ),
}
"""Data of the study's examples: link lengths [m], symmetric joint limit [rad], targets [m]."""


def example_problem(name: str) -> CyclicIKProblem:
    """Return example ``"A"`` or ``"B"`` of the study as a problem.

    Raises
    ------
    ParameterError
        For another name.
    """
    key = str(name).upper()
    if key not in EXAMPLES:
        raise ParameterError(
            f"unknown example {name!r}; choose one of {', '.join(EXAMPLES)}",
            name="example",
            value=name,
        )
    data = EXAMPLES[key]
    limit = np.inf if data.limit is None else data.limit  # +-inf: unlimited
    chain = PlanarChain(
        lengths=np.array(data.lengths),
        q_lower=np.full(len(data.lengths), -limit),
        q_upper=np.full(len(data.lengths), limit),
        name=f"study2_example_{key}",
    )
    return CyclicIKProblem(robot=chain, targets=position_targets(data.targets))
