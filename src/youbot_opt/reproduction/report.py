"""Comparison tables of the study-1 reproduction, as markdown and JSON.

:func:`markdown_report` turns the JSON form of a
:class:`~youbot_opt.reproduction.runs.Study1Reproduction` (``to_json()``, or the
file :func:`write_report` saved) into the tables of
``docs/trajopt_reproduction.md``: the base case (study's reported figure |
study's transcription reproduced | correct transcriptions), the deviations one
at a time, the weight extremes, the Pareto front and the refinement in knots,
each with its forward-simulation certificate. Tables are built from the saved
JSON only, so they can be regenerated without solving again.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypedDict, cast

from youbot_opt._files import atomic_write_text, json_ready

__all__ = ["STUDY_REPORTED", "ParetoPoint", "markdown_report", "write_report", "pareto_knee"]

STUDY_REPORTED: dict[str, str] = {
    "objective": "9.359 (92 % of starts)",
    "optima": "9.359 (92 %), 11.070 (8 %)",
    "dt_s": "~0.050",
    "duration_s": "~2.4",
    "beta_high": "~1.4 s (beta near 1)",
    "beta_low": "61 s (beta near 0)",
    "pareto": "corner near beta = 0.5",
}
"""The study's figures (spec ``trajopt.md``, "Figures the study reported"), verbatim."""

JSON_NAME = "study1_reproduction.json"
MARKDOWN_NAME = "study1_reproduction.md"


def _layout(data: Mapping[str, object]) -> dict[str, Any]:
    """Read the reproduction's JSON by the layout of ``Study1Reproduction.to_json()``."""
    return cast("dict[str, Any]", data)


def _f(x: Any, digits: int = 4) -> str:
    """Format a number with ``digits`` significant digits; a dash for missing values."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return str(x)
    return f"{x:.{digits}g}"


def _table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def _cert(rec: dict[str, Any] | None, key: str = "certificate") -> dict[str, Any]:
    cert = (rec or {}).get(key)
    return cert if isinstance(cert, dict) else {}


def _verdict(cert: dict[str, Any]) -> str:
    if not cert:
        return "-"
    return "passes" if cert.get("ok") else "fails"


_SHORT = (
    ("tracking: feedback/plan torque, RMS", "feedback RMS"),
    ("tracking: feedback/plan torque, peak", "feedback peak"),
    ("tracking: position error [rad]", "tracking [rad]"),
    ("local error, position [rad]", "local q [rad]"),
    ("local error, velocity [rad/s]", "local v [rad/s]"),
    ("bound velocity, between knots (relative)", "speed bound between knots"),
    ("bound position, between knots (relative)", "position bound between knots"),
    ("bound torque, between knots (relative)", "torque bound between knots"),
)


def _why(cert: dict[str, Any]) -> str:
    """Return the certificate's verdict with its failed checks, abbreviated."""
    if not cert:
        return "-"
    failures = cert.get("failures") or []
    if cert.get("ok") or not failures:
        return _verdict(cert)
    short = []
    for text in failures:
        for long, abbrev in _SHORT:
            text = text.replace(long, abbrev)
        short.append(text)
    return "fails: " + "; ".join(short)


