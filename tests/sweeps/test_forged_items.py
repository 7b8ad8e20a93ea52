"""Forged sweep items (#29): copied from another sweep, re-bound, checksums recomputed.

The attacker uses the library's own code: the journal lines of a beta = 0.9
store are re-bound to the beta = 0.5 store's published binding (its manifest)
and re-encoded with :func:`~youbot_opt.sweeps.journal.encode_line`, which
recomputes their checksums; the payloads are copied beside them. The store's
checksums then all agree, so only what the payload itself says can tell: the
item is re-checked against the sweep's own problem (beta, bound scale, start
seed, objective at the sweep's beta) and refused, then recomputed.
"""

from __future__ import annotations

import json
import shutil
import warnings
from pathlib import Path

import pytest

from youbot_opt.exceptions import YoubotOptWarning
from youbot_opt.sweeps.journal import encode_line, read_journal
from youbot_opt.sweeps.options import SweepOptions

_KNOTS = 15


@pytest.fixture(scope="module")
def small_solver():  # type: ignore[no-untyped-def]
    """A 15-knot study-1 solver, built once for the tests below."""
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.solver import TrajOptSolver

    return TrajOptSolver(study1_problem(_KNOTS))


def _forge(source: Path, target: Path, keys: dict[str, str] | None = None) -> None:
    """Copy ``source``'s items into ``target`` as an attacker would (re-bound, re-checksummed).

    ``keys`` renames items (source key -> target key): a start's item passed off as another's.
    """
    binding = json.loads((target / "manifest.json").read_text())["binding"]
    lines, _ = read_journal(source / "items" / "journal")
    folder = target / "items" / "journal"
    shutil.rmtree(folder)
    folder.mkdir()
    out = bytearray()
    for line in lines:
        key = (keys or {}).get(line["key"], line["key"])
        forged = {**line, "key": key, "sweep": binding}
        if line.get("payload"):
            src = source / "items" / line["payload"]
            name = src.name.replace(line["key"], key)
            dst_rel = next(target.glob(f"items/*/{name}")).relative_to(target / "items")
            shutil.copyfile(src, target / "items" / dst_rel)
            forged["payload"] = dst_rel.as_posix()
        out += encode_line(forged)  # the library's own checksum
    (folder / "forged.jsonl").write_bytes(bytes(out))


def _sweep(solver, beta: float, out: Path, *, keep: bool = True, n: int = 1):  # type: ignore[no-untyped-def]
    from youbot_opt.trajopt.multistart import run_multistart

    opts = SweepOptions(executor="serial", out=out, keep_results=keep)
    return run_multistart(solver, n, beta=beta, seed=5, include_straight=False, sweep=opts)


@pytest.mark.parametrize("keep", [True, False])
def test_forged_item_from_another_beta_is_refused(small_solver, tmp_path: Path, keep: bool) -> None:  # type: ignore[no-untyped-def]
    """A beta = 0.9 item re-bound into a beta = 0.5 store is refused and recomputed."""
    other = _sweep(small_solver, 0.9, tmp_path / "b09", keep=keep)
    mine = _sweep(small_solver, 0.5, tmp_path / "b05", keep=keep)
    f09, f05 = other.best.objective, mine.best.objective
    assert f09 != f05
    _forge(tmp_path / "b09", tmp_path / "b05")
    with pytest.warns(YoubotOptWarning, match=r"start_0000.*beta = 0\.9.*0\.5"):
        again = _sweep(small_solver, 0.5, tmp_path / "b05", keep=keep)
    assert again.best.objective == f05  # not the beta = 0.9 optimum
    assert again.best.result is not None and again.best.result.beta == 0.5
    with warnings.catch_warnings():  # recomputed and bound again: loaded without a word
        warnings.simplefilter("error", YoubotOptWarning)
        assert _sweep(small_solver, 0.5, tmp_path / "b05", keep=keep).best.objective == f05


