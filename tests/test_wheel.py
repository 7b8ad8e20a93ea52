"""The package as users get it: a wheel built from the tree works without the source tree."""

from __future__ import annotations

import json
import os
import site
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def wheel_env(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A wheel of the tree, installed into a fresh virtual environment (dependencies shared)."""
    pytest.importorskip("hatchling", reason="the test extras install the build backend")
    tmp = tmp_path_factory.mktemp("wheel")
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-w",
            str(tmp),
            str(ROOT),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stdout + out.stderr
    (wheel,) = tmp.glob("youbot_opt-*.whl")
    env_dir = tmp / "venv"
    python = _environment_sharing_dependencies(env_dir)
    out = subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps", str(wheel)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stdout + out.stderr
    return wheel, python


def _environment_sharing_dependencies(env_dir: Path) -> Path:
    """A fresh virtual environment that sees this interpreter's dependencies, not its package.

    `system_site_packages=True` would share the *base* interpreter's site-packages: when
    the tests run in a virtual environment (what the README tells users to use), the
    base interpreter has neither pinocchio nor casadi. Instead the new environment gets a
    `.pth` file that adds this interpreter's own site-packages with `site.addsitedir`, so
    their `.pth` files run too (the `pin` wheel is found through `cmeel.pth`). Those
    folders are appended after the environment's own site-packages, so the package comes
    from the wheel installed there, never from this interpreter's (editable) copy.
    """
    venv.EnvBuilder(system_site_packages=False, with_pip=False).create(env_dir)
    python = env_dir / "bin" / "python"
    purelib = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    ).stdout.strip()
    parents = [p for p in site.getsitepackages() if Path(p).is_dir()]
    lines = [f"import site; site.addsitedir({p!r})" for p in parents]
    (Path(purelib) / "_parent_site_packages.pth").write_text("\n".join(lines) + "\n")
    return python


def _clean_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["MPLBACKEND"] = "Agg"
    return env


@pytest.mark.slow
def test_wheel_carries_the_package_data(wheel_env):
    """The wheel holds every module of src/ plus the committed youBot URDF and py.typed."""
    wheel, _ = wheel_env
    names = set(zipfile.ZipFile(wheel).namelist())
    sources = {
        str(p.relative_to(ROOT / "src")) for p in (ROOT / "src" / "youbot_opt").rglob("*.py")
    }
    assert sources <= names, sorted(sources - names)
    assert "youbot_opt/_urdf/youbot_arm_planar.urdf" in names


@pytest.mark.slow
def test_installed_wheel_imports_and_runs_the_main_job(wheel_env, tmp_path):
    """`import youbot_opt` and the main job run from the installed wheel, not from src/."""
    _, python = wheel_env
    probe = (
        "import json, youbot_opt, youbot_opt.robot.catalogue as m;"
        "print(json.dumps([youbot_opt.__file__, str(m.youbot_urdf_path())]))"
    )
    out = subprocess.run(
        [str(python), "-c", probe],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=_clean_env(),
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    module_file, urdf = json.loads(out.stdout)
    venv_dir = str(python.parent.parent)
    assert module_file.startswith(venv_dir), module_file
    assert urdf.startswith(venv_dir) and Path(urdf).is_file(), urdf
    run = subprocess.run(
        [str(python), "-m", "youbot_opt", "main", "--out", str(tmp_path / "run")],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=_clean_env(),
        timeout=600,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert "solved" in run.stdout
    assert (tmp_path / "run" / "summary.json").is_file()
