"""The numbered notebooks (01-11): stripped in git, narrative, and executed headless in quick mode.

Each notebook is executed with nbclient in a fresh ``python3`` kernel, with
``YOUBOT_QUICK=1`` (small studies) and a temporary working directory, so that
the replay files it writes never land in the repository. A cell error fails the
test; then the notebook's key outputs -- figures, replays and the numbers its
narrative talks about -- are checked.
"""

from __future__ import annotations

import ast
import base64
import html
import importlib.util
import json
import re
import time
from pathlib import Path
from typing import Any

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOK_DIR = ROOT / "notebooks"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("*.ipynb"))
EXPECTED = [
    "01_model_and_dynamics",
    "02_trajectory_solve",
    "03_studies",
    "04_ik_path",
    "05_other_robot",
    "06_your_robot",
    "07_spatial_ik_path",
    "08_arm_in_a_cell",
    "09_payload_and_export",
    "10_tool_constraints",
    "11_timed_waypoints",
]
CELL_TIMEOUT = 300  # [s] per cell; quick-mode cells take < 30 s on 2 busy cores
MIN_PROSE_WORDS = 250  # words of markdown prose per notebook, formulas and code excluded
PLACEHOLDERS = re.compile(r"\b(TODO|TBD|FIXME|XXX|lorem ipsum)\b", re.IGNORECASE)


def _strip_module() -> Any:
    """Import scripts/strip_notebooks.py (scripts/ is not a package)."""
    spec = importlib.util.spec_from_file_location(
        "strip_notebooks", ROOT / "scripts" / "strip_notebooks.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


strip_notebooks = _strip_module()


def _read(path: Path) -> Any:
    return nbformat.read(path, as_version=4)


def _ids(paths: list[Path]) -> list[str]:
    return [p.stem for p in paths]


# ------------------------------------------------------------------ in git
def test_the_numbered_notebooks_exist() -> None:
    """notebooks/ holds exactly the numbered notebooks of EXPECTED."""
    assert [p.stem for p in NOTEBOOKS] == EXPECTED


@pytest.mark.parametrize("path", NOTEBOOKS, ids=_ids(NOTEBOOKS))
def test_committed_notebook_is_stripped(path: Path) -> None:
    """No outputs, no execution counts, no widget state or transient metadata."""
    assert strip_notebooks.problems(_read(path)) == []


def test_strip_script_strips_and_checks(tmp_path: Path) -> None:
    """strip_notebooks: --check flags outputs and widget state, stripping removes them, once."""
    nb = nbformat.v4.new_notebook()
    nb.metadata["widgets"] = {"state": {}}
    cell = nbformat.v4.new_code_cell("1 + 1", execution_count=3)
    cell.outputs = [
        nbformat.v4.new_output("execute_result", {"text/plain": "2"}, execution_count=3)
    ]
    cell.metadata["scrolled"] = True
    nb.cells = [nbformat.v4.new_markdown_cell("# title"), cell]
    path = tmp_path / "dirty.ipynb"
    nbformat.write(nb, path)

    found = strip_notebooks.problems(_read(path))
    assert found == [
        "notebook metadata: 'widgets'",
        "cell 1: 1 outputs",
        "cell 1: execution_count 3",
        "cell 1: metadata 'scrolled'",
    ]
    assert strip_notebooks.main(["--check", str(path)]) == 1
    assert strip_notebooks.strip_file(path) is True
    clean = _read(path)
    assert strip_notebooks.problems(clean) == []
    assert clean.cells[1].source == "1 + 1" and clean.cells[0].source == "# title"
    assert strip_notebooks.strip_file(path) is False  # idempotent
    assert strip_notebooks.main(["--check", str(path)]) == 0


# ------------------------------------------------------------- narrative
def _prose(markdown: str) -> str:
    """Markdown without display math, inline math and code."""
    text = re.sub(r"\$\$.*?\$\$", " ", markdown, flags=re.DOTALL)
    text = re.sub(r"\$[^$]*\$", " ", text)
    return re.sub(r"`[^`]*`", " ", text)


def _code(source: str) -> str:
    """Cell source without IPython magics, parseable as Python."""
    return "\n".join(
        "" if line.lstrip().startswith(("%", "!")) else line for line in source.splitlines()
    )


@pytest.mark.parametrize("path", NOTEBOOKS, ids=_ids(NOTEBOOKS))
def test_notebook_is_narrative(path: Path) -> None:
    """Title, parameters first, prose between the code, and no logic defined in cells."""
    nb = _read(path)
    cells = nb.cells
    number = path.stem.split("_")[0]
    assert cells[0].cell_type == "markdown" and cells[0].source.startswith(f"# {number} — ")
    assert cells[-1].cell_type == "markdown", "a notebook ends with its conclusion in prose"
    code = [c for c in cells if c.cell_type == "code"]
    assert 'QUICK = os.environ.get("YOUBOT_QUICK") == "1"' in code[0].source
    assert code[0] is cells[1], "the parameters are the first code cell, after the title"

    markdown = [c.source for c in cells if c.cell_type == "markdown"]
    words = sum(len(re.findall(r"[A-Za-z][A-Za-z'-]+", _prose(m))) for m in markdown)
    assert words >= MIN_PROSE_WORDS, f"{words} words of prose"
    sentences = [m for m in markdown if re.search(r"[a-z][^.]{40,}\.(\s|$)", _prose(m))]
    assert len(sentences) >= len(markdown) - 1, "markdown cells hold sentences, not just headings"
    assert not any(PLACEHOLDERS.search(m) for m in markdown)

    run = 0
    for cell in cells:
        run = run + 1 if cell.cell_type == "code" else 0
        assert run <= 3, "more than three code cells in a row without prose"
    for cell in code:
        tree = ast.parse(_code(cell.source))
        defined = [
            type(node).__name__
            for node in ast.walk(tree)
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef | ast.Lambda)
        ]
        assert not defined, f"logic belongs in the package, not in a cell: {cell.source[:60]!r}"


