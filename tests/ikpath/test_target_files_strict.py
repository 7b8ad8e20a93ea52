"""Target files: orientation is never dropped without a word; bad files are named errors (#29).

Before: a partial quaternion, columns named QX..QW or a JSON key "quaternion" turned a
pose target into a position target silently, and undecodable text, numbers that are
text, JSON of the wrong shape, FIFOs and huge files gave tracebacks or hangs.
"""

from __future__ import annotations

import json
import os

import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.targets import MAX_TARGETS, load_targets


def _csv(tmp_path, text):
    path = tmp_path / "t.csv"
    path.write_text(text)
    return path


def _json(tmp_path, data):
    path = tmp_path / "t.json"
    path.write_text(json.dumps(data))
    return path


def test_a_full_pose_row_and_a_position_row_load(tmp_path):
    path = _csv(tmp_path, "x,y,z,qx,qy,qz,qw\n0.3,0,0.4,0,0,0,1\n0.2,0.1,0.4,,,,\n")
    pose, point = load_targets(path)
    assert pose.rotation is not None and point.rotation is None


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "x,y,z,qx,qy,qz,qw\n0.3,0,0.4,0,0,,1\n",
            "row 1: a partial quaternion (qx, qy, qw given, qz empty)",
        ),
        ("x,y,z,QX,QY,QZ,QW\n0.3,0,0.4,0,0,0,1\n", "unknown column 'QX', 'QY', 'QZ', 'QW'"),
        ("x,y,z,ax,ay,az\n0.3,0,0.4,0,,1\n", "row 1: a partial approach (ax, az given, ay empty)"),
        ("x,y,z\n0.3,zero,0.4\n", "row 1: y must be a number, got 'zero'"),
        ("x,y,z\n0.3,0,0.4,9\n", "row 1: 4 values for the 3 columns of the header"),
        ("x,y\n0.3,0\n", "missing z"),
    ],
)
def test_bad_csv_rows_are_named(tmp_path, text, message):
    with pytest.raises(ParameterError, match=message.replace("(", r"\(").replace(")", r"\)")):
        load_targets(_csv(tmp_path, text))


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ([{"position": [0.3, 0, 0.4], "quaternion": [0, 0, 0, 1]}], "unknown key 'quaternion'"),
        ([[0.3, 0, 0.4]], "a target is an object with a position"),
        ({"targets": 3}, "expected a list of targets"),
        ([{"quaternion_xyzw": [0, 0, 0, 1]}], "needs a position"),
        ([{"position": [0.3, 0, 0.4], "position_tol": "tight"}], "position_tol must be a number"),
    ],
)
def test_bad_json_targets_are_named(tmp_path, data, message):
    with pytest.raises(ParameterError, match=message):
        load_targets(_json(tmp_path, data))


def test_undecodable_fifo_and_too_many(tmp_path):
    bad = tmp_path / "t.csv"
    bad.write_bytes(b"x,y,z\n\xff\xfe,0,0\n")
    with pytest.raises(ParameterError, match="not UTF-8"):
        load_targets(bad)
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    with pytest.raises(ParameterError, match="not a regular file"):
        load_targets(fifo)
    many = _csv(tmp_path, "x,y,z\n" + "0.3,0,0.4\n" * (MAX_TARGETS + 1))
    with pytest.raises(ParameterError, match=f"more than MAX_TARGETS = {MAX_TARGETS}"):
        load_targets(many)
    long = _csv(tmp_path, "x,y,z\n" + "1" * 200_000 + "x,0,0\n")
    with pytest.raises(ParameterError, match=r"not a CSV file \(field larger than field limit"):
        load_targets(long)
