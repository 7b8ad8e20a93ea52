"""Figures of the study-1 reproduction, drawn from its JSON records only.

Each function takes the JSON form of a
:class:`~youbot_opt.reproduction.runs.Study1Reproduction` and returns a new
Figure, so ``youbot-opt reproduce-study1 --from-json FILE`` redraws without
solving: :func:`plot_base_case`, :func:`plot_fronts`, :func:`plot_refinement`;
:data:`FIGURES` names each (``repro_*.png``).

>>> plot_fronts(json.loads(path.read_text())).savefig("fronts.png")  # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any, cast

import numpy as np
from matplotlib.figure import Figure

__all__ = ["FIGURES", "plot_base_case", "plot_fronts", "plot_refinement"]

_COLOURS = ("tab:blue", "tab:orange", "tab:green")
_STYLES = {"study": "--", "trapezoidal": "-", "hermite_simpson": ":"}
_VARIANT_COLOURS = {
    "study": "tab:red",
    "trapezoidal": "tab:blue",
    "hermite_simpson": "tab:green",
    "trapezoidal_b0.1": "tab:purple",
    "hermite_simpson_b0.1": "tab:olive",
}
_W_UNIT = r"N$^2$ m$^2$ s"  # unit of the work W = int tau . tau dt


def _layout(data: Mapping[str, object]) -> dict[str, Any]:
    """Read the reproduction's JSON by the layout of ``Study1Reproduction.to_json()``."""
    return cast("dict[str, Any]", data)


def _limits() -> dict[str, np.ndarray]:
    """Data-sheet bounds of the planar youBot: position [rad], speed [rad/s], torque [N m]."""
    from youbot_opt.robot.load import load_model

    robot = load_model("youbot")
    return {
        "q": np.vstack([robot.q_lower, robot.q_upper]),
        "v": np.vstack([-robot.velocity_limit, robot.velocity_limit]),
        "tau": np.vstack([-robot.effort_limit, robot.effort_limit]),
    }


def plot_base_case(
    data: Mapping[str, object], keys: tuple[str, ...] = ("study", "trapezoidal")
) -> Figure:
    """Best beta = 0.5 trajectories of the variants ``keys``, one column per variant.

    Parameters
    ----------
    data : dict
        The reproduction's JSON; its ``base`` records must hold ``trajectory``.
    keys : tuple of str
        Variant keys, one column each.

    Returns
    -------
    Figure
        Rows: joint angle [rad], speed [rad/s], torque [N m] against time [s];
        data-sheet bounds dashed.
    """
    data = _layout(data)
    keys = tuple(k for k in keys if "trajectory" in ((data["base"].get(k) or {}).get("best") or {}))
    limits = _limits()
    fig = Figure(figsize=(4.2 * max(len(keys), 1), 6.6), layout="constrained")
    axes = fig.subplots(3, max(len(keys), 1), sharex="col", sharey="row", squeeze=False)
    labels = {"q": "q [rad]", "v": "v [rad/s]", "tau": r"$\tau$ [N m]"}
    for col, key in enumerate(keys):
        best = data["base"][key]["best"]
        traj = best["trajectory"]
        t = np.asarray(traj["t"])
        for row, name in enumerate(("q", "v", "tau")):
            ax = axes[row, col]
            values = np.asarray(traj[name])
            for j in range(values.shape[1]):
                colour = _COLOURS[j % len(_COLOURS)]
                ax.plot(t, values[:, j], color=colour, marker=".", ms=3, label=f"joint {j + 1}")
                for bound in limits[name][:, j]:
                    ax.axhline(bound, color=colour, ls="--", lw=0.8, alpha=0.7)
            ax.grid(alpha=0.3)
            if col == 0:
                ax.set_ylabel(labels[name])
        cert = best.get("certificate_paper") or {}
        verdict = (
            "" if not cert else ("certificate passes" if cert.get("ok") else "certificate fails")
        )
        axes[0, col].set_title(
            f"{best['label']}\nf = {best['objective']:.4f}, T = {best['duration_s']:.3f} s, "
            f"W = {best['work']:.2f}\n{verdict}",
            fontsize=9,
        )
        axes[-1, col].set_xlabel("t [s]")
    if keys:
        axes[0, 0].legend(fontsize=8, loc="lower right")
    fig.suptitle(f"beta = {data['config']['beta']}, n = {data['config']['n_knots']} knots")
    return fig


