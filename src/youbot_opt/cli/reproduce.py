"""``youbot-opt reproduce-study1``: reproduce study 1 with its own and the correct transcription.

Runs :func:`youbot_opt.reproduction.reproduce_study1` (``--quick``: a small
subset) with progress on stderr, prints the markdown tables on stdout and
writes everything it computed to one output folder (:mod:`youbot_opt.cli.output`);
``--from-json FILE`` rebuilds tables and figures without solving. Exit code 0
when every base-case multistart converged at least once, 1 otherwise. The
folder's contents: docs/design.md, "Module notes".

Usage::

    youbot-opt reproduce-study1 [--quick] [--out DIR] [--starts K] [--from-json FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from youbot_opt._files import read_regular_file
from youbot_opt.cli.drawing import DRAWING_PROCESSES, Drawing, FigureJob
from youbot_opt.cli.output import print_outputs, remove_stale_figures, run_folder, write_summary
from youbot_opt.cli.run_size import check_trajopt_size
from youbot_opt.exceptions import ParameterError, ResultFileError
from youbot_opt.reproduction.figures import FIGURES
from youbot_opt.reproduction.report import write_report
from youbot_opt.reproduction.runs import ReproductionConfig, reproduce_study1
from youbot_opt.trajopt.io import save_result

__all__ = ["run"]


_TOP_KEYS: dict[str, type] = {
    "config": dict, "base": dict, "search": dict, "ablation": list, "extremes": dict,
    "pareto": dict, "refinement": list, "timings": dict,
}  # fmt: skip
"""The top-level fields of a reproduction JSON (``Study1Reproduction.to_json``) and their types."""


def _check_reproduction_json(data: object, path: str) -> None:
    """Refuse ``--from-json`` data that is not a reproduction's JSON, naming the field."""
    if not isinstance(data, dict):
        raise ParameterError(
            f"--from-json {path}: a reproduction JSON is an object, got a {type(data).__name__}",
            name="from_json",
        )
    for key, kind in _TOP_KEYS.items():
        if not isinstance(data.get(key), kind):
            found = type(data[key]).__name__ if key in data else "nothing"
            raise ParameterError(
                f"--from-json {path}: field {key!r} must be a JSON {kind.__name__}, got "
                f"{found} (write it with `youbot-opt reproduce-study1 --out DIR`)",
                name="from_json",
            )


_MAX_SHOWN = 200  # characters of the reason a wrong-shaped field gave (a field may be huge)


class _Seen:
    """The field of a ``--from-json`` document read last (``data['base']['study']``)."""

    def __init__(self) -> None:
        self.last = "the document"


class _Fields(dict):  # type: ignore[type-arg]
    """A JSON object that records which field is read (to name a wrong-shaped one)."""

    def __init__(self, data: dict[str, Any], path: str, seen: _Seen) -> None:
        super().__init__(data)
        self._path, self._seen = path, seen

    def __getitem__(self, key: Any) -> Any:
        where = f"{self._path}[{key!r}]"
        self._seen.last = where
        return _tracked(super().__getitem__(key), where, self._seen)

    def get(self, key: Any, default: Any = None) -> Any:
        return self[key] if key in self else default

    def values(self) -> Any:  # type: ignore[override]
        return [self[k] for k in self]

    def items(self) -> Any:  # type: ignore[override]
        return [(k, self[k]) for k in self]


class _Items(list):  # type: ignore[type-arg]
    """A JSON list that records which item is read (see :class:`_Fields`)."""

    def __init__(self, data: list[Any], path: str, seen: _Seen) -> None:
        super().__init__(data)
        self._path, self._seen = path, seen

    def __getitem__(self, i: Any) -> Any:
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        where = f"{self._path}[{i}]"
        self._seen.last = where
        return _tracked(super().__getitem__(i), where, self._seen)

    def __iter__(self) -> Any:
        return (self[i] for i in range(len(self)))


def _tracked(value: Any, path: str, seen: _Seen) -> Any:
    if isinstance(value, dict) and not isinstance(value, _Fields):
        return _Fields(value, path, seen)
    if isinstance(value, list) and not isinstance(value, _Items):
        return _Items(value, path, seen)
    return value


def _from_json(
    data: dict[str, Any], path: str, folder: Path, figures: bool = True
) -> tuple[list[Path], bool]:
    """Write the outputs of a ``--from-json`` document; a wrong-shaped field is named."""
    seen = _Seen()
    tracked = _Fields(data, "data", seen)
    try:
        files = _write_outputs(tracked, {}, folder, figures, processes=0)  # seen.last: here
        return files, _converged(tracked)
    except (KeyError, TypeError, ValueError, IndexError, AttributeError, ArithmeticError) as exc:
        what = f"{type(exc).__name__}: {str(exc)[:_MAX_SHOWN]}"
        raise ParameterError(
            f"--from-json {path}: field {seen.last.removeprefix('data')} does not hold what a "
            f"reproduction JSON holds there ({what}); write it with "
            "`youbot-opt reproduce-study1 --out DIR`",
            name="from_json",
        ) from exc


