"""What ``youbot-opt ikpath`` reports: its summary document, ``starts.jsonl`` and its text.

The summary (``summary.json``, or stdout with ``--json``) of a planar run
(:func:`planar_summary`) or a 3-D one (:func:`summary_3d`,
:func:`add_result_3d`); one JSON object a line per start in ``starts.jsonl``
(:func:`write_starts`); the printed text of each (:func:`print_planar`,
:func:`print_3d`, :func:`print_starts`) and the warnings about undecided targets.

>>> starts = write_starts(folder, ms.results, ms.attempts)  # doctest: +SKIP
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from youbot_opt._files import write_json_lines
from youbot_opt._typing import JSONDict
from youbot_opt.cli.output import STARTS_FILE
from youbot_opt.collision.clearance import Clearance, ClearanceCertificate
from youbot_opt.ikpath.examples import STUDY_E_A
from youbot_opt.ikpath.multistart import MultistartResult
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability import Reachability
from youbot_opt.ikpath.reachability.general import ReachVerdict3D
from youbot_opt.ikpath.reachability.planar import ReachVerdict
from youbot_opt.ikpath.result import IKPathResult
from youbot_opt.ikpath.stored import StartSummary, StoredResults

__all__ = [
    "StartsFile",
    "add_result_3d",
    "budget_fields",
    "certainty",
    "clearance_summary",
    "planar_summary",
    "print_3d",
    "print_planar",
    "print_starts",
    "residual_field",
    "summary_3d",
    "warn_undecided_3d",
    "warn_undecided_planar",
    "write_starts",
]


class StartsFile(NamedTuple):
    """What :func:`write_starts` wrote: the file, and what the printed summary needs of it."""

    path: Path
    """``starts.jsonl`` in the run folder."""
    retried: list[int]
    """Indices of the starts that needed more than one attempt."""
    crashed: list[JSONDict]
    """The rows of the starts that crashed on every attempt (their ``message`` says why)."""


def write_starts(
    folder: Path,
    results: Sequence[IKPathResult],
    attempts: Sequence[int],
    detail: Callable[[IKPathResult | StartSummary[IKPathResult]], JSONDict] | None = None,
) -> StartsFile:
    """Write one JSON object per start to ``folder/starts.jsonl`` (:data:`STARTS_FILE`).

    Each row holds ``index``, ``status``, ``E`` [rad^2], the ``detail`` fields,
    ``attempts`` (``null``: unknown) and ``message`` (``null`` on a success).

    Parameters
    ----------
    folder : Path
        The run folder.
    results : sequence of IKPathResult
        One result per start, in start order (``--no-keep-results``: a
        :class:`~youbot_opt.ikpath.stored.StoredResults`, whose journal
        summaries are read instead, one at a time: a sweep of a million starts
        is never held in memory).
    attempts : sequence of int
        Attempts per start (empty: unknown).
    detail : callable ``(result or StartSummary) -> dict``, optional
        Mode-specific fields of each start, written after ``E``.

    Returns
    -------
    StartsFile
        The file, the retried starts and the crashed starts' rows.
    """
    crashed: list[JSONDict] = []

    def row(
        index: int, status: str, r: IKPathResult | StartSummary[IKPathResult], attempts: int | None
    ) -> JSONDict:
        out: JSONDict = {
            "index": index,
            "status": status,
            "E": r.objective,
            **({} if detail is None else detail(r)),
            "attempts": attempts,
            "message": None if r.success else r.message,
        }
        if status == "crashed":
            crashed.append(out)
        return out

    rows: Iterable[JSONDict]
    if isinstance(results, StoredResults):  # streamed from the journal, never all in memory
        rows = (row(s.index, s.status, s, s.attempts) for s in results.summaries())
        retried = [s.index for s in results.summaries() if s.attempts > 1]
    else:
        rows = (
            row(i, r.status.value, r, attempts[i] if attempts else None)
            for i, r in enumerate(results)
        )
        retried = [i for i, a in enumerate(attempts) if a > 1]
    path = folder / STARTS_FILE
    write_json_lines(path, rows)
    return StartsFile(path, retried, crashed)


def print_starts(doc: Mapping[str, object], crashed: Sequence[Mapping[str, object]]) -> None:
    """Print how the starts ran: throughput and outcomes, resumed, retried and crashed starts.

    ``doc`` is the run's summary (``starts``, ``seed``, ``start_kind``,
    ``workers``, ``wall_time`` [s], ``starts_per_second`` [1/s],
    ``status_counts``, ``resumed`` and ``retried``, and the time budget's
    ``planned_starts``, ``time_budget`` and ``budget_reached``); ``crashed`` the
    rows of :attr:`StartsFile.crashed`.
    """
    print(
        f"multistart: {doc['starts']} starts (seed {doc['seed']}, {doc['start_kind']}), "
        f"{doc['workers']} workers, {doc['wall_time']:.2f} s "
        f"({doc['starts_per_second']:.1f} starts/s); outcomes {doc['status_counts']}"
    )
    if doc.get("budget_reached"):
        ran, planned = doc["starts"], doc["planned_starts"]
        assert isinstance(ran, int) and isinstance(planned, int)
        folder = doc.get("output_folder", "DIR")
        print(
            f"  time budget {doc['time_budget']:g} s reached: {ran} of {planned} automatic "
            f"starts ran, {planned - ran} not run (rerun with "
            f"--out {folder} to go on with them, or give a larger --time-budget)"
        )
    if doc["resumed"]:
        print(f"  {doc['resumed']} starts loaded from the output folder (resumed)")
    if doc["retried"]:
        print(f"  retried after a failed attempt: starts {doc['retried']}")
    for o in crashed:
        print(f"  start {o['index']} failed after {o['attempts']} attempts: {o['message']}")


def budget_fields(ms: MultistartResult) -> JSONDict:
    """Return the summary's start tally: the starts run, planned, and the time budget.

    ``starts`` ran (or were loaded), of ``planned_starts``; ``time_budget`` [s] of
    the automatic starts (``None``: starts asked for, which all run);
    ``budget_reached``: it stopped the run before every planned start ran.
    """
    return {
        "starts": ms.n_starts,
        "planned_starts": ms.planned_starts,
        "time_budget": ms.time_budget,
        "budget_reached": ms.budget_reached,
    }


def certainty(ms: MultistartResult) -> JSONDict:
    """Return how sure the best path is: who reached it, how many minima, the next best.

    ``best_count`` of ``starts`` reached the best minimum (``n_success`` met the
    targets); ``distinct_minima`` counts paths, a path and its 2 pi shifts or a
    turn of a joint that moves no target being one
    (:func:`~youbot_opt.ikpath.multistart.minimum_distance`);
    ``next_E`` [rad^2] is the second best minimum (``None``: none).
    """
    return {
        "best_count": ms.best_count,
        "starts": ms.n_starts,
        "n_success": ms.n_converged,
        "distinct_minima": len(ms.minima),
        "next_E": ms.minima[1].objective if len(ms.minima) > 1 else None,
    }


def _print_certainty(doc: Mapping[str, Any]) -> None:
    """Print the certainty of the best path (:func:`certainty`), or why there is none."""
    c = doc["certainty"]
    if c["starts"] == 1 and doc.get("budget_reached"):
        print("certainty: one start ran within the time budget, nothing to compare with")
        return
    if c["starts"] == 1:
        print(
            "certainty: one start, nothing to compare with (run without --starts for the "
            "automatic starts)"
        )
        return
    if not c["best_count"]:
        print(f"certainty: none of {c['starts']} starts met the targets")
        return
    text = (
        f"certainty: {c['best_count']} of {c['starts']} starts reached the best E "
        f"({c['n_success']} met the targets), {c['distinct_minima']} distinct minima"
    )
    if c["next_E"] is not None:
        gap = (c["next_E"] - doc["E"]) / max(abs(doc["E"]), 1e-300)
        text += f", the next best E = {c['next_E']:.10g} rad^2 ({gap:+.2%})"
    if c["best_count"] == 1:
        text += "; only one start found it: more starts (--starts N) may find a better one"
    print(text)


# ------------------------------------------------------------------ planar
def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _verdict_json(v: ReachVerdict) -> dict[str, Any]:
    return {
        "index": v.index,
        "target": v.target.tolist(),
        "verdict": v.status.value,
        "method": v.method,
        "witness": None if v.witness is None else v.witness.tolist(),
        "witness_error": _num(v.witness_error),
        "distance_lower": v.distance_lower,
        "distance_upper": v.distance_upper,
        "nearest": v.nearest.tolist(),
        "message": v.describe(),
    }


def planar_summary(
    args: argparse.Namespace,
    problem: CyclicIKProblem,
    verdicts: tuple[ReachVerdict, ...],
    ms: MultistartResult | None,
    starts: StartsFile | None,
) -> JSONDict:
    """Return the summary document of a planar run (``ms``: None when a target is unreachable)."""
    chain = problem.planar_chain
    doc: dict[str, Any] = {
        "chain": chain.name,
        "lengths": chain.lengths.tolist(),
        "q_lower": [_num(v) for v in chain.q_lower] if problem.bounded else None,
        "q_upper": [_num(v) for v in chain.q_upper] if problem.bounded else None,
        "targets": problem.target_points.tolist(),
        "method": args.method,
        "reachability": [_verdict_json(v) for v in verdicts],
        "reachability_undecided": [v.index for v in verdicts if v.status is Reachability.UNDECIDED],
    }
    if args.example == "A":
        doc["study_E"] = STUDY_E_A
    if ms is None or starts is None:
        doc.update(status="unreachable", E=None, configurations=None, max_residual=None)
        return doc
    best = ms.best
    doc.update(
        status=best.status.value,
        message=best.message,
        E=best.objective,
        configurations=best.configurations.tolist(),
        residuals=best.position_errors.tolist(),
        max_residual=best.max_position_error(),
        limit_violation=best.limit_violation,
        multipliers=best.multipliers.tolist(),
        iterations=best.iterations,
        solve_time=best.wall_time,
        start_index=ms.best_index,
        **budget_fields(ms),
        seed=ms.seed,
        start_kind=args.start_kind,
        n_success=ms.n_converged,
        best_count=ms.best_count,
        certainty=certainty(ms),
        status_counts=ms.status_counts(),
        minima=[
            {
                "E": m.objective,
                "count": m.count,
                "first_start": m.start_indices[0],
                "max_residual": m.result.max_position_error(),
                "multiplier_norm": float(np.linalg.norm(m.result.multipliers)),
            }
            for m in ms.minima
        ],
        zero_start={"status": ms.results[0].status.value, "E": ms.results[0].objective},
        wall_time=ms.wall_time,
        workers=ms.n_workers,
        starts_per_second=ms.starts_per_second(),
        resumed=ms.resumed,
        retried=starts.retried,
        starts_file=starts.path.name,
    )
    return doc


def residual_field(r: IKPathResult | StartSummary[IKPathResult]) -> JSONDict:
    """Return the planar per-start field of ``summary.json``: the largest residual in [m]."""
    if hasattr(r, "max_position_error"):  # a result, not its stored summary
        return {"max_residual": r.max_position_error()}
    return {"max_residual": r.max_residual}


def print_planar(summary: JSONDict, crashed: list[JSONDict]) -> None:
    """Print a planar run's summary: the arm, the verdicts, the starts and the best path."""
    doc: dict[str, Any] = summary
    if doc["q_lower"] is None:
        lims = "none"
    else:
        lo = ", ".join("-inf" if v is None else f"{v:.4g}" for v in doc["q_lower"])
        hi = ", ".join("inf" if v is None else f"{v:.4g}" for v in doc["q_upper"])
        lims = f"[{lo}] .. [{hi}] rad"
    print(
        f"IK path: {doc['chain']} l = {doc['lengths']} m, limits {lims}, "
        f"{len(doc['targets'])} targets, method {doc['method']}"
    )
    print("reachability (exact, no sampling):")
    for v in doc["reachability"]:
        print(f"  {v['message']}")
    if doc["E"] is None:
        return
    if doc["planned_starts"] == 1:
        _print_single_start(doc, crashed)
    else:
        _print_multistart(doc, crashed)
    for j, q in enumerate(doc["configurations"]):
        print(f"  q{j + 1} = [{', '.join(f'{v:+.6f}' for v in q)}] rad")
    if "study_E" in doc:
        print(
            f"study reported E = {doc['study_E']} from the zero guess "
            f"(difference {doc['study_E'] - doc['E']:+.4f} rad^2; see docs/ikpath.md)"
        )


