"""The size of a command-line run (memory, IK chain, sweep values), checked before it is built.

``solve --knots 10000000`` used to die in ``std::bad_alloc`` after 8.7 s and
``ikpath --starts 1000000000`` to try to allocate 112 GiB. The commands now
estimate the memory a run needs from its sizes first and refuse, with exit
code 2, a run that would need more than :func:`memory_limit` (the machine's
memory; set ``YOUBOT_OPT_MEMORY_LIMIT_GB`` to change it), saying how much it
would take. The IK chain length is limited by :data:`MAX_IK_LINKS`
(``YOUBOT_OPT_MAX_IK_LINKS``). The per-unit figures are measured upper
bounds with a margin (docs: the constants below).

Example: ``check_trajopt_size(n_knots=10_000_000, nq=3)`` raises ParameterError.
"""

from __future__ import annotations

import os
import re

from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.urdf_check.xml import limit

__all__ = [
    "BYTES_PER_IK_START",
    "BYTES_PER_KNOT_JOINT",
    "BYTES_PER_START",
    "MAX_IK_LINKS",
    "MAX_SWEEP_VALUES",
    "check_ikpath_size",
    "check_sweep_values",
    "check_trajopt_size",
    "memory_limit",
]

#: Memory of the trajectory NLP per knot and joint, in [bytes]: building it
#: measured 21-30 kB (planar youBot, 3 joints, 500-2000 knots, resident set
#: growth); doubled for IPOPT's factorisation and iterates.
BYTES_PER_KNOT_JOINT: int = 64 * 1024
#: Memory a multistart keeps per start besides its trajectory, in [bytes]
#: (status, statistics, sweep bookkeeping).
BYTES_PER_START: int = 4096
#: Memory an IK-path multistart keeps per start besides its path, in [bytes].
BYTES_PER_IK_START: int = 4096
#: Most links of a planar IK chain (the study's arms have 3 to 5; the exact
#: reachability test branches over every link).
#: Environment variable: ``YOUBOT_OPT_MAX_IK_LINKS``.
MAX_IK_LINKS: int = 100
#: Most values of a ``start:stop:step`` sweep (``--betas``, ``--scales``); each
#: is at least one full solve. Environment variable: ``YOUBOT_OPT_MAX_SWEEP_VALUES``.
MAX_SWEEP_VALUES: int = 10_000
_GIB = 2**30


def memory_limit() -> tuple[int, str]:
    """Return the memory a run may use in [bytes] and where the figure comes from.

    Returns
    -------
    tuple of (int, str)
        ``YOUBOT_OPT_MEMORY_LIMIT_GB`` (in GiB) if set, else the machine's
        physical memory; and a phrase naming the source for messages.

    Raises
    ------
    ParameterError
        If ``YOUBOT_OPT_MEMORY_LIMIT_GB`` is not a positive number.
    """
    text = os.environ.get("YOUBOT_OPT_MEMORY_LIMIT_GB", "").strip()
    if text:
        if not re.fullmatch(r"[0-9]{1,9}(\.[0-9]{0,9})?", text) or float(text) <= 0:
            raise ParameterError(
                f"YOUBOT_OPT_MEMORY_LIMIT_GB={text[:40]!r} is not a positive number of GiB",
                name="YOUBOT_OPT_MEMORY_LIMIT_GB",
            )
        return int(float(text) * _GIB), "YOUBOT_OPT_MEMORY_LIMIT_GB"
    try:
        total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError):  # not on this platform
        total = 8 * _GIB
    return int(total), "this machine's memory; set YOUBOT_OPT_MEMORY_LIMIT_GB to change it"


def _size(n_bytes: float) -> str:
    for unit, scale in (("TiB", 2**40), ("GiB", _GIB), ("MiB", 2**20)):
        if n_bytes >= scale:
            return f"{n_bytes / scale:,.1f} {unit}"
    return f"{n_bytes / 1024:,.1f} KiB"


def _refuse(what: str, need: float, detail: str, name: str) -> None:
    budget, source = memory_limit()
    if need > budget:
        raise ParameterError(
            f"{what} would need about {_size(need)} of memory ({detail}), more than the "
            f"limit of {_size(budget)} ({source})",
            name=name,
        )


def check_trajopt_size(*, n_knots: int, nq: int, n_starts: int = 1, max_knots: int = 0) -> None:
    """Refuse a trajectory optimisation whose estimated memory exceeds :func:`memory_limit`.

    Parameters
    ----------
    n_knots : int
        Knots of the first grid (``--knots``).
    nq : int
        Joints of the robot.
    n_starts : int
        Starts of a multistart (1 for one solve).
    max_knots : int
        Largest grid mesh refinement may build (``--max-knots``; 0 without refinement).

    Raises
    ------
    ParameterError
        Saying how much memory the run would take and the limit.
    """
    option = "--max-knots" if max_knots > n_knots else "--knots"
    largest = max(n_knots, max_knots)
    nlp = float(largest) * nq * BYTES_PER_KNOT_JOINT
    _refuse(
        f"{option} {largest:,} with {nq} joints",
        nlp,
        f"{BYTES_PER_KNOT_JOINT // 1024} KiB per knot and joint",
        option.lstrip("-").replace("-", "_"),
    )
    per_start = BYTES_PER_START + 8.0 * n_knots * (3 * nq + 2)  # q, v, tau and times per knot
    _refuse(
        f"--starts {n_starts:,} of {n_knots:,} knots",
        nlp + n_starts * per_start,
        f"the NLP plus {_size(per_start)} per start",
        "starts",
    )


def check_ikpath_size(*, n_starts: int, n_links: int, n_targets: int) -> None:
    """Refuse an IK-path run with too long a chain or too many starts for the memory.

    Parameters
    ----------
    n_starts : int
        ``--starts``.
    n_links : int
        Links of the planar chain (0 when not given on the command line).
    n_targets : int
        Tip targets (0 when not given on the command line; 5 is assumed).

    Raises
    ------
    ParameterError
        Naming the limit and how to raise it, or the memory the run would take.
    """
    links_limit = limit("MAX_IK_LINKS", MAX_IK_LINKS)
    if n_links > links_limit:
        raise ParameterError(
            f"--lengths gives {n_links:,} links, more than the limit of {links_limit:,} "
            "(raise it with the environment variable YOUBOT_OPT_MAX_IK_LINKS)",
            name="lengths",
        )
    path_floats = max(n_links, 3) * max(n_targets, 5)  # one configuration per target
    per_start = BYTES_PER_IK_START + 8.0 * 4 * path_floats  # start, path, multipliers, copy
    _refuse(
        f"--starts {n_starts:,}",
        n_starts * per_start,
        f"{_size(per_start)} per start",
        "starts",
    )


def check_sweep_values(count: float, option: str) -> None:
    """Refuse a ``start:stop:step`` sweep with more than :data:`MAX_SWEEP_VALUES` values.

    Parameters
    ----------
    count : float
        Number of values, ``(stop - start) / step + 1``, before any array is made.
    option : str
        The option's name without dashes (``"betas"``), for the message.

    Raises
    ------
    ParameterError
        Naming the count, the limit and how to raise it.
    """
    values_limit = limit("MAX_SWEEP_VALUES", MAX_SWEEP_VALUES)
    if count > values_limit:
        raise ParameterError(
            f"--{option} gives {count:,.0f} values, more than the limit of {values_limit:,} "
            "(raise it with the environment variable YOUBOT_OPT_MAX_SWEEP_VALUES)",
            name=option,
        )
