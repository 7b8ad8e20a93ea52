"""Run ``youbot-opt`` with every sweep item slowed by a fixed sleep (the kill tests).

Usage: ``python tests/_slow_cli.py SECONDS COMMAND ARGS...``; ``tests/`` must be
on ``PYTHONPATH`` so pool workers can load :class:`_faults.Slow`.
"""

from __future__ import annotations

import sys

from _faults import slow_every_item

if __name__ == "__main__":
    slow_every_item(float(sys.argv[1]))
    from youbot_opt.cli import main

    sys.exit(main(sys.argv[2:]))