def _print_single_start(doc: dict[str, Any], crashed: list[JSONDict]) -> None:
    """Print the one run of ``--starts 1`` (the zero start) as one run, not as a multistart."""
    resumed = " (loaded from the output folder: resumed)" if doc["resumed"] else ""
    print(f"one start (the zero vector), {doc['wall_time']:.2f} s{resumed}")
    if doc["retried"]:
        print("  retried once after a failed attempt")
    for o in crashed:
        print(f"  failed after {o['attempts']} attempts: {o['message']}")
    print(
        f"result: E = {doc['E']:.10f} rad^2 ({doc['status']}); max residual "
        f"{doc['max_residual']:.2e} m, limit violation {doc['limit_violation']:.2e} rad"
    )
    _print_certainty(doc)
    _print_failure(doc)


def _print_failure(doc: dict[str, Any]) -> None:
    """Print why the best start failed (nothing for a success)."""
    if doc["status"] not in ("solved", "solved_acceptable"):
        print(f"failed ({doc['status']}): {doc['message']}")


def _print_multistart(doc: dict[str, Any], crashed: list[JSONDict]) -> None:
    """Print the multistart's outcomes, its local minima, the zero start and the best."""
    print_starts(doc, crashed)
    for m in doc["minima"][:8]:
        print(
            f"  local minimum E = {m['E']:.10f} rad^2 found by {m['count']} starts "
            f"(first: start {m['first_start']})"
        )
    z = doc["zero_start"]
    print(f"start 0 (the zero vector): {z['status']}, E = {z['E']:.10f} rad^2")
    print(
        f"best: E = {doc['E']:.10f} rad^2 ({doc['status']}), found by {doc['best_count']} of "
        f"{doc['starts']} starts; max residual {doc['max_residual']:.2e} m, "
        f"limit violation {doc['limit_violation']:.2e} rad"
    )
    _print_certainty(doc)
    _print_failure(doc)


