"""Size limits and "dynamics defined" checks of the strict loader (issue 16, items 1-3).

The huge files of the issue (a 10,000-link chain that overflowed the stack in
Pinocchio's parser, 100,000 nested elements, 10,000 children of one link, a
1 MB attribute) are generated here in a temporary folder, not kept in git, and
loaded in capped child processes (``_load_in_subprocess.py``); files just past
each limit live in the corpus (``urdf_corpus/limits``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pinocchio as pin
import pytest

from youbot_opt.exceptions import (
    InvalidModelError,
    ParameterError,
    UnsafeURDFError,
    URDFStructureError,
    URDFSyntaxError,
)
from youbot_opt.robot.urdf_check.dynamics_defined import check_dynamics_defined
from youbot_opt.robot.urdf_check.rules import check_mimic_graph
from youbot_opt.robot.urdf_check.size import MAX_TREE_DEPTH, check_urdf_size, tree_depth
from youbot_opt.robot.urdf_check.xml import parse_number, parse_xml_strict, shorten, site

HERE = Path(__file__).resolve().parent
HELPER = HERE / "_load_in_subprocess.py"
CORPUS = HERE / "urdf_corpus"
LIMIT = '<limit lower="-1" upper="1" effort="1" velocity="1"/>'
INERTIAL = (
    '<inertial><mass value="1"/>'
    '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>'
)


def _robot(body: str) -> str:
    return f'<?xml version="1.0"?>\n<robot name="big">\n<link name="l0"/>\n{body}</robot>\n'


def _joint(i: int, parent: str, jtype: str = "revolute") -> str:
    extra = f'<axis xyz="0 1 0"/>{LIMIT}' if jtype != "fixed" else ""
    return (
        f'<link name="l{i}">{INERTIAL}</link><joint name="j{i}" type="{jtype}">'
        f'<parent link="{parent}"/><child link="l{i}"/>{extra}</joint>\n'
    )


def _huge_files() -> dict[str, tuple[str, str, str]]:
    """name -> (text, expected error class, message fragment): the issue's reports."""
    nest = 100_000
    macros = 5_000
    return {
        "chain_10000": (
            _robot("".join(_joint(i, f"l{i - 1}") for i in range(1, 10_001))),
            "UnsafeURDFError",
            "has 10,000 joints, more than the limit of 1,000",
        ),
        "chain_5000_fixed": (
            _robot("".join(_joint(i, f"l{i - 1}", "fixed") for i in range(1, 5_001))),
            "UnsafeURDFError",
            "has 5,000 joints",
        ),
        "chain_2000": (
            _robot("".join(_joint(i, f"l{i - 1}") for i in range(1, 2_001))),
            "UnsafeURDFError",
            "has 2,000 joints",
        ),
        "chain_900_fixed": (  # under the joint limit, over the depth limit
            _robot("".join(_joint(i, f"l{i - 1}", "fixed") for i in range(1, 901))),
            "UnsafeURDFError",
            "has a chain of 900 joints, deeper than the limit of 500",
        ),
        "chain_250": (
            _robot("".join(_joint(i, f"l{i - 1}") for i in range(1, 251))),
            "UnsafeURDFError",
            "has 250 degrees of freedom, more than the limit of 100",
        ),
        "star_10000": (
            _robot("".join(_joint(i, "l0") for i in range(1, 10_001))),
            "UnsafeURDFError",
            "has 10,000 joints",
        ),
        "nesting_100000": (
            _robot("<gazebo>" + "<g>" * nest + "</g>" * nest + "</gazebo>\n"),
            "UnsafeURDFError",
            "the XML nesting exceeds the limit of 100",
        ),
        "xacro_macros_5000": (
            '<robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro"><link name="l0"/>'
            + "".join(f'<xacro:macro name="m{i}" params="a">' for i in range(macros))
            + "</xacro:macro>" * macros
            + "</robot>",
            "UnsafeURDFError",
            "the XML nesting exceeds the limit of 100",
        ),
        "elements_300000": (
            _robot("<gazebo>" + "<p/>" * 300_000 + "</gazebo>\n"),
            "UnsafeURDFError",
            "the XML element count exceeds the limit of 200,000",
        ),
        "attribute_1MB": (
            _robot(
                INERTIAL.replace('value="1"', f'value="{"1" * 2**20}x"').join(
                    ['<link name="a">', "</link>"]
                )
            ),
            "InvalidModelError",
            "characters>...",
        ),
    }


