"""Work with no end is bounded: a failed 2-knot solve, a replay of 1e6 s per move (#29).

Before: `solve --knots 2 --no-refine` spent minutes certifying, then replaying, a failed
plan with T = 5.7e5 s (1.7e7 frames); `ikpath --segment-time 1e6` asked the replay
for 6e7 frames.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from youbot_opt.cli import main
from youbot_opt.viz.meshcat.scene import MAX_REPLAY_FRAMES, Run, frame_times


def test_a_failed_two_knot_solve_returns_at_once_with_its_files(tmp_path, capsys):
    out = tmp_path / "run"
    assert (
        main(["solve", "--robot", "youbot", "--knots", "2", "--no-refine", "--out", str(out)]) == 1
    )
    text = capsys.readouterr()
    assert "certificate   none: the solve failed" in text.out
    assert f"more than MAX_REPLAY_FRAMES = {MAX_REPLAY_FRAMES}" in text.err
    assert not (out / "replay.html").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert (out / "result.npz").is_file() and summary["status"] != "solved"


@pytest.mark.parametrize("value", ["1e6", "0", "-1", "nan", "inf"])
def test_segment_time_is_range_checked(value, tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        main(["ikpath", "--example", "A", "--segment-time", value, "--out", str(tmp_path / "r")])
    assert info.value.code == 2
    assert "--segment-time must be" in capsys.readouterr().err


def test_the_frame_limit_names_duration_and_limit():
    import numpy as np

    from youbot_opt.exceptions import ParameterError

    long = Run(node="", t=np.array([0.0, 1e4]), q=np.zeros((2, 1)), offset=np.zeros(3),
               opacity=1.0, color=0, with_targets=False)  # fmt: skip
    with pytest.raises(ParameterError, match=r"replay of 10000 s at 30 frames/s needs 3e\+05"):
        frame_times([long], 30.0)
    assert frame_times([long], 3.0).size == 30_001  # within the limit: every frame


@pytest.mark.parametrize(
    "argv",
    [
        ["pareto", "--first-starts", "1000000000000"],
        ["reproduce-study1", "--quick", "--starts", "100000000000000"],
    ],
)
def test_start_counts_past_the_memory_are_refused_before_any_task_list(argv, tmp_path, capsys):
    """Before: both built their task lists eagerly (hours and all the memory)."""
    assert main([*argv, "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "TiB of memory" in err and "YOUBOT_OPT_MEMORY_LIMIT_GB" in err


def test_a_fifo_or_a_device_is_refused_without_blocking(tmp_path, capsys):
    """--from-json and IK result files: a FIFO blocked forever, /dev/zero ate the memory."""
    import os

    from youbot_opt.exceptions import ResultFileError
    from youbot_opt.ikpath.io import load_result

    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for path, kind in ((fifo, "a FIFO"), ("/dev/zero", "a character device")):
        assert (
            main(["reproduce-study1", "--from-json", str(path), "--out", str(tmp_path / "r")]) == 2
        )
        assert f"is not a regular file ({kind})" in capsys.readouterr().err
        with pytest.raises(ResultFileError, match=rf"is not a regular file \({kind}\)"):
            load_result(path)


@pytest.mark.parametrize(
    ("text", "message"),
    [("[1, 2]", "is an object, got a list"), ('{"a": 1}', "field 'config' must be a JSON dict")],
)
def test_a_reproduction_json_of_the_wrong_shape_is_refused(text, message, tmp_path, capsys):
    path = tmp_path / "wrong.json"
    path.write_text(text)
    assert main(["reproduce-study1", "--from-json", str(path), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_a_fifo_as_the_linear_solver_library_is_refused(tmp_path, capsys):
    """IPOPT's dlopen of a FIFO blocked forever (#29)."""
    import os

    fifo = tmp_path / "libhsl.so"
    os.mkfifo(fifo)
    argv = ["solve", "--linear-solver", "ma27", "--linear-solver-library", str(fifo)]
    assert main([*argv, "--no-refine", "--out", str(tmp_path / "r")]) == 2
    assert "is not a regular file" in capsys.readouterr().err


def _in_a_thread(call, seconds: float = 20.0):
    """Run ``call`` in a daemon thread; fail (instead of hanging the suite) if it blocks."""
    import threading

    box: dict[str, BaseException | None] = {}

    def run() -> None:
        try:
            call()
        except BaseException as exc:  # noqa: BLE001 - handed back to the test
            box["raised"] = exc
        else:
            box["raised"] = None

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), f"{call!r} blocked for {seconds} s"
    return box["raised"]


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_a_library_path_that_is_no_regular_file_is_named_and_never_opened(tmp_path, capsys, kind):
    """--linear-solver-library and IPOPT's own hsllib option: a FIFO blocked dlopen (#29).

    The refusal names the path and what it is; ``extra={"hsllib": fifo}`` (IPOPT's
    option, which wins over the field) went straight to ``ctypes.CDLL`` and blocked.
    """
    import os

    from youbot_opt.exceptions import ParameterError
    from youbot_opt.nlp.ipopt import IpoptOptions, check_linear_solver

    if kind == "fifo":
        path = tmp_path / "libhsl.so"
        os.mkfifo(path)
        what = "a FIFO"
    else:
        path = Path("/dev/zero")
        what = "a character device"
    argv = ["solve", "--linear-solver", "ma27", "--linear-solver-library", str(path)]
    assert main([*argv, "--no-refine", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and what in err and "Traceback" not in err
    for options in (
        IpoptOptions(linear_solver="ma27", extra={"hsllib": str(path)}),
        IpoptOptions(linear_solver="pardiso", extra={"pardisolib": str(path)}),
    ):
        raised = _in_a_thread(lambda options=options: check_linear_solver(options))
        assert isinstance(raised, ParameterError), raised
        assert str(path) in str(raised) and what in str(raised)


def test_a_trajectory_result_path_that_is_a_fifo_is_named_as_one(tmp_path):
    """load_result of a FIFO said "does not exist"; it names what the path is."""
    import os

    from youbot_opt.exceptions import ResultFileError
    from youbot_opt.trajopt.io import load_result

    fifo = tmp_path / "result.npz"
    os.mkfifo(fifo)
    raised = _in_a_thread(lambda: load_result(fifo))
    assert isinstance(raised, ResultFileError)
    assert "is not a regular file (a FIFO)" in str(raised) and str(fifo) in str(raised)
    with pytest.raises(ResultFileError, match="does not exist"):
        load_result(tmp_path / "missing.npz")
