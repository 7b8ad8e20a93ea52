"""``reproduce-study1 --from-json``: wrong-shaped nested fields are refused by field (#29).

A reproduction JSON whose top-level fields have the right types but whose
inner fields do not (a list where an object is, text where a number is, ...)
ends in one error line naming the field, exit 2, no traceback.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from youbot_opt.cli import main


@pytest.fixture(scope="module")
def document(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The quick reproduction's JSON (a few seconds of solves)."""
    out = tmp_path_factory.mktemp("repro")
    assert main(["reproduce-study1", "--quick", "--serial", "--out", str(out)]) == 0
    return json.loads((out / "study1_reproduction.json").read_text())


def _set(*path: Any) -> Callable[[dict[str, Any]], None]:
    *where, (key, value) = path

    def edit(doc: dict[str, Any]) -> None:
        node: Any = doc
        for k in where:
            node = node[k]
        node[key] = value

    return edit


CASES = {  # edit -> the field the error must name
    "study case a list": (_set("base", ("study", [])), "['base']['study']"),
    "success rate text": (
        _set("base", "study", ("success_rate", "a")),
        "['base']['study']['success_rate']",
    ),
    "objective null": (
        _set("base", "study", "best", ("objective", None)),
        "['base']['study']['best']['objective']",
    ),
    "refinement row a number": (_set("refinement", (0, 3)), "['refinement'][0]"),
    "pareto point a list": (_set("pareto", "study", (0, [1])), "['pareto']['study'][0]"),
    "optima text": (_set("search", "study", ("optima", "x")), "['search']['study']['optima']"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_wrong_inner_shape_is_refused_by_field(
    document: dict[str, Any], case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    edit, field = CASES[case]
    doc = copy.deepcopy(document)
    edit(doc)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    capsys.readouterr()
    code = main(["reproduce-study1", "--from-json", str(path), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if x.startswith("youbot-opt: error:")]
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert f"field {field}" in lines[0] and str(path) in lines[0]


def test_no_figures_rerun_keeps_no_stale_figure(document: dict[str, Any], tmp_path: Path) -> None:
    """`--from-json` into a folder with figures, then `--no-figures`: no repro_*.png left."""
    path = tmp_path / "study.json"
    path.write_text(json.dumps(document))
    out = tmp_path / "o"
    assert main(["reproduce-study1", "--from-json", str(path), "--out", str(out)]) == 0
    drawn = sorted(p.name for p in out.glob("repro_*.png"))
    assert drawn
    (out / "notes.png").write_bytes(b"not ours")
    before = sorted(p.name for p in out.iterdir())
    argv = ["reproduce-study1", "--from-json", str(path), "--out", str(out), "--no-figures"]
    assert main(argv) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(set(before) - set(drawn))
    assert (out / "notes.png").read_bytes() == b"not ours"


def test_figures_drawn_in_other_processes_are_there_on_return(
    document: dict[str, Any], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A run's repro_*.png are drawn by `cli.drawing.Drawing` while the rest is written.

    Every one is in the folder when the outputs are written; a figure that
    fails there raises here.
    """
    from youbot_opt.cli import reproduce
    from youbot_opt.reproduction import figures

    files = reproduce._write_outputs(document, {}, tmp_path / "a")
    pngs = [f for f in files if f.suffix == ".png"]
    assert sorted(p.name for p in pngs) == sorted(
        f"{stem}.png" for stem, (drawable, _) in figures.FIGURES.items() if drawable(document)
    )
    assert pngs and all(p.stat().st_size > 0 for p in pngs)

    def fails(data: object) -> object:
        raise RuntimeError("the Pareto figure broke")

    broken = {**figures.FIGURES, "repro_pareto": (lambda data: True, fails)}
    monkeypatch.setattr(reproduce, "FIGURES", broken)
    with pytest.raises(RuntimeError, match="the Pareto figure broke") as caught:
        reproduce._write_outputs(document, {}, tmp_path / "b")
    assert any("in the figure process" in note for note in caught.value.__notes__)