def test_forged_item_with_edited_beta_is_refused(small_solver, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """The payload's own beta edited to the sweep's: its objective then betrays it."""
    import numpy as np

    from youbot_opt.trajopt.io import load_result, save_result

    _sweep(small_solver, 0.9, tmp_path / "b09")
    mine = _sweep(small_solver, 0.5, tmp_path / "b05")
    npz = next((tmp_path / "b09").glob("items/*/start_0000.npz"))
    result = load_result(npz, robot=small_solver.problem.robot)
    import dataclasses

    edited = dataclasses.replace(result, beta=0.5)  # objective still the beta = 0.9 one
    save_result(edited, npz)
    with np.load(npz) as data:
        assert "metadata" in data
    _forge(tmp_path / "b09", tmp_path / "b05")  # lines re-made over the edited payload
    lines, _ = read_journal(tmp_path / "b05" / "items" / "journal")
    from youbot_opt.sweeps.records import sha256_file

    fixed = []
    for line in lines:  # the attacker also recomputes the payload checksum
        fixed.append(
            {**line, "checksum": sha256_file(tmp_path / "b05" / "items" / line["payload"])}
        )
    (tmp_path / "b05" / "items" / "journal" / "forged.jsonl").write_bytes(
        b"".join(encode_line(x) for x in fixed)
    )
    with pytest.warns(YoubotOptWarning, match=r"start_0000.*objective"):
        again = _sweep(small_solver, 0.5, tmp_path / "b05")
    assert again.resumed == 0
    assert again.best.objective == mine.best.objective


def _edit_payload(store: Path, key: str, robot, edit) -> None:  # type: ignore[no-untyped-def]
    """Rewrite item ``key``'s payload with ``edit(result)`` and re-checksum its journal line.

    As an attacker would: the library's ``load_result``/``save_result`` rewrite the
    payload, :func:`~youbot_opt.sweeps.records.sha256_file` recomputes its checksum
    and :func:`~youbot_opt.sweeps.journal.encode_line` the line's own.
    """
    from youbot_opt.sweeps.records import sha256_file
    from youbot_opt.trajopt.io import load_result, save_result

    npz = next(store.glob(f"items/*/{key}.npz"))
    save_result(edit(load_result(npz, robot=robot)), npz)
    folder = store / "items" / "journal"
    lines, _ = read_journal(folder)
    fixed = [
        {**x, "checksum": sha256_file(store / "items" / x["payload"])} if x["key"] == key else x
        for x in lines
    ]
    for old in folder.iterdir():
        old.unlink()
    (folder / "edited.jsonl").write_bytes(b"".join(encode_line(x) for x in fixed))


def _at_beta(result, beta: float):  # type: ignore[no-untyped-def]
    """``result`` passed off as a solve at ``beta``: its beta and its objective made consistent."""
    import dataclasses

    value = beta * result.duration + (1.0 - beta) * result.work
    return dataclasses.replace(result, beta=beta, objective=value)


@pytest.mark.parametrize("keep", [True, False])
def test_forged_item_with_beta_and_objective_edited_consistently_is_refused(  # type: ignore[no-untyped-def]
    small_solver, tmp_path: Path, keep: bool
) -> None:
    """A beta = 0.9 optimum whose beta and objective are edited to a beta = 0.5 solve.

    Problem, beta, bound scale, seed and objective (re-evaluated from its own
    trajectory at the sweep's beta) all agree, and the plan is feasible: only
    optimality tells. At the sweep's beta the stored point is no first-order
    optimum of the sweep's problem (the gradient of the Lagrangian, with the
    file's multipliers, is far from zero), so it is refused and recomputed.
    """
    robot = small_solver.problem.robot
    _sweep(small_solver, 0.9, tmp_path / "b09", keep=keep)
    mine = _sweep(small_solver, 0.5, tmp_path / "b05", keep=keep)
    _forge(tmp_path / "b09", tmp_path / "b05")
    _edit_payload(tmp_path / "b05", "start_0000", robot, lambda r: _at_beta(r, 0.5))
    with pytest.warns(YoubotOptWarning, match=r"start_0000.*first-order optimum.*beta = 0\.5"):
        again = _sweep(small_solver, 0.5, tmp_path / "b05", keep=keep)
    assert again.resumed == 0
    assert again.best.objective == mine.best.objective
    with warnings.catch_warnings():  # recomputed and bound again: loaded without a word
        warnings.simplefilter("error", YoubotOptWarning)
        assert _sweep(small_solver, 0.5, tmp_path / "b05", keep=keep).resumed == 1


def _fitted_multipliers(solver, result, beta: float, how: str):  # type: ignore[no-untyped-def]
    """``result`` with multipliers made up to zero its Lagrangian's gradient at ``beta``.

    ``how = "bounds"``: every variable's bound multiplier absorbs the residual
    (then they push against bounds the plan does not touch); ``"rows"``: the
    constraint multipliers are the least-squares fit, the bound ones the file's.
    """
    import dataclasses

    import casadi as ca
    import numpy as np

    from youbot_opt.trajopt.transcription.base import BOUND_NAMES

    nlp = solver.nlp
    m = result.multipliers
    x = nlp.variables.pack(dict(result.variables))
    blocks = nlp.variables.blocks
    lam_x = nlp.variables.pack(
        {n: m[f"{BOUND_NAMES[n]}_lower"] + m[f"{BOUND_NAMES[n]}_upper"] for n in blocks}
    )
    lam_g = nlp.constraints.pack({k: m[k] for k in nlp.constraints.blocks})
    grad_f, jac_g = solver.first_order_functions()
    grad = np.asarray(grad_f(x, beta)[1]).ravel()
    jac = np.asarray(ca.densify(jac_g(x, beta)[1]))
    if how == "bounds":
        lam_x = -(grad + jac.T @ lam_g)
    else:
        lam_g = np.linalg.lstsq(jac.T, -(grad + lam_x), rcond=None)[0]
    fitted = dict(nlp.constraints.unpack(lam_g))
    for name, block in nlp.variables.blocks.items():
        lam = block.take(lam_x)
        fitted[f"{BOUND_NAMES[name]}_lower"] = np.minimum(lam, 0.0)
        fitted[f"{BOUND_NAMES[name]}_upper"] = np.maximum(lam, 0.0)
    return dataclasses.replace(result, multipliers=fitted)


@pytest.mark.parametrize(
    ("how", "message"),
    [("bounds", "complementarity|side without a bound"), ("rows", "gradient of its Lagrangian")],
)
def test_forged_item_with_made_up_multipliers_is_refused(  # type: ignore[no-untyped-def]
    small_solver, tmp_path: Path, how: str, message: str
) -> None:
    """The edited beta = 0.9 optimum with multipliers fitted at beta = 0.5 is refused too.

    The multipliers are the file's: checked, never trusted. Those that zero the
    gradient push against bounds the plan does not touch; a least-squares fit
    of the constraint multipliers leaves the gradient far from zero.
    """
    robot = small_solver.problem.robot
    _sweep(small_solver, 0.9, tmp_path / "b09")
    mine = _sweep(small_solver, 0.5, tmp_path / "b05")
    _forge(tmp_path / "b09", tmp_path / "b05")

    def edit(result):  # type: ignore[no-untyped-def]
        return _fitted_multipliers(small_solver, _at_beta(result, 0.5), 0.5, how)

    _edit_payload(tmp_path / "b05", "start_0000", robot, edit)
    with pytest.warns(YoubotOptWarning, match=rf"start_0000.*first-order optimum.*({message})"):
        again = _sweep(small_solver, 0.5, tmp_path / "b05")
    assert again.resumed == 0
    assert again.best.objective == mine.best.objective


def test_stored_successes_are_first_order_optima_of_their_sweep(small_solver) -> None:  # type: ignore[no-untyped-def]
    """What the resume check requires holds for genuine solves, with a wide margin.

    Three transcriptions, beta 0.1, 0.5 and 0.9: each solve is a first-order
    optimum at its own beta (relative figures below 1e-8, the tolerance is 1e-6),
    and none at another beta 0.4 away (above 0.1).
    """
    import dataclasses

    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.optimality import first_order
    from youbot_opt.trajopt.solver import TrajOptSolver

    for method in ("trapezoidal", "hermite_simpson", "radau"):
        solver = (
            small_solver
            if method == "trapezoidal"
            else TrajOptSolver(study1_problem(_KNOTS), method, dynamics=small_solver.dynamics)
        )
        for beta in (0.1, 0.5, 0.9):
            result = solver.solve(beta=beta)
            assert result.success
            own = first_order(solver, result, beta=beta)
            assert own.passed, own.reason
            worst = max(own.stationarity, own.complementarity, own.wrong_side) / own.scale
            assert worst < 1e-8 and own.rtol == 1e-6
            other = first_order(solver, result, beta=0.5 if beta != 0.5 else 0.9)
            assert not other.passed and other.stationarity / other.scale > 0.1
            assert "gradient of its Lagrangian" in str(other.reason)
            scaled = first_order(solver, dataclasses.replace(result), beta=beta, bound_scale=0.5)
            assert not scaled.passed and "violates a bound" in str(scaled.reason)


def test_item_passed_off_as_another_start_is_refused(small_solver, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """Start 0's item re-keyed as start 1 of the same sweep: its seed is not start 1's."""
    first = _sweep(small_solver, 0.5, tmp_path / "a", n=2)
    _sweep(small_solver, 0.5, tmp_path / "b", n=2)
    lines, _ = read_journal(tmp_path / "a" / "items" / "journal")
    assert {x["key"] for x in lines} == {"start_0000", "start_0001"}
    _forge(
        tmp_path / "a",
        tmp_path / "b",
        keys={"start_0001": "start_0000", "start_0000": "start_0001"},
    )
    with pytest.warns(YoubotOptWarning, match=r"seed"):
        again = _sweep(small_solver, 0.5, tmp_path / "b", n=2)
    assert [s.objective for s in again.starts] == [s.objective for s in first.starts]


def _ik(targets, out: Path, n: int = 3, *, keep: bool = True):  # type: ignore[no-untyped-def]
    from youbot_opt.ikpath.multistart import run_multistart
    from youbot_opt.ikpath.problem import CyclicIKProblem
    from youbot_opt.robot.planar import PlanarChain

    problem = CyclicIKProblem(robot=PlanarChain(lengths=[1.0, 0.8]), targets=targets)
    sweep = SweepOptions(workers=1, out=out, keep_results=keep)
    return run_multistart(problem, n_starts=n, seed=4, sweep=sweep)


_T1 = [(1.2, 0.5), (0.3, 1.1), (-0.9, 0.6), (0.4, -1.0)]
_T2 = [(1.2, 0.5), (0.3, 1.1), (-0.9, 0.6), (0.5, -1.0)]


def test_forged_ik_item_from_other_targets_is_refused(tmp_path: Path) -> None:
    """IK: items of a sweep over other targets, re-bound, are refused (they miss these targets)."""
    _ik(_T1, tmp_path / "t1")
    mine = _ik(_T2, tmp_path / "t2")
    _forge(tmp_path / "t1", tmp_path / "t2")
    with pytest.warns(YoubotOptWarning, match=r"start_0000.*problem differs"):
        again = _ik(_T2, tmp_path / "t2")
    assert again.resumed == 0
    assert [r.objective for r in again.results] == [r.objective for r in mine.results]


def test_forged_pareto_point_is_refused_and_recomputed(small_solver, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """Pareto: a point of a beta = 0.9 front re-bound into a beta = 0.5 front is recomputed."""
    from youbot_opt.trajopt.pareto import pareto_sweep

    def front(beta: float, out: Path):  # type: ignore[no-untyped-def]
        opts = SweepOptions(executor="serial", out=out)
        return pareto_sweep(small_solver, [beta], first_starts=0, sweep=opts)

    other, mine = front(0.9, tmp_path / "b09"), front(0.5, tmp_path / "b05")
    assert other.points[0].objective != mine.points[0].objective
    _forge(tmp_path / "b09", tmp_path / "b05")
    with pytest.warns(YoubotOptWarning, match=r"point_000.*beta = 0\.9"):
        again = front(0.5, tmp_path / "b05")
    assert again.resumed == 0 and again.points[0].objective == mine.points[0].objective


@pytest.mark.parametrize("keep", [True, False])
def test_ik_item_passed_off_as_another_start_is_refused(tmp_path: Path, keep: bool) -> None:
    """IK: start 1's item re-keyed as start 3 of the same sweep (and back) is refused.

    Both are checked minima of this very problem, so only the start each item
    carries tells: it is not the start the sweep draws for its key. The two are
    solved again from their own starts; start 0 (untouched) is loaded.
    """
    import numpy as np

    first = _ik(_T1, tmp_path / "a", n=4, keep=keep)
    _ik(_T1, tmp_path / "b", n=4, keep=keep)
    starts = [np.asarray(first.results[i].start) for i in range(4)]
    assert not np.array_equal(starts[1], starts[3])
    assert first.results[1].objective != first.results[3].objective  # other minima
    _forge(
        tmp_path / "a",
        tmp_path / "b",
        keys={"start_0001": "start_0003", "start_0003": "start_0001"},
    )
    with pytest.warns(YoubotOptWarning, match=r"start_000[13].*its start is not start [13]"):
        again = _ik(_T1, tmp_path / "b", n=4, keep=keep)
    assert again.resumed == 2
    for i in range(4):
        assert np.array_equal(np.asarray(again.results[i].start), starts[i])
        assert again.results[i].objective == first.results[i].objective
    with warnings.catch_warnings():  # solved again and bound: loaded without a word
        warnings.simplefilter("error", YoubotOptWarning)
        assert _ik(_T1, tmp_path / "b", n=4, keep=keep).resumed == 4