def test_huge_files_are_refused_before_any_expensive_step(tmp_path: Path) -> None:
    """Each of the issue's huge files ends in its documented URDFError in a capped child.

    Before the limits these ended in SIGSEGV (10,000 and 5,000 links), MemoryError (2,000
    links under 2 GiB; 10,000 children after 13 s) or RecursionError (deep nesting). The
    caps are the harness's 2 GiB and a 20 s wall clock; the error message stays short
    (a 1 MB attribute is quoted elided).
    """
    files = _huge_files()
    jobs = []
    for name, (text, _, _) in files.items():
        path = tmp_path / f"{name}.urdf"
        path.write_text(text)
        jobs.append({"id": name, "path": str(path), "package_dirs": []})
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    for key in [k for k in env if k.startswith("YOUBOT_OPT_MAX_")]:
        del env[key]
    done = subprocess.run(
        [sys.executable, str(HELPER)],
        input=json.dumps(jobs),
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
        check=True,
    )
    reports = {r["id"]: r for r in map(json.loads, done.stdout.splitlines())}
    for name, (_, error_class, fragment) in files.items():
        report = reports[name]
        assert report["outcome"] == "error", (name, report)
        assert report["error_class"] == error_class, (name, report["message"][:300])
        assert fragment in report["message"], (name, report["message"][:300])
        assert len(report["message"]) < 1000, name
        assert f"{name}.urdf" in report["message"]


def test_limits_can_be_raised_by_keyword_and_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    """The 501-deep corpus chain is refused by default, accepted with a raised limit."""
    path = CORPUS / "limits" / "depth_501_chain.urdf"
    tree = parse_xml_strict(path.read_bytes(), str(path))
    monkeypatch.delenv("YOUBOT_OPT_MAX_TREE_DEPTH", raising=False)
    with pytest.raises(UnsafeURDFError, match="YOUBOT_OPT_MAX_TREE_DEPTH"):
        check_urdf_size(tree, str(path))
    check_urdf_size(tree, str(path), max_depth=501)
    monkeypatch.setenv("YOUBOT_OPT_MAX_TREE_DEPTH", "600")
    check_urdf_size(tree, str(path))
    monkeypatch.setenv("YOUBOT_OPT_MAX_TREE_DEPTH", "lots")
    with pytest.raises(ParameterError, match="YOUBOT_OPT_MAX_TREE_DEPTH='lots'"):
        check_urdf_size(tree, str(path))
    with pytest.raises(ParameterError, match="max_dof=0"):
        check_urdf_size(tree, str(path), max_depth=600, max_dof=0)
    deep = b"<robot name='r'>" + b"<g>" * 150 + b"</g>" * 150 + b"</robot>"
    with pytest.raises(UnsafeURDFError, match="YOUBOT_OPT_MAX_XML_DEPTH"):
        parse_xml_strict(deep, "deep.urdf")
    monkeypatch.setenv("YOUBOT_OPT_MAX_XML_DEPTH", "200")
    assert len(list(parse_xml_strict(deep, "deep.urdf").iter("g"))) == 150


def test_nesting_past_libxml2s_own_stop_is_refused_as_the_nesting_limit() -> None:
    """A limit raised past libxml2's 256 levels still refuses deeper files, naming libxml2's."""
    deep = b"<robot name='r'>" + b"<g>" * 300 + b"</g>" * 300 + b"</robot>"
    with pytest.raises(UnsafeURDFError, match="libxml2's limit of 256 levels") as info:
        parse_xml_strict(deep, "deep.urdf", max_depth=1000)
    assert info.value.rule == "XML nesting <= 1,000 levels and <= 200,000 elements"


def test_text_nodes_past_10_mb_are_read_for_meshes_only() -> None:
    """A 12 MB text node (a COLLADA vertex array) is malformed in a URDF, read in a mesh."""
    data = b"<float_array>" + b"0 " * (6 * 2**20) + b"</float_array>"
    with pytest.raises(URDFSyntaxError, match="not well-formed XML"):
        parse_xml_strict(data, "big.urdf")
    root = parse_xml_strict(data, "big.dae", long_text=True).getroot()
    assert len(root.text) == 12 * 2**20