def _converged(data: dict[str, Any]) -> bool:
    """Whether every base-case multistart converged at least once."""
    return all(b["best"] is not None and b["success_rate"] > 0 for b in data["base"].values())


def run(args: argparse.Namespace) -> int:
    """Run ``youbot-opt reproduce-study1``; returns the exit code."""
    results: dict[str, Any] = {}
    if args.from_json is not None:
        try:
            data = json.loads(read_regular_file(Path(args.from_json), what="a reproduction JSON"))
        except (ResultFileError, ValueError, RecursionError) as exc:
            raise ParameterError(
                f"cannot read {args.from_json!r}: {exc}", name="from_json"
            ) from exc
        _check_reproduction_json(data, args.from_json)
        folder = run_folder("reproduce-study1", args.out)
        files, ok = _from_json(data, args.from_json, folder, not args.no_figures)
        print((folder / files[1].name).read_text())
        print_outputs(folder, files)
        return 0 if ok else 1
    else:
        changes: dict[str, Any] = {"seed": args.seed, "workers": args.workers}
        if args.starts is not None:
            changes["n_starts"] = args.starts
        if args.search_starts is not None:
            changes["search_starts"] = args.search_starts
        if args.serial:
            changes["executor"] = "serial"
        config = (
            ReproductionConfig.quick(**changes) if args.quick else ReproductionConfig(**changes)
        )
        # the sweeps list every start's task up front: refuse what cannot fit in memory
        check_trajopt_size(
            n_knots=config.n_knots,
            nq=3,  # the study's planar youBot
            n_starts=max(config.n_starts, config.search_starts),
        )
        folder = run_folder("reproduce-study1", args.out)
        tic = time.perf_counter()

        def progress(message: str) -> None:
            print(f"[{time.perf_counter() - tic:7.1f} s] {message}", file=sys.stderr, flush=True)

        reproduction = reproduce_study1(config, progress=progress)
        data, results = reproduction.to_json(), reproduction.results
    files = _write_outputs(data, results, folder, not args.no_figures)
    print((folder / files[1].name).read_text())
    print_outputs(folder, files)
    return 0 if _converged(data) else 1


def _write_outputs(
    data: dict[str, Any],
    results: dict[str, Any],
    folder: Path,
    figures: bool = True,
    processes: int = DRAWING_PROCESSES,
) -> list[Path]:
    """Write the JSON, markdown, summary, figures and result files; return them (JSON, md first).

    The figures are drawn in ``processes`` other processes (:class:`Drawing`)
    while the results and the summary are written; 0: here, last, as before
    (a ``--from-json`` document: its fields are then read in the order its
    errors name them). A drawing error propagates. ``figures`` False
    (``--no-figures``): no ``repro_*.png``. A reused folder keeps no figure of
    ours that this run did not write.
    """
    files = list(write_report(data, folder))
    drawing = Drawing(folder, _figures(data, figures) if processes else [], processes)
    try:  # drawn elsewhere from here on
        if results:  # the solves first: nothing below can lose them
            (folder / "results").mkdir(exist_ok=True)
            for name, result in results.items():
                save_result(result, folder / "results" / f"{name}.npz")
            files.append(folder / "results")
        files.append(write_summary(folder, _summary(data)))
        if not processes:
            drawing = Drawing(folder, _figures(data, figures), 0)
        files += [p for p in drawing.wait() if p is not None]
    finally:
        drawing.stop()
    remove_stale_figures(folder, files)
    return files


def _figures(data: dict[str, Any], figures: bool) -> list[FigureJob]:
    """Return the ``repro_*.png`` jobs that ``data`` can draw (none if not ``figures``)."""
    return [
        FigureJob(f"{stem}.png", draw, (data,), optional=False, dpi=90)
        for stem, (drawable, draw) in FIGURES.items()
        if figures and drawable(data)
    ]


def _summary(data: dict[str, Any]) -> dict[str, Any]:
    """Headline figures: each variant's base-case optimum, certificate and optima."""
    summary: dict[str, Any] = {"command": "reproduce-study1", "config": data["config"]}
    for key, base in data["base"].items():
        best = base.get("best") or {}
        cert = best.get("certificate_paper") or {}
        summary[key] = {
            "label": best.get("label"),
            "objective": best.get("objective"),
            "objective_true": best.get("objective_true"),
            "dt_s": best.get("dt_s"),
            "duration_s": best.get("duration_s"),
            "work": best.get("work"),
            "success_rate": base.get("success_rate"),
            "optima": [(o["objective"], o["count"]) for o in base.get("optima", [])],
            "certificate_paper_ok": cert.get("ok"),
            "feedback_rms_ratio": cert.get("feedback_rms_ratio"),
        }
    for key, search in (data.get("search") or {}).items():
        summary[f"search_{key}"] = {
            "n_starts": search["n_starts"],
            "statuses": search.get("statuses"),
            "optima": [(o["objective"], o["count"]) for o in search["optima"]],
        }
    return summary
