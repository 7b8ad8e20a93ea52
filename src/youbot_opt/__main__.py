"""Allow ``python -m youbot_opt``: the same as the ``youbot-opt`` command."""

from youbot_opt.cli import main

raise SystemExit(main())
