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
    """Every name of the public face (``__init__.pyi``, read with ast here) is in ``__all__``,
    listed once, and resolves to the object of the module the stub names; importing the
    package imports neither Pinocchio nor CasADi."""
    import ast
    import importlib
    import subprocess
    import sys
    from pathlib import Path

    import youbot_opt

    stub = Path(youbot_opt.__file__).with_suffix(".pyi")
    names: list[tuple[str, str]] = []
    for node in ast.parse(stub.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.ImportFrom):
            assert node.level == 1 and node.module, ast.dump(node)
            names += [(alias.name, f"youbot_opt.{node.module}") for alias in node.names]
    listed = [name for name, _ in names]
    assert len(listed) == len(set(listed)), "a public name is listed twice"
    assert sorted(listed) == sorted(youbot_opt.__all__)
    for name, module in names:
        assert getattr(youbot_opt, name) is getattr(importlib.import_module(module), name)
    assert set(youbot_opt.__all__) <= set(dir(youbot_opt))
    code = "import sys, youbot_opt; print(sorted({'pinocchio', 'casadi'} & set(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def _readme() -> str:
    from pathlib import Path

    return (Path(__file__).resolve().parent.parent / "README.md").read_text(encoding="utf-8")


def test_ci_runs_exactly_the_readme_test_command() -> None:
    """.ci/run's command line is the README's test command, character for character."""
    import re
    from pathlib import Path

    quick_start = re.search(r"## Quick start.*?```bash\n(.*?)```", _readme(), re.DOTALL)
    assert quick_start is not None, "README has no Quick start bash block"
    lines = [ln for ln in quick_start.group(1).splitlines() if ln.strip()]
    assert len(lines) == 2, "the Quick start is exactly two commands"
    test_command = lines[1].split("#")[0].strip()
    ci = (Path(__file__).resolve().parent.parent / ".ci" / "run").read_text(encoding="utf-8")
    ci_commands = [
        ln.strip() for ln in ci.splitlines() if ln.strip() and not ln.lstrip().startswith("#")
    ]
    assert ci_commands[-1] == test_command


def test_readme_python_example_runs(tmp_path, monkeypatch) -> None:
    """The README's Python API example runs and prints what its comments claim."""
    import contextlib
    import io
    import re

    block = re.search(r"## Python API.*?```python\n(.*?)```", _readme(), re.DOTALL)
    assert block is not None
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(block.group(1), "README.md", "exec"), {})
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("SolveStatus.SOLVED 8.0997")  # HS, 50 knots, beta = 0.5
    assert lines[1] == "True"  # the certificate passes
    assert lines[2] == "19"
    assert lines[3].startswith("SolveStatus.SOLVED 0.8405")
    assert (tmp_path / "replay.html").stat().st_size > 100_000