# ------------------------------------------------------------- execution
def _outputs(nb: Any) -> dict[str, Any]:
    """Text, markdown, PNG count and HTML pages of an executed notebook."""
    text, markdown, html, stderr, png = [], [], [], [], 0
    for cell in nb.cells:
        for out in cell.get("outputs", []):
            if out.output_type == "stream":
                (stderr if out.name == "stderr" else text).append(out.text)
            elif out.output_type in ("display_data", "execute_result"):
                data = out.get("data", {})
                png += "image/png" in data
                if "text/html" in data:
                    html.append(data["text/html"])
                elif "text/markdown" in data:
                    markdown.append(data["text/markdown"])
                elif "text/plain" in data:
                    text.append(data["text/plain"])
    return {
        "text": "\n".join(text),
        "markdown": "\n".join(markdown),
        "html": html,
        "stderr": "\n".join(stderr),
        "png": png,
    }


def _replays(out: dict[str, Any]) -> list[str]:
    """Embedded standalone meshcat pages (iframe srcdoc with meshcat's viewer inlined)."""
    return [h for h in out["html"] if "<iframe srcdoc=" in h and "meshcat-pane" in h]


def _check_01(out: dict[str, Any], tmp: Path) -> None:
    errors = [float(x) for x in re.findall(r"max error (\S+)", out["text"])]
    # 4 Pinocchio-vs-hand identities + 3 comparisons per CasADi backend (>= 2 backends)
    assert len(errors) >= 10, out["text"]
    # Independent double-precision computations of O(0.01-1000) quantities differ by
    # rounding (~1e-15 .. 1e-11 relative to |a| ~ 1e3 rad/s^2); a modelling error is >= 1e-3.
    assert max(errors) < 1e-9, errors
    rows = re.findall(r"^\([^)]*\)\s+\([^)]*\)\s+(\S+)\s+(\S+)$", out["text"], flags=re.MULTILINE)
    assert len(rows) == 4  # the study's four tip poses
    assert max(float(x) for row in rows for x in row) < 1e-12  # [m], [-]: rounding of O(1) sums
    assert out["png"] >= 1


