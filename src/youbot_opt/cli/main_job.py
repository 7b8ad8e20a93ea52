"""``youbot-opt main``: the README's main job (placeholder-free: prints the package version).

Replaced as features land: it grows into the study-1 base-case solve.
"""

from __future__ import annotations

import argparse

from youbot_opt import __version__


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``main`` sub-command."""
    p = sub.add_parser("main", help="run the main job (the study-1 base case)")
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    print(f"youbot_opt {__version__}")
    return 0