def _base_table(data: dict[str, Any]) -> str:
    keys = list(data["base"])
    best = {k: data["base"][k]["best"] or {} for k in keys}
    header = ["quantity", "study reported", *[best[k].get("label", k) for k in keys]]

    def optima(k: str) -> str:
        ms = data["base"][k]
        return ", ".join(
            f"{_f(o['objective'], 5)} ({o['count']}/{ms['n_starts']})" for o in ms["optima"]
        )

    def row(name: str, reported: str, fn: Any) -> list[str]:
        return [name, reported, *[fn(k) for k in keys]]

    rows = [
        row(
            "f, as its NLP defines it",
            STUDY_REPORTED["objective"],
            lambda k: _f(best[k].get("objective"), 5),
        ),
        row("f with T = (n-1) dt", "-", lambda k: _f(best[k].get("objective_true"), 5)),
        row("distinct optima (count/starts)", STUDY_REPORTED["optima"], optima),
        row(
            "converged starts", "~95 %", lambda k: f"{100 * data['base'][k]['success_rate']:.0f} %"
        ),
        row("dt [s]", STUDY_REPORTED["dt_s"], lambda k: _f(best[k].get("dt_s"))),
        row(
            "T = (n-1) dt [s]",
            STUDY_REPORTED["duration_s"],
            lambda k: _f(best[k].get("duration_s")),
        ),
        row("T in its objective [s]", "-", lambda k: _f(best[k].get("duration_code_s"))),
        row("W [N^2 m^2 s]", "-", lambda k: _f(best[k].get("work"))),
    ]
    for key, arm in (("certificate", "own model"), ("certificate_paper", "paper arm, b = 0")):
        rows += [
            row(f"certificate ({arm})", "-", lambda k, key=key: _why(_cert(best[k], key))),
            row(f"  local position error [rad] ({arm})", "-",
                lambda k, key=key: _f(_cert(best[k], key).get("local_position_max_rad"), 3)),
            row(f"  local velocity error [rad/s] ({arm})", "-",
                lambda k, key=key: _f(_cert(best[k], key).get("local_velocity_max_rad_s"), 3)),
            row(f"  feedback/plan torque RMS ({arm})", "-",
                lambda k, key=key: _f(_cert(best[k], key).get("feedback_rms_ratio"), 3)),
            row(f"  tracking error [rad] ({arm})", "-",
                lambda k, key=key: _f(_cert(best[k], key).get("tracking_position_error_rad"), 3)),
        ]  # fmt: skip
    return _table(header, rows)


def _search_table(data: dict[str, Any]) -> str:
    header = [
        "transcription", "starts", "converged", "optimum f (own)", "found by", "T [s]", "W",
        "dt [s]", "certificate (own / paper)", "feedback RMS (paper)", "local pos. err. (paper)",
    ]  # fmt: skip
    rows = [[
        "study reported", "50", "~95 %", "9.359 / 11.070", "92 % / 8 %", "~2.4", "-", "~0.050",
        "-", "-", "-",
    ]]  # fmt: skip
    for s in data["search"].values():
        for o in s["optima"]:
            cert = _cert(o, "certificate_paper")
            rows.append([
                o["label"], str(s["n_starts"]), f"{100 * s['success_rate']:.0f} %",
                _f(o["objective"], 5), f"{o['count']} ({100 * o['fraction']:.0f} %)",
                _f(o["duration_s"]), _f(o["work"]), _f(o["dt_s"]),
                f"{_verdict(_cert(o))} / {_why(cert)}", _f(cert.get("feedback_rms_ratio"), 3),
                _f(cert.get("local_position_max_rad"), 3),
            ])  # fmt: skip
    return _table(header, rows)


def _ablation_table(data: dict[str, Any]) -> str:
    header = [
        "deviations", "beta", "f (own)", "T [s]", "W", "dt [s]", "tau at knot 1 [N m]",
        "tau at knot n [N m]", "local pos. err. [rad]", "feedback RMS", "certificate",
    ]  # fmt: skip
    rows = []
    for r in data["ablation"]:
        cert = _cert(r, "certificate_paper")
        rows.append([
            r["deviations"], _f(r["beta"], 3), _f(r["objective"], 5), _f(r["duration_s"]),
            _f(r["work"]), _f(r["dt_s"]), " ".join(f"{t:.2f}" for t in r["tau_first"]),
            " ".join(f"{t:.2f}" for t in r["tau_last"]),
            _f(cert.get("local_position_max_rad"), 3), _f(cert.get("feedback_rms_ratio"), 3),
            _verdict(cert),
        ])  # fmt: skip
    return _table(header, rows)