def _check_02(out: dict[str, Any], tmp: Path) -> None:
    text = out["text"]
    assert "variables   451" in text and "equalities  306" in text  # 9n + 1, 6(n - 1) + 12
    assert re.search(r"status\s+solved", text)
    assert re.search(r"Certificate: youbot, 100 knots, trapezoidal, T = \S+ s: PASSED", text)
    assert out["png"] >= 3  # trajectory, convergence, arm
    assert len(_replays(out)) == 1
    assert (tmp / "youbot_opt_runs" / "notebook_02" / "replay_study1.html").stat().st_size > 1e5


def _check_03(out: dict[str, Any], tmp: Path) -> None:
    assert re.search(r"\d+ starts, \d+% converged, [1-9]\d* distinct local optima", out["text"])
    assert "Study 1 reproduced" in out["markdown"] and "Base case" in out["markdown"]
    assert out["png"] >= 4  # multistart, convergence, Pareto front, bound scaling
    assert len(_replays(out)) == 1


def _check_04(out: dict[str, Any], tmp: Path) -> None:
    text = out["text"]
    assert "target p2 = (0, 7.1): unreachable" in text
    assert "target p1 = (0, 7): reachable" in text
    assert "solve refused: UnreachableTarget" in text
    gap = float(re.search(r"E\(AL\) - E\(IPOPT\) = (\S+) rad", text).group(1))
    assert abs(gap) < 1e-6  # [rad^2]: both methods converge to 1e-8 stationarity
    assert text.count("limit violation 0 rad") >= 2  # example B, both methods
    assert out["png"] >= 6
    assert len(_replays(out)) == 2


def _check_05(out: dict[str, Any], tmp: Path) -> None:
    assert re.search(
        r"Certificate: ur5, \d+ knots, hermite_simpson, T = \S+ s: PASSED", out["text"]
    )
    assert out["png"] >= 2
    (page,) = _replays(out)
    assert len(page) > 1_000_000  # the UR5's COLLADA meshes are embedded


def _check_06(out: dict[str, Any], tmp: Path) -> None:
    text = out["text"]
    assert re.search(r"Certificate: my_arm, \d+ knots, hermite_simpson, T = \S+ s: PASSED", text)
    assert "nq = 4, nv = 3" in text and "JointModelRUBZ" in text  # continuous yaw: (cos, sin)
    assert "finger_right_joint" in text  # the mimic finger is locked, not a motor
    yaw_end = float(re.search(r"yaw turned from \S+ rad to (\S+) rad", text).group(1))
    assert yaw_end > 3.14159  # [rad] planned past +pi in one coordinate
    assert out["png"] >= 2
    assert len(_replays(out)) == 1


def _check_07(out: dict[str, Any], tmp: Path) -> None:
    text = out["text"]
    ratio = float(re.search(r"ours / greedy = (\S+)", text).group(1))
    assert ratio <= 1.0  # the greedy path is start 0: the best minimum cannot be worse
    al, ip = (float(x) for x in re.search(r"AL E = (\S+), IPOPT E = (\S+)", text).groups())
    assert abs(al - ip) <= 1e-6 * al  # both methods, same start: the same minimum
    errors = [float(x) for x in re.findall(r"(?:position|orientation) error (\S+)", text)]
    assert errors and max(errors) <= 1e-6  # framesForwardKinematics check of every station
    assert out["png"] >= 2


def _check_08(out: dict[str, Any], tmp: Path) -> None:
    import umsgpack

    text = out["text"]
    assert re.search(r"status\s+solved", text)
    assert "clearance certified: True" in text
    assert "disabled by SRDF" in text  # the pairs report
    assert out["png"] >= 1  # the clearance figure
    (page,) = _replays(out)
    blob = re.search(r"var commands = (\[.*?\]);", html.unescape(page), re.S)
    assert blob is not None
    commands = [umsgpack.unpackb(base64.b64decode(c)) for c in json.loads(blob.group(1))]
    drawn = {c["path"] for c in commands if c["type"] == "set_object"}
    assert {"/meshcat/youbot_opt/ur5/obstacles/table", "/meshcat/youbot_opt/ur5/obstacles/shelf",
            "/meshcat/youbot_opt/ur5/carried/held_box"} <= drawn  # fmt: skip
    scene = tmp / "youbot_opt_runs" / "notebook_08" / "cell.json"
    assert scene.stat().st_size > 0