def warn_undecided_planar(verdicts: Sequence[ReachVerdict]) -> None:
    """Warn on stderr about every target whose reachability was not decided."""
    for v in verdicts:
        if v.status is Reachability.UNDECIDED:
            print(
                f"youbot-opt: warning: reachability of target p{v.index + 1} = "
                f"({v.target[0]:.6g}, {v.target[1]:.6g}) is undecided (branch and bound "
                f"budget exhausted after {v.evaluations} evaluations): its distance to the "
                f"workspace is certified only to lie in [{v.distance_lower:.6g}, "
                f"{v.distance_upper:.6g}] m; solving anyway (a failed solve may mean the "
                "target is unreachable; a larger --reach-evaluations may decide it)",
                file=sys.stderr,
            )


# ------------------------------------------------------------------ 3-D
def summary_3d(
    args: argparse.Namespace,
    problem: CyclicIKProblem,
    robot: str,
    verdicts: Sequence[ReachVerdict3D],
) -> JSONDict:
    """Return the head of a 3-D run's summary: the problem and every target's verdict."""
    frame, targets = problem.frame, problem.targets
    return {
        "robot": robot,
        "frame": frame,
        "joints": list(problem.joint_names),
        "q_lower": problem.q_lower,
        "q_upper": problem.q_upper,
        "use_limits": problem.use_limits,
        "method": args.method,
        "targets": [t.to_dict() for t in targets],
        "reachability": [
            {
                "index": v.index,
                "verdict": v.status.value,
                "witness": None if v.witness is None else v.witness,
                "distance": v.distance,
                "reach": v.reach,
                "message": v.message,
                "decided_by": v.method,
                "interval_boxes": v.boxes,
                "interval_depth": v.depth,
            }
            for v in verdicts
        ],
    }