def _extremes_table(data: dict[str, Any]) -> str:
    header = [
        "variant", "beta", "f (own)", "T [s]", "W", "optima: T [s] (count)",
        "closest to q = 0 [rad]", "time near q = 0 [s]", "certificate (own / paper)",
    ]  # fmt: skip
    rows = [
        ["study reported", "~1", "-", STUDY_REPORTED["beta_high"], "-", "-", "-", "-", "-"],
        ["study reported", "~0", "-", STUDY_REPORTED["beta_low"], "-", "-", "-", "-", "-"],
    ]
    for key, entries in data["extremes"].items():
        for e in entries:
            b = e["best"] or {}
            opts = ", ".join(f"{_f(o['duration_s'], 3)} ({o['count']})" for o in e["optima"])
            rows.append([
                b.get("label", key), _f(e["beta"], 3), _f(b.get("objective"), 5),
                _f(b.get("duration_s")), _f(b.get("work")), opts,
                _f(b.get("upright_distance_rad"), 2), _f(b.get("upright_time_s"), 3),
                f"{_verdict(_cert(b))} / {_verdict(_cert(b, 'certificate_paper'))}",
            ])  # fmt: skip
    return _table(header, rows)


class ParetoPoint(TypedDict, total=False):
    """One point of a reproduction's Pareto section, as :func:`pareto_knee` reads it."""

    beta: float
    duration_s: float
    work: float
    success: bool
    dominated: bool


def pareto_knee(points: list[ParetoPoint]) -> float | None:
    """Weight of the front's corner: the non-dominated point farthest from the chord.

    ``T`` and ``W`` are normalised to [0, 1] over the non-dominated points, and
    the corner is the point with the largest distance to the line through the
    two ends of the front (the "knee").

    Parameters
    ----------
    points : list of ParetoPoint
        Records with ``beta``, ``duration_s``, ``work``, ``success`` and ``dominated``.

    Returns
    -------
    float or None
        ``beta`` of the corner; ``None`` with fewer than three non-dominated points.
    """
    front = [p for p in points if p.get("success") and not p.get("dominated")]
    front.sort(key=lambda p: p["duration_s"])
    if len(front) < 3:
        return None
    t = [p["duration_s"] for p in front]
    w = [p["work"] for p in front]
    span_t, span_w = (max(t) - min(t)) or 1.0, (max(w) - min(w)) or 1.0
    xs = [(x - min(t)) / span_t for x in t]
    ys = [(y - min(w)) / span_w for y in w]
    dx, dy = xs[-1] - xs[0], ys[-1] - ys[0]
    norm = math.hypot(dx, dy) or 1.0
    dist = [abs(dy * (x - xs[0]) - dx * (y - ys[0])) / norm for x, y in zip(xs, ys, strict=True)]
    return float(front[max(range(len(front)), key=dist.__getitem__)]["beta"])


def _pareto_table(data: dict[str, Any]) -> str:
    keys = list(data["pareto"])
    betas = sorted({p["beta"] for k in keys for p in data["pareto"][k]})
    header = ["beta"] + [f"{k}: T [s] / W / cert." for k in keys]
    rows = []
    for b in betas:
        row = [_f(b, 3)]
        for k in keys:
            p = next((p for p in data["pareto"][k] if p["beta"] == b), None)
            if p is None or not p.get("success"):
                row.append("-" if p is None else p.get("status", "-"))
                continue
            mark = " (dominated)" if p.get("dominated") else ""
            verdict = _verdict(_cert(p, "certificate_paper"))
            row.append(f"{_f(p['duration_s'])} / {_f(p['work'])} / {verdict}{mark}")
        rows.append(row)
    rows.append(["corner (knee) beta", *[_f(pareto_knee(data["pareto"][k]), 3) for k in keys]])
    return _table(header, rows)