def plot_fronts(
    data: Mapping[str, object], keys: tuple[str, ...] = ("study", "trapezoidal", "hermite_simpson")
) -> Figure:
    """Duration (log axis) against work of the variants' weighted-sum sweeps.

    Parameters
    ----------
    data : dict
        The reproduction's JSON with a ``pareto`` section.
    keys : tuple of str
        Variants drawn (those the data has).

    Returns
    -------
    Figure
        One line per variant through its converged points in order of beta,
        dominated points crossed, beta = 0.5 ringed; a paper-arm certificate that
        fails is drawn hollow.
    """
    data = _layout(data)
    fig = Figure(figsize=(7.0, 4.6), layout="constrained")
    ax = fig.subplots()
    for key in (k for k in keys if k in data["pareto"]):
        points = data["pareto"][key]
        pts = sorted((p for p in points if p.get("success")), key=lambda p: p["beta"])
        if not pts:
            continue
        colour = _VARIANT_COLOURS.get(key, "k")
        label = pts[0].get("label", key)
        ax.plot([p["work"] for p in pts], [p["duration_s"] for p in pts], color=colour, lw=1,
                ls=_STYLES.get(key, "-."), label=label)  # fmt: skip
        for p in pts:
            ok = (p.get("certificate_paper") or {}).get("ok")
            marker = "x" if p.get("dominated") else "o"
            face = colour if ok else "none"
            ax.scatter(p["work"], p["duration_s"], marker=marker, s=22, edgecolors=colour,
                       facecolors=face if marker == "o" else colour, zorder=3)  # fmt: skip
            if math.isclose(p["beta"], 0.5):
                ax.scatter(p["work"], p["duration_s"], s=110, facecolors="none",
                           edgecolors=colour, lw=1.2, zorder=3)  # fmt: skip
    ax.set_yscale("log")
    ax.set_xlabel(f"work W [{_W_UNIT}]")
    ax.set_ylabel("duration T = (n - 1) dt [s]")
    ax.set_title(
        "Weighted-sum fronts (filled: paper-arm certificate passes; ringed: beta = 0.5)",
        fontsize=9,
    )
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    return fig


def plot_refinement(data: Mapping[str, object]) -> Figure:
    """Objective and certificate figures against the number of knots.

    Parameters
    ----------
    data : dict
        The reproduction's JSON with a ``refinement`` section.

    Returns
    -------
    Figure
        Left: objective (true ``T = (n - 1) dt``) against knots; right: the
        paper-arm certificate's feedback/plan torque RMS ratio and its local
        position error [rad] against knots (log-log), default tolerances dashed.
    """
    data = _layout(data)
    fig = Figure(figsize=(9.0, 3.8), layout="constrained")
    left, right = fig.subplots(1, 2)
    by_variant: dict[str, list[dict[str, Any]]] = {}
    for r in data["refinement"]:
        by_variant.setdefault(r["variant"], []).append(r)
    for key, rows in by_variant.items():
        rows = [r for r in rows if r.get("success")]
        if not rows:
            continue
        n = [r["n_knots"] for r in rows]
        colour, style = _VARIANT_COLOURS.get(key, "k"), _STYLES.get(key, "-.")
        left.plot(n, [r["objective_true"] for r in rows], marker="o", color=colour, ls=style,
                  label=rows[0]["label"])  # fmt: skip
        certs = [r.get("certificate_paper") or {} for r in rows]
        for field, marker in (("feedback_rms_ratio", "o"), ("local_position_max_rad", "s")):
            y = [c.get(field) for c in certs]
            if all(v is not None for v in y):
                right.plot(n, y, marker=marker, color=colour, ls=style, ms=4)
    right.axhline(0.05, color="k", lw=0.8, ls="--")
    right.text(55, 0.055, "default tolerance 0.05", fontsize=7)
    right.plot([], [], "ko", ms=4, label="feedback / plan torque RMS")
    right.plot([], [], "ks", ms=4, label="local position error [rad]")
    for ax in (left, right):
        ax.set_xscale("log")
        ax.set_xticks(sorted({r["n_knots"] for r in data["refinement"]}))
        ax.set_xticklabels([str(k) for k in sorted({r["n_knots"] for r in data["refinement"]})])
        ax.minorticks_off()
        ax.set_xlabel("knots n")
        ax.grid(alpha=0.3)
    right.set_yscale("log")
    left.set_ylabel("f = beta T + (1 - beta) W, T = (n - 1) dt")
    left.set_title(f"optimum at beta = {data['config']['beta']}", fontsize=9)
    right.set_title("paper-arm certificate", fontsize=9)
    left.legend(fontsize=8)
    right.legend(fontsize=8)
    return fig


def _has_trajectories(data: Mapping[str, object]) -> bool:
    data = _layout(data)
    return any("trajectory" in (b.get("best") or {}) for b in (data.get("base") or {}).values())


FIGURES: dict[
    str, tuple[Callable[[Mapping[str, object]], bool], Callable[[Mapping[str, object]], Figure]]
] = {
    "repro_base_case": (_has_trajectories, plot_base_case),
    "repro_pareto": (lambda data: bool(data.get("pareto")), plot_fronts),
    "repro_refinement": (lambda data: bool(data.get("refinement")), plot_refinement),
}
"""File stem -> (whether the data can draw it, function drawing it)."""
