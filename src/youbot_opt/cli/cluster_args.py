"""The ``--scheduler`` / ``--scheduler-file`` / ``--shard`` flags of every sweeping command.

A sweep given either flag runs its items on that Dask cluster instead of the
local process pool (``pip install youbot_opt[dask]``; guide:
``docs/scaling.md``). :func:`add_scheduler_args` adds the two exclusive
flags and ``--shard I/K`` (a share of the items, for plain job arrays) to a
parser; :func:`scheduler_address` turns them into the address a sweep
connects to (``None`` when neither flag is given); :func:`report_shard`
prints what a shard run did.

    sweep = SweepOptions(executor=scheduler_address(args) or "process", out=folder)
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.scheduler import (
    check_scheduler_address,
    is_scheduler_address,
    read_scheduler_file,
)

if TYPE_CHECKING:  # the sweep modules are imported by the commands that run one
    from youbot_opt.sweeps.resume import ShardReport

__all__ = [
    "add_keep_results_arg",
    "add_scheduler_args",
    "int_in_range",
    "out_arg",
    "report_shard",
    "scheduler_address",
    "shard_arg",
]


def report_shard(report: ShardReport) -> int:
    """Print what a ``--shard I/K`` run did (on stderr) and return its exit status, 0.

    A shard that solved its share is a success; the message says how many of
    the sweep's items are finished and how to collect them.
    """
    print(f"youbot-opt: {report}", file=sys.stderr)
    return 0


def shard_arg(text: str) -> tuple[int, int]:
    """Parse ``--shard I/K`` (``1 <= I <= K``) into ``(I, K)``.

    Raises
    ------
    argparse.ArgumentTypeError
        If ``text`` is not two integers ``I/K`` with ``1 <= I <= K``.
    """
    try:
        i, k = (int(x) for x in text.split("/"))
    except ValueError:
        i = k = 0
    if not 1 <= i <= k:
        raise argparse.ArgumentTypeError(f"expected I/K with 1 <= I <= K, e.g. 2/8; got {text!r}")
    return i, k


#: Largest ``--max-iter``: IPOPT stores its iteration cap in a 32-bit int.
MAX_ITER_LIMIT = 2**31 - 1
#: Largest ``--seed``: NumPy's legacy seeds (the spline guesses) are 32-bit.
SEED_LIMIT = 2**32 - 1


def int_in_range(flag: str, lo: int, hi: int) -> Callable[[str], int]:
    """Return an argparse ``type`` for an int in ``lo..hi`` (errors name flag, value, range)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{flag} must be an integer in {lo}..{hi}, got {text!r}"
            ) from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"{flag} must be in {lo}..{hi}, got {value}")
        return value

    return parse


def out_arg(text: str) -> str:
    """Parse ``--out DIR``: any path but the empty one (which would mean the current folder).

    Raises
    ------
    argparse.ArgumentTypeError
        If ``text`` is empty or only spaces.
    """
    if not text.strip():
        raise argparse.ArgumentTypeError(
            "must name a folder, got an empty path (use --out . for the current folder)"
        )
    return text


def add_scheduler_args(p: argparse.ArgumentParser, *, shard: bool = True) -> None:
    """Add ``--scheduler`` / ``--scheduler-file`` (mutually exclusive) and ``--shard`` to ``p``.

    ``shard=False`` leaves ``--shard`` out (a command whose sweep keeps no store).
    """
    g = p.add_mutually_exclusive_group()
    g.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run the items on this Dask scheduler, e.g. tcp://10.0.0.5:8786 "
        "(needs youbot_opt[dask]; see docs/scaling.md)",
    )
    g.add_argument(
        "--scheduler-file",
        default=None,
        metavar="FILE",
        help="run the items on the Dask scheduler described by FILE "
        "(written by 'dask scheduler --scheduler-file FILE' or dask-jobqueue)",
    )
    if not shard:
        return
    p.add_argument(
        "--shard",
        type=shard_arg,
        default=None,
        metavar="I/K",
        help="solve only share I of K (items I, I+K, ...) into --out and stop; a job array "
        "runs the K shards into one folder, then a run without --shard collects",
    )


def add_keep_results_arg(p: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """Add ``--keep-results/--no-keep-results`` (``SweepOptions.keep_results``, default keep)."""
    p.add_argument(
        "--keep-results",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="hold every start's result in memory (default); --no-keep-results holds only "
        "the best and the distinct optima, the other starts stay in the run folder "
        "(for 10^4+ starts; see docs/scaling.md)",
    )


def scheduler_address(args: argparse.Namespace) -> str | None:
    """Return the scheduler address named by the flags (``None``: neither flag given).

    A scheduler file is read for its ``address``; the sweep connects (and
    disconnects) itself, so the address is all a command passes on as
    ``SweepOptions(executor=...)``.

    Raises
    ------
    ParameterError
        If the file is missing, not a regular file, too large or names no
        address, the address is not sane (see
        :func:`~youbot_opt.sweeps.scheduler.check_scheduler_address`), or
        ``--workers 0`` / ``--item-timeout`` is combined with a scheduler.
    """
    address = getattr(args, "scheduler", None)
    path = getattr(args, "scheduler_file", None)
    if address is None and path is None:
        return None
    if getattr(args, "workers", None) == 0:
        raise ParameterError(
            "--workers 0 (in-process) cannot be combined with --scheduler/--scheduler-file",
            name="workers",
        )
    if getattr(args, "item_timeout", None) is not None:
        raise ParameterError(
            "--item-timeout needs local worker processes; it cannot be combined with "
            "--scheduler/--scheduler-file",
            name="item_timeout",
        )
    if path is not None:
        return read_scheduler_file(path, name="scheduler_file")
    if not is_scheduler_address(address):
        raise ParameterError(
            f"--scheduler must be an address such as tcp://10.0.0.5:8786, got {address!r}",
            name="scheduler",
        )
    return check_scheduler_address(address, name="scheduler")
