"""Whether each target of a cyclic IK path can be reached, decided before solving.

:mod:`.planar` gives exact verdicts for planar chains (with a witness or a
certificate; :mod:`.branch_and_bound` for 4+ links with limits); :mod:`.general`
decides 3-D targets by a witness, the reach sphere or the interval bounds of
:mod:`.interval`.

    from youbot_opt.ikpath.reachability.planar import check_reachability

The verdict, :class:`Reachability`, is one type for both.
"""

from enum import Enum

__all__ = ["Reachability"]


class Reachability(Enum):
    """Verdict on one target: reachable, unreachable, or undecided by the search's budget."""

    REACHABLE = "reachable"
    UNREACHABLE = "unreachable"
    UNDECIDED = "undecided"