def _check_09(out: dict[str, Any], tmp: Path) -> None:
    text = out["text"]
    t_ratio, w_ratio = (float(x) for x in re.search(r"T x (\S+), W x (\S+)", text).groups())
    assert t_ratio > 1.0 and w_ratio > 1.0  # carrying 0.5 kg: slower and costlier
    equal = re.findall(r"values equal (\w+), largest time difference (\S+) s", text)
    assert [e for e, _ in equal] == ["True"] * 3  # CSV, JSON, ROS 2 message
    assert max(float(d) for _, d in equal) <= 1e-9  # the message's stamps: whole nanoseconds
    assert "MJCF arm: status solved" in text and "MJCF arm certificate: PASSED" in text
    assert (tmp / "youbot_opt_runs" / "notebook_09" / "plan.ros2.json").stat().st_size > 0


def _check_10(out: dict[str, Any], tmp: Path) -> None:
    text = out["text"]
    for what in ("cup", "speed", "line"):
        assert f"{what}: certified True" in text, text
    tilt = float(re.search(r"largest tilt (\S+) rad", text).group(1))
    assert tilt > 0.03  # the free plan tips the cup beyond the limit
    first, free = (
        float(x) for x in re.search(r"first grid f = (\S+) >= free f = (\S+)", text).groups()
    )
    assert first >= free - 1e-9
    t_free, t_slow = (
        float(x) for x in re.search(r"T free (\S+) s, T limited (\S+) s", text).groups()
    )
    assert t_slow > t_free
    assert out["png"] >= 2


def _check_11(out: dict[str, Any], tmp: Path) -> None:
    text = out["text"]
    times = [float(t) for t in re.findall(r"waypoint \d reached at t = (\S+) s", text)]
    assert len(times) == 2 and 0.0 < times[0] < times[1]
    total, parts = (
        float(x) for x in re.search(r"T = (\S+) s = sum of segments (\S+) s", text).groups()
    )
    assert times[1] < total and abs(total - parts) <= 1e-4  # printed to 4 decimals
    assert "certificate passed: True" in text
    two, one = (
        float(x)
        for x in re.search(r"two segments f = (\S+) <= one segment f = (\S+)", text).groups()
    )
    assert two <= one * (1 + 1e-6)  # the single-segment optimum is feasible for two segments
    detour, plain = (
        float(x) for x in re.search(r"detour: T = (\S+) s against (\S+) s", text).groups()
    )
    assert detour > plain
    assert "back at waypoint 1: True, success True" in text
    assert out["png"] >= 1  # the trajectory figure


CHECKS = {
    "01_model_and_dynamics": _check_01,
    "02_trajectory_solve": _check_02,
    "03_studies": _check_03,
    "04_ik_path": _check_04,
    "05_other_robot": _check_05,
    "06_your_robot": _check_06,
    "07_spatial_ik_path": _check_07,
    "08_arm_in_a_cell": _check_08,
    "09_payload_and_export": _check_09,
    "10_tool_constraints": _check_10,
    "11_timed_waypoints": _check_11,
}


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=_ids(NOTEBOOKS))
def test_notebook_executes_in_quick_mode(
    path: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The notebook runs headless without a cell error and shows its key outputs."""
    monkeypatch.setenv("YOUBOT_QUICK", "1")
    monkeypatch.delenv("YOUBOT_LIVE", raising=False)  # never start a meshcat server here
    before = sorted(p.name for p in NOTEBOOK_DIR.iterdir())
    nb = _read(path)
    client = nbclient.NotebookClient(
        nb,
        timeout=CELL_TIMEOUT,
        kernel_name="python3",
        resources={"metadata": {"path": str(tmp_path)}},
    )
    tic = time.perf_counter()
    client.execute()  # raises CellExecutionError on the first failing cell
    print(f"{path.name}: executed in {time.perf_counter() - tic:.1f} s")
    out = _outputs(nb)
    assert "Traceback" not in out["stderr"], out["stderr"]
    CHECKS[path.stem](out, tmp_path)
    assert sorted(p.name for p in NOTEBOOK_DIR.iterdir()) == before  # nothing written here