def _refinement_table(data: dict[str, Any]) -> str:
    header = [
        "variant", "knots", "status", "f (own)", "T [s]", "W", "dt [s]", "IPOPT iter. (warm)",
        "local pos. err. [rad]", "local vel. err. [rad/s]", "feedback RMS", "tracking err. [rad]",
        "certificate (paper arm)",
    ]  # fmt: skip
    rows = []
    for r in data["refinement"]:
        cert = _cert(r, "certificate_paper")
        rows.append([
            r["label"], str(r["n_knots"]), r["status"], _f(r["objective"], 7),
            _f(r["duration_s"], 6), _f(r["work"], 6), _f(r["dt_s"]), str(r["iterations"]),
            _f(cert.get("local_position_max_rad"), 3), _f(cert.get("local_velocity_max_rad_s"), 3),
            _f(cert.get("feedback_rms_ratio"), 3), _f(cert.get("tracking_position_error_rad"), 3),
            _why(cert),
        ])  # fmt: skip
    note = (
        "IPOPT iter. (warm): iterations of a warm-started solve; the first grid starts from "
        "the base case's best solution on that grid, each finer grid from the coarser one's "
        "solution, so it can be far below the count of a standalone straight-line solve."
    )
    return note + "\n\n" + _table(header, rows)


def markdown_report(data: Mapping[str, object]) -> str:
    """All comparison tables as one markdown document.

    Parameters
    ----------
    data : dict
        ``Study1Reproduction.to_json()`` or the saved JSON file's content.

    Returns
    -------
    str
        Markdown with one section per part of the reproduction (sections that
        were not run are omitted).
    """
    data = _layout(data)
    cfg = data["config"]
    parts = [
        "# Study 1 reproduced: tables",
        f"n = {cfg['n_knots']} knots, beta = {cfg['beta']}, {cfg['n_starts']} seeded random "
        f"spline starts (seed {cfg['seed']}), IPOPT tol {cfg['tol']:g}. Certificates: "
        "`youbot_opt.trajopt.certify.certify` default tolerances; 'own model' is the arm the NLP "
        "describes (b = 0.1 for the study's code), 'paper arm' has b = 0.",
    ]
    sections = [
        ("base", "Base case (beta = 0.5)", _base_table),
        (
            "search",
            "Second optimum: the study's random starts read as LP vertices (beta = 0.5)",
            _search_table,
        ),
        (
            "ablation",
            "The study's deviations one at a time (paper-arm certificate)",
            _ablation_table,
        ),
        ("extremes", "Weight extremes", _extremes_table),
        ("pareto", "Pareto front (paper-arm certificate)", _pareto_table),
        ("refinement", "Refinement in knots (beta = 0.5)", _refinement_table),
    ]
    for key, title, build in sections:
        if data.get(key):
            parts += [f"## {title}", build(data)]
    timings = ", ".join(f"{k} {v:.0f} s" for k, v in data.get("timings", {}).items())
    parts.append(f"Wall time per section: {timings}.")
    return "\n\n".join(parts) + "\n"


def write_report(data: Mapping[str, object], out_dir: str | os.PathLike[str]) -> tuple[Path, Path]:
    """Write the JSON figures and the markdown tables to ``out_dir`` (created if needed).

    Parameters
    ----------
    data : dict
        ``Study1Reproduction.to_json()``.
    out_dir : path-like
        Output directory.

    Returns
    -------
    tuple of Path
        The JSON and markdown files (``study1_reproduction.json``, ``.md``).
    """
    data = _layout(data)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    json_path, md_path = out / JSON_NAME, out / MARKDOWN_NAME
    # default=str: any object json_ready leaves as it is is written as its text
    text = json.dumps(json_ready(data), indent=1, allow_nan=False, default=str)
    atomic_write_text(json_path, text + "\n")
    atomic_write_text(md_path, markdown_report(data))
    return json_path, md_path
