"""Package-level checks: import, version, exception tree, CLI entry point."""

from __future__ import annotations

import subprocess
import sys

import youbot_opt
from youbot_opt import exceptions


def test_version_is_exposed() -> None:
    """The package exposes a PEP 440 version string."""
    assert youbot_opt.__version__.count(".") == 2


def test_every_error_derives_from_base() -> None:
    """Every exported exception class is catchable as YoubotOptError."""
    for name in exceptions.__all__:
        cls = getattr(exceptions, name)
        if name != "YoubotOptWarning":
            assert issubclass(cls, youbot_opt.YoubotOptError), name


def test_cli_help_runs() -> None:
    """`python -m youbot_opt --help` exits 0 and lists the commands."""
    out = subprocess.run(
        [sys.executable, "-m", "youbot_opt", "--help"], capture_output=True, text=True, check=True
    )
    assert "youbot-opt" in out.stdout


def test_lazy_public_names_resolve_and_are_exported() -> None:
    """Every lazily imported name is in ``__all__`` and resolves to the object of its module."""
    import importlib

    import youbot_opt

    for name, module in youbot_opt._LAZY.items():
        assert name in youbot_opt.__all__
        assert getattr(youbot_opt, name) is getattr(importlib.import_module(module), name)
    assert set(youbot_opt.__all__) <= set(dir(youbot_opt))