def add_result_3d(
    doc: JSONDict,
    args: argparse.Namespace,
    ms: MultistartResult,
    kind: str,
    starts: StartsFile,
) -> None:
    """Add the multistart's outcome to a 3-D run's summary ``doc`` (in place)."""
    best = ms.best
    doc.update(
        status=best.status.value,
        E=best.objective,
        result=best.to_dict(),
        start_index=ms.best_index,
        **budget_fields(ms),
        seed=args.seed,
        start_kind=kind,
        max_wall_time=args.max_wall_time,
        workers=ms.n_workers,
        n_success=ms.n_converged,
        certainty=certainty(ms),
        status_counts=ms.status_counts(),
        minima=[{"E": m.objective, "count": m.count} for m in ms.minima],
        starts_per_second=ms.starts_per_second(),
        wall_time=ms.wall_time,
        resumed=ms.resumed,
        retried=starts.retried,
        starts_file=starts.path.name,
    )


def warn_undecided_3d(verdicts: Sequence[ReachVerdict3D]) -> None:
    """Warn on stderr about every target whose reachability was not decided."""
    for v in verdicts:
        if v.status is Reachability.UNDECIDED:
            print(
                f"youbot-opt: warning: reachability of target {v.index} is undecided "
                f"({v.message}); solving anyway (a failed solve may mean it is unreachable; "
                "a larger --reach-evaluations may decide it)",
                file=sys.stderr,
            )