def test_tree_depth_counts_the_longest_joint_chain() -> None:
    """Hand-counted trees: a chain, a star, a fork, and a loop (tolerated, counted once)."""

    def depth(pairs: list[tuple[str, str]]) -> int:
        body = "".join(
            f'<joint name="j{i}"><parent link="{p}"/><child link="{c}"/></joint>'
            for i, (p, c) in enumerate(pairs)
        )
        return tree_depth(ET.fromstring(f"<robot>{body}</robot>"))

    assert depth([]) == 0
    assert depth([("a", "b"), ("b", "c"), ("c", "d")]) == 3
    assert depth([("a", "b"), ("a", "c"), ("a", "d")]) == 1
    assert depth([("a", "b"), ("b", "c"), ("a", "x"), ("x", "y"), ("y", "z")]) == 3
    assert depth([("a", "b"), ("b", "a")]) == 2
    chain = [(f"l{i}", f"l{i + 1}") for i in range(5 * MAX_TREE_DEPTH)]  # no recursion
    assert depth(chain) == 5 * MAX_TREE_DEPTH


def test_long_values_are_quoted_elided_and_numbers_fail_in_linear_time() -> None:
    """A megabyte of digits and a letter: refused quickly (the pattern cannot backtrack)."""
    text = "1" * 2**20 + "x"
    where = site("f.urdf", ET.Element("mass"))
    with pytest.raises(InvalidModelError) as info:
        parse_number(text, where, "value")
    assert len(str(info.value)) < 400
    assert "1,048,5" in str(info.value)  # the number of characters left out
    assert shorten("abc") == "'abc'"
    assert shorten("a" * 100, 20) == "'aaaaaaaaa...<82 characters>...aaaaaaaaa'"


def test_subnormal_inertia_is_refused_by_the_dynamics_check() -> None:
    """mass = inertia = 5e-324: positive and finite, but ABA is NaN; 1e-3 kg passes."""
    text = (CORPUS / "physics" / "subnormal_mass_and_inertia.urdf").read_text()
    model = pin.buildModelFromXML(text)
    assert model.inertias[1].mass > 0
    with pytest.raises(InvalidModelError, match=r"ABA \(joint accelerations\) is not finite"):
        check_dynamics_defined(model, "subnormal.urdf")
    fine = text.replace("5e-324", "1e-3")
    check_dynamics_defined(pin.buildModelFromXML(fine), "fine.urdf")


def test_ill_conditioned_mass_matrix_is_refused() -> None:
    """A 1e-13 kg m^2 tip on a 10 kg arm: M(q) condition number ~1e13 > 1e12."""
    text = (CORPUS / "valid" / "gimbal_massless_middle.urdf").read_text()
    model = pin.buildModelFromXML(text)
    check_dynamics_defined(model, "gimbal.urdf")
    model.inertias[model.njoints - 1] = pin.Inertia(
        1e-13, pin.utils.zero(3), 1e-13 * pin.utils.eye(3)
    )
    model.inertias[1] = pin.Inertia(10.0, pin.utils.zero(3), 10.0 * pin.utils.eye(3))
    with pytest.raises(InvalidModelError, match="condition number"):
        check_dynamics_defined(model, "gimbal.urdf")


def test_mimic_graph_names_the_cycle_and_the_chain() -> None:
    """A three-joint cycle and a two-step chain are refused with every joint named."""

    def joints(relations: dict[str, str | None]) -> dict[str, ET.Element]:
        out = {}
        for name, target in relations.items():
            joint = ET.Element("joint", name=name, type="revolute")
            if target is not None:
                ET.SubElement(joint, "mimic", joint=target)
            out[name] = joint
        return out

    with pytest.raises(URDFStructureError, match="mimic cycle 'a' -> 'b' -> 'c' -> 'a'"):
        check_mimic_graph(joints({"a": "b", "b": "c", "c": "a"}), "m.urdf")
    with pytest.raises(URDFStructureError, match="the chain 'a' -> 'b' -> 'c'"):
        check_mimic_graph(joints({"a": "b", "b": "c", "c": None}), "m.urdf")
    with pytest.raises(URDFStructureError, match="mimics 'ghost', not another joint"):
        check_mimic_graph(joints({"a": "ghost"}), "m.urdf")
    check_mimic_graph(joints({"a": "c", "b": "c", "c": None}), "m.urdf")  # two followers: fine