def clearance_summary(
    spec: Clearance, scene: Path | None, certificate: ClearanceCertificate | None
) -> JSONDict:
    """Return the summary's ``clearance``: the scene, margin and coal's closest pair.

    ``closest_leg`` and ``closest_fraction``: where along the closed path (leg
    ``j`` from target ``j`` to the next, the fraction of it).
    """
    doc: JSONDict = {
        "scene": None if scene is None else str(scene),
        "margin_m": spec.margin,
        "self_collision": spec.self_collision,
        "obstacles": [o.name for o in spec.scene.obstacles],
        "certified": None,
    }
    if certificate is None:  # no pair to check
        return doc
    leg = int(math.floor(certificate.closest_time))
    doc.update(
        certified=certificate.certified,
        lower_bound_m=certificate.lower_bound,
        closest_pair=list(certificate.closest_pair),
        closest_m=certificate.closest_distance,
        closest_leg=leg,
        closest_fraction=certificate.closest_time - leg,
        n_samples=certificate.n_samples,
    )
    return doc


def _print_clearance(doc: dict[str, Any]) -> None:
    """Print the clearance line of a 3-D run (coal's closest pair, where on the path)."""
    clear = doc.get("clearance")
    if clear is None:
        return
    if clear["certified"] is None:
        print(f"clearance: margin {clear['margin_m']:g} m, no pair to check")
        return
    verdict = "certified" if clear["certified"] else "NOT certified"
    a, b = clear["closest_pair"]
    print(
        f"clearance: closest pair {a} / {b} at {clear['closest_m']:.6g} m (coal), "
        f"leg {clear['closest_leg']} at fraction {clear['closest_fraction']:.3f}; margin "
        f"{clear['margin_m']:g} m, {verdict} (lower bound {clear['lower_bound_m']:.6g} m)"
    )


def print_3d(
    summary: JSONDict,
    robot: str,
    frame: str,
    n_targets: int,
    method: str,
    starts: StartsFile | None,
) -> None:
    """Print a 3-D run's summary: the verdicts, the starts and the best path."""
    doc: dict[str, Any] = summary
    print(f"IK path (spatial): {robot}, frame {frame}, {n_targets} targets, method {method}")
    for v in doc["reachability"]:
        print(f"  target {v['index']}: {v['verdict']} ({v['message']})")
    if doc["E"] is None or starts is None:
        return
    print_starts(doc, starts.crashed)
    print(
        f"best: E = {doc['E']:.10g} rad^2 ({doc['status']}, start {doc['start_index']}), "
        f"{doc['n_success']} of {doc['starts']} starts succeeded, {len(doc['minima'])} "
        "distinct minima"
    )
    _print_certainty(doc)
    _print_clearance(doc)
    if not doc["result"]["success"]:
        print(f"failed ({doc['status']}): {doc['result']['message']}")
    for j, q in enumerate(doc["result"]["configurations_rad"]):
        print(f"  q{j + 1} = [{', '.join(f'{x:+.6f}' for x in q)}] rad")
