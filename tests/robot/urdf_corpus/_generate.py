"""Regenerate the hostile-URDF corpus: ``python tests/robot/urdf_corpus/_generate.py``.

Writes the URDF files (one folder per expected outcome), ``manifest.json``
(file -> expected error class, a fragment of the expected message and why the
file is hostile) and the small mesh package ``pkg/corpus_pkg``. Fixtures git
cannot hold (symlinks, a FIFO, a folder named like a mesh) are made by
``tests/robot/test_loader.py`` in a temporary copy of the package. Output is
deterministic.
"""

# ruff: noqa: E501, E741
# fmt: off
import json
import struct
import zlib
from collections import Counter
from pathlib import Path

OUT = Path(__file__).resolve().parent
BASE = """<?xml version="1.0"?>
<!-- {why} -->
<robot name="corpus">
  <link name="base"/>
  <link name="arm">
    <inertial>
      <origin xyz="0 0 0.1" rpy="0 0 0"/>
      <mass value="1.0"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.001"/>
    </inertial>
    <visual>
      <geometry>
        <mesh filename="package://corpus_pkg/meshes/box.stl"/>
      </geometry>
    </visual>
  </link>
  <joint name="shoulder" type="revolute">
    <parent link="base"/>
    <child link="arm"/>
    <axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="1.5" effort="10" velocity="2"/>
  </joint>
</robot>
"""
MESH = 'filename="package://corpus_pkg/meshes/box.stl"'
MASS = '<mass value="1.0"/>'
INERTIA = '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.001"/>'
AXIS = '<axis xyz="0 1 0"/>'
LIMIT = '<limit lower="-1.5" upper="1.5" effort="10" velocity="2"/>'
END = "</robot>\n"

_COLLADA = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
  <library_images>
    <image id="tex-image" name="tex">
      <init_from>{texture}</init_from>
    </image>
  </library_images>
  <library_effects>
    <effect id="mat-effect">
      <profile_COMMON>
        <newparam sid="tex-surface">
          <surface type="2D">
            <init_from>tex-image</init_from>
          </surface>
        </newparam>
        <newparam sid="tex-sampler">
          <sampler2D><source>tex-surface</source></sampler2D>
        </newparam>
        <technique sid="common">
          <lambert><diffuse><texture texture="tex-sampler" texcoord="UVMap"/></diffuse></lambert>
        </technique>
      </profile_COMMON>
    </effect>
  </library_effects>
  <library_materials>
    <material id="mat" name="mat"><instance_effect url="#mat-effect"/></material>
  </library_materials>
  <library_geometries>
    <geometry id="tri-mesh" name="tri">
      <mesh>
        <source id="tri-positions">
          <float_array id="tri-positions-array" count="9">0 0 0 0.05 0 0 0 0.05 0</float_array>
          <technique_common>
            <accessor source="#tri-positions-array" count="3" stride="3">
              <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
            </accessor>
          </technique_common>
        </source>
        <vertices id="tri-vertices"><input semantic="POSITION" source="#tri-positions"/></vertices>
        <triangles material="mat" count="1">
          <input semantic="VERTEX" source="#tri-vertices" offset="0"/>
          <p>0 1 2</p>
        </triangles>
      </mesh>
    </geometry>
  </library_geometries>
  <library_visual_scenes>
    <visual_scene id="scene" name="scene">
      <node id="tri-node" name="tri">
        <instance_geometry url="#tri-mesh">
          <bind_material><technique_common><instance_material symbol="mat" target="#mat"/></technique_common></bind_material>
        </instance_geometry>
      </node>
    </visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
"""
_OBJ = "# tetrahedron\nmtllib {mtl}\nv 0 0 0\nv 0.05 0 0\nv 0 0.05 0\nv 0 0 0.05\nusemtl grey\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
_STL_FACETS = [
    ("0 0 -1", ["0 0 0", "0 0.05 0", "0.05 0 0"]),
    ("0 -1 0", ["0 0 0", "0.05 0 0", "0 0 0.05"]),
    ("-1 0 0", ["0 0 0", "0 0 0.05", "0 0.05 0"]),
    ("0.577 0.577 0.577", ["0.05 0 0", "0 0.05 0", "0 0 0.05"]),
]


def _png_1x1() -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = zlib.crc32(kind + data) & 0xFFFFFFFF
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)

    header = struct.pack(">IIBBBBB", 1, 1, 8, 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(b"\x00\xff\x80\x00"))
        + chunk(b"IEND", b"")
    )


def write_package() -> None:
    """Write the meshes and textures of ``pkg/corpus_pkg`` (benign and hostile)."""
    meshes = OUT / "pkg" / "corpus_pkg" / "meshes"
    meshes.mkdir(parents=True, exist_ok=True)
    stl = ["solid tetra"]
    for normal, vertices in _STL_FACETS:
        stl += [f"  facet normal {normal}", "    outer loop"]
        stl += [f"      vertex {v}" for v in vertices]
        stl += ["    endloop", "  endfacet"]
    (meshes / "box.stl").write_text("\n".join([*stl, "endsolid tetra"]) + "\n")
    (meshes / "tex.png").write_bytes(_png_1x1())
    (meshes / "model.fbx").write_bytes(b"Kaydara FBX Binary  \x00\x1a\x00")
    textures = {
        "textured": "tex.png",
        "missing_texture": "no_such_texture.png",
        "evil_texture_absolute": "/etc/passwd",
        "evil_texture_dotdot": "../" * 10 + "etc/passwd",
        "evil_texture_http": "http://example.com/tex.png",
        "evil_texture_file_uri": "file:///etc/passwd",
        "evil_texture_percent": "%2e%2e/" * 8 + "etc/passwd",
    }
    for name, texture in textures.items():
        (meshes / f"{name}.dae").write_text(_COLLADA.format(texture=texture))
    v15 = _COLLADA.replace('version="1.4.1"', 'version="1.5.0"').replace("2005/11", "2008/03")
    (meshes / "evil_texture_ref_1_5.dae").write_text(v15.format(texture="<ref>/etc/passwd</ref>"))
    doctype = '<!DOCTYPE COLLADA [\n  <!ENTITY secret SYSTEM "file:///etc/passwd">\n]>\n'
    xxe = _COLLADA.format(texture="&secret;").replace("?>\n", "?>\n" + doctype, 1)
    (meshes / "evil_entity.dae").write_text(xxe)
    (meshes / "broken.dae").write_text(_COLLADA.format(texture="tex.png")[:900])
    (meshes / "tetra.obj").write_text(_OBJ.format(mtl="tetra.mtl"))
    (meshes / "tetra.mtl").write_text("newmtl grey\nKd 0.5 0.5 0.5\n")
    (meshes / "evil_mtllib.obj").write_text(_OBJ.format(mtl="../" * 10 + "etc/passwd"))


def write_corpus() -> list[dict]:
    """Write the URDF files; return the manifest entries."""
    entries: list[dict] = []



    def add(group, name, expect, match, why, text=None, *, subs=(), data=None, element=None):
        if data is None:
            if text is None:
                text = BASE
                for old, new in subs:
                    assert text.count(old) >= 1, (name, old)
                    text = text.replace(old, new, 1)
            text = text.replace("{why}", why.replace("--", "- -"))
            data = text.encode()
        path = OUT / group / f"{name}.urdf"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
        entry = {"file": f"{group}/{name}.urdf", "expect": expect, "match": match, "why": why}
        if element is not None:  # the URDF element the error must name (mesh and texture rules)
            entry["element"] = element
        entries.append(entry)


    def mesh(ref):
        return [(MESH, f'filename="{ref}"')]


    def visual(ref, tag="mesh", path="<visual><geometry>", owner="link 'arm'"):
        return f"{path}<{tag} filename={ref!r}> of {owner}"


    def on_mesh(ref):  # the template's visual mesh replaced; errors must name that element
        return {"subs": mesh(ref), "element": visual(ref)}


    # ---------------------------------------------------------------- syntax
    SYNTAX = "URDFSyntaxError"
    base = BASE.replace("{why}", "truncated")
    add("syntax", "truncated_in_element", SYNTAX, "not well-formed", "file cut inside an element",
        data=base[: base.index('iyy="0.01"')].encode())
    add("syntax", "truncated_before_root_end", SYNTAX, "not well-formed", "file cut before </robot>",
        data=base[: base.index(END)].encode())
    add("syntax", "mismatched_tag", SYNTAX, "Opening and ending tag mismatch", "a closing tag that does not match",
        subs=[("  </link>\n  <joint", "  </lnk>\n  <joint")])
    add("syntax", "not_xml", SYNTAX, "not well-formed", "plain text, not XML",
        data=b"this is not a robot description\n")
    add("syntax", "empty", SYNTAX, "Document is empty", "an empty file", data=b"")
    add("syntax", "invalid_utf8", SYNTAX, "not well-formed", "bytes that are not UTF-8 in a name",
        data=BASE.replace("{why}", "invalid UTF-8").encode().replace(b'name="arm"', b'name="arm\xff\xfe"', 1))
    add("syntax", "two_roots", SYNTAX, "Extra content at the end of the document", "a second root element after </robot>",
        text=BASE + '<robot name="second"/>\n')
    add("syntax", "duplicate_attribute", SYNTAX, "Attribute value redefined", "an attribute given twice",
        subs=[(MASS, '<mass value="1.0" value="200.0"/>')])
    add("syntax", "undefined_entity", SYNTAX, "Entity 'arm' not defined", "an entity reference without a DTD",
        subs=[('name="arm">', 'name="&arm;">')])
    add("syntax", "unquoted_attribute", SYNTAX, "not well-formed", "an unquoted attribute value",
        subs=[(MASS, "<mass value=1.0/>")])
    add("syntax", "nul_byte", SYNTAX, "not well-formed", "a NUL byte inside the document",
        data=BASE.replace("{why}", "NUL byte").encode().replace(b'name="arm"', b'name="a\x00rm"', 1))
    add("syntax", "dae_truncated", SYNTAX, "broken.dae", "a COLLADA mesh that is cut off",
        **on_mesh("package://corpus_pkg/meshes/broken.dae"))

    # ---------------------------------------------------------------- unsafe XML
    U = "UnsafeURDFError"
    lol = ['<!ENTITY lol "lol">'] + [
        f'<!ENTITY lol{i} "{("&lol" + (str(i - 1) if i > 1 else "") + ";") * 10}">' for i in range(1, 10)
    ]
    add("unsafe_xml", "billion_laughs", U, "<!DOCTYPE> is refused", "billion laughs: nested entities expanding to 10^9 'lol'",
        text=BASE.replace('<robot name="corpus">', "<!DOCTYPE robot [\n  " + "\n  ".join(lol) + '\n]>\n<robot name="&lol9;">'))
    big = "x" * 5000
    add("unsafe_xml", "quadratic_blowup", U, "<!DOCTYPE> is refused", "one 5 kB entity referenced 2000 times (10 MB)",
        text=BASE.replace('<robot name="corpus">', f'<!DOCTYPE robot [<!ENTITY a "{big}">]>\n<robot name="corpus">')
        .replace(END, '<material name="m">' + "&a;" * 2000 + "</material>\n" + END))
    add("unsafe_xml", "external_entity_file", U, "<!DOCTYPE> is refused", "XXE: an external entity reading /etc/passwd",
        text=BASE.replace('<robot name="corpus">', '<!DOCTYPE robot [<!ENTITY xxe SYSTEM "file:///etc/passwd">]>\n<robot name="&xxe;">'))
    add("unsafe_xml", "external_entity_http", U, "<!DOCTYPE> is refused", "XXE: an external entity fetched over HTTP",
        text=BASE.replace('<robot name="corpus">', '<!DOCTYPE robot [<!ENTITY xxe SYSTEM "http://127.0.0.1:9/x">]>\n<robot name="&xxe;">'))
    add("unsafe_xml", "parameter_entity", U, "<!DOCTYPE> is refused", "a parameter entity loading an external DTD",
        text=BASE.replace('<robot name="corpus">', '<!DOCTYPE robot [<!ENTITY % ext SYSTEM "http://127.0.0.1:9/evil.dtd"> %ext;]>\n<robot name="corpus">'))
    add("unsafe_xml", "external_dtd", U, "<!DOCTYPE> is refused", "an external DTD subset (SYSTEM identifier)",
        text=BASE.replace('<robot name="corpus">', '<!DOCTYPE robot SYSTEM "file:///etc/passwd">\n<robot name="corpus">'))
    add("unsafe_xml", "plain_doctype", U, "<!DOCTYPE> is refused", "a harmless-looking DOCTYPE (every DOCTYPE is refused)",
        text=BASE.replace('<robot name="corpus">', "<!DOCTYPE robot>\n<robot name=\"corpus\">"))
    add("unsafe_xml", "dae_external_entity", U, "evil_entity.dae", "a COLLADA mesh with an XXE DOCTYPE",
        **on_mesh("package://corpus_pkg/meshes/evil_entity.dae"))

    # ---------------------------------------------------------------- unsafe paths
    P = "UnsafePathError"
    out = ", outside ["
    add("paths", "package_dotdot", P, out, "package:// with ../ climbing out to /etc/passwd",
        **on_mesh("package://corpus_pkg/" + "../" * 12 + "etc/passwd"))
    add("paths", "relative_dotdot", P, out, "a relative path with ../ climbing out",
        **on_mesh("../" * 12 + "etc/hostname"))
    add("paths", "absolute_outside", P, out, "an absolute path outside the package directories",
        **on_mesh("/etc/passwd"))
    add("paths", "file_uri_outside", P, out, "a file:// URI outside the package directories",
        **on_mesh("file:///etc/passwd"))
    add("paths", "file_uri_relative", P, "refused URL form", "a file:// URI with a relative (cwd-dependent) path",
        **on_mesh("file://corpus_pkg/meshes/box.stl"))
    add("paths", "http_mesh", P, "refused URL form (http:)", "a mesh fetched over http://",
        **on_mesh("http://127.0.0.1:9/box.stl"))
    add("paths", "https_mesh", P, "refused URL form (https:)", "a mesh fetched over https://",
        **on_mesh("https://example.com/box.stl"))
    add("paths", "ftp_mesh", P, "refused URL form (ftp:)", "a mesh fetched over ftp://",
        **on_mesh("ftp://example.com/box.stl"))
    add("paths", "data_uri", P, "refused URL form (data:)", "an inline data: URI",
        **on_mesh("data:model/stl;base64,c29saWQ="))
    add("paths", "dev_zero", P, out, "the device /dev/zero as a mesh (endless read)",
        **on_mesh("/dev/zero"))
    add("paths", "proc_environ", P, out, "/proc/self/environ as a mesh (leaks secrets)",
        **on_mesh("/proc/self/environ"))
    add("paths", "symlink_escape", P, out, "a symlink inside the package pointing outside it",
        **on_mesh("package://corpus_pkg/meshes/escape.stl"))
    add("paths", "symlink_dev_zero", P, out, "a symlink inside the package pointing to /dev/zero",
        **on_mesh("package://corpus_pkg/meshes/zero.stl"))
    add("paths", "fifo", P, "not a regular file", "a FIFO inside the package (a read would block)",
        **on_mesh("package://corpus_pkg/meshes/fifo.stl"))
    add("paths", "directory", P, "not a regular file", "a folder named like a mesh",
        **on_mesh("package://corpus_pkg/meshes/folder.stl"))
    add("paths", "unsupported_format", P, "refused format", "a mesh format outside .stl/.dae/.obj/.ply",
        **on_mesh("package://corpus_pkg/meshes/model.fbx"))
    add("paths", "collision_outside", P, out, "a collision mesh outside the package directories",
        subs=[("    <visual>", '    <collision>\n      <geometry>\n        <mesh filename="/etc/shadow"/>\n      </geometry>\n    </collision>\n    <visual>')],
        element=visual("/etc/shadow", path="<collision><geometry>"))
    add("paths", "texture_outside", P, out, "a material texture outside the package directories",
        subs=[("      </geometry>\n    </visual>", '      </geometry>\n      <material name="skin">\n        <texture filename="/etc/passwd"/>\n      </material>\n    </visual>')],
        element=visual("/etc/passwd", tag="texture", path="<visual><material name='skin'>"))
    add("paths", "gazebo_mesh_outside", P, out, "a mesh in an element URDF parsers ignore (<gazebo>)",
        subs=[(END, '  <gazebo reference="arm">\n    <visual>\n      <geometry>\n        <mesh filename="/etc/passwd"/>\n      </geometry>\n    </visual>\n  </gazebo>\n' + END)],
        element=visual("/etc/passwd", owner="<gazebo reference='arm'>"))
    for name, why in [
        ("absolute", "a COLLADA texture with an absolute path (meshcat would send it to the browser)"),
        ("dotdot", "a COLLADA texture climbing out with ../"),
        ("http", "a COLLADA texture fetched over http://"),
        ("file_uri", "a COLLADA texture as a file:// URI outside"),
        ("percent", "a COLLADA texture climbing out with percent-encoded %2e%2e/"),
        ("ref_1_5", "a COLLADA 1.5 <init_from><ref> texture outside"),
    ]:
        add("paths", f"dae_texture_{name}", P, "refused URL form" if name == "http" else out, why,
            **on_mesh(f"package://corpus_pkg/meshes/evil_texture_{name}.dae"))
    add("paths", "obj_mtllib_escape", P, out, "an OBJ material library climbing out with ../",
        **on_mesh("package://corpus_pkg/meshes/evil_mtllib.obj"))

    # ---------------------------------------------------------------- missing resources
    M = "ResourceNotFoundError"
    add("missing", "mesh_missing", M, "does not exist", "a mesh file that does not exist",
        **on_mesh("package://corpus_pkg/meshes/no_such_mesh.stl"))
    add("missing", "unknown_package", M, "does not exist", "a package no package directory holds",
        **on_mesh("package://no_such_pkg/meshes/box.stl"))
    add("missing", "relative_missing", M, "does not exist", "a relative path found in no package directory",
        **on_mesh("corpus_pkg/meshes/no_such_mesh.stl"))
    add("missing", "package_absolute_rest", M, "does not exist",
        "package:///etc/passwd: resolved like Pinocchio (dir + '/' + rest), i.e. inside, where it does not exist",
        **on_mesh("package:///etc/passwd"))
    add("missing", "dae_texture_missing", M, "no_such_texture.png", "a COLLADA texture that does not exist",
        **on_mesh("package://corpus_pkg/meshes/missing_texture.dae"))

    # ---------------------------------------------------------------- structure
    T = "URDFStructureError"
    add("structure", "root_not_robot", T, "root element is <model>", "an SDF-like <model> root",
        subs=[('<robot name="corpus">', '<model name="corpus">'), ("</robot>", "</model>")])
    add("structure", "robot_without_name", T, "root element", "<robot> without a name",
        subs=[('<robot name="corpus">', "<robot>")])
    add("structure", "no_links", T, "has no <link>", "a robot without links",
        text='<?xml version="1.0"?>\n<!-- {why} -->\n<robot name="corpus"/>\n')
    add("structure", "link_without_name", T, "has no name", "a link without a name",
        subs=[('<link name="base"/>', "<link/>")])
    add("structure", "duplicate_link", T, "also used on line", "two links with the same name",
        subs=[('<link name="base"/>', '<link name="base"/>\n  <link name="base"/>')])
    add("structure", "duplicate_joint", T, "also used on line", "two joints with the same name",
        subs=[('  <link name="arm">', '  <link name="arm2"/>\n  <link name="arm">'),
              (END, '  <joint name="shoulder" type="fixed">\n    <parent link="arm"/>\n    <child link="arm2"/>\n  </joint>\n' + END)])
    add("structure", "undefined_parent", T, "names no link", "a joint whose parent link does not exist",
        subs=[('<parent link="base"/>', '<parent link="ghost"/>')])
    add("structure", "undefined_child", T, "names no link", "a joint whose child link does not exist",
        subs=[('<child link="arm"/>', '<child link="ghost"/>')])
    add("structure", "joint_without_child", T, "has 0 <child> elements", "a joint without a <child>",
        subs=[('    <child link="arm"/>\n', "")])
    add("structure", "two_parent_joints", T, "kinematic loop", "a link that is the child of two joints (a closed chain)",
        subs=[('  <link name="arm">', '  <link name="other"/>\n  <link name="arm">'),
              (END, '  <joint name="closing" type="fixed">\n    <parent link="other"/>\n    <child link="arm"/>\n  </joint>\n'
                    '  <joint name="other_joint" type="fixed">\n    <parent link="base"/>\n    <child link="other"/>\n  </joint>\n' + END)])
    add("structure", "detached_cycle", T, "form a loop", "two links that are each other's parent, apart from the tree",
        subs=[('  <link name="arm">', '  <link name="x"/>\n  <link name="y"/>\n  <link name="arm">'),
              (END, '  <joint name="xy" type="fixed">\n    <parent link="x"/>\n    <child link="y"/>\n  </joint>\n'
                    '  <joint name="yx" type="fixed">\n    <parent link="y"/>\n    <child link="x"/>\n  </joint>\n' + END)])
    add("structure", "self_loop", T, "child of itself", "a joint whose parent is its child",
        subs=[('<parent link="base"/>', '<parent link="arm"/>')])
    add("structure", "two_root_links", T, "has root links", "a link connected to nothing (two trees)",
        subs=[('<link name="base"/>', '<link name="base"/>\n  <link name="floating_part"/>')])
    add("structure", "unknown_joint_type", T, "is unknown", "an unknown joint type 'hinge'",
        subs=[('type="revolute"', 'type="hinge"')])
    add("structure", "revolute_without_limit", T, "has 0 <limit> elements", "a revolute joint without <limit>",
        subs=[("    " + LIMIT + "\n", "")])
    add("structure", "limit_without_effort", T, "'effort' is missing", "a <limit> without effort",
        subs=[(LIMIT, '<limit lower="-1.5" upper="1.5" velocity="2"/>')])
    add("structure", "inertial_without_mass", T, "has 0 <mass> elements", "an <inertial> without <mass>",
        subs=[("      " + MASS + "\n", "")])
    add("structure", "geometry_empty", T, "holds []", "a <geometry> without a shape",
        subs=[('        <mesh filename="package://corpus_pkg/meshes/box.stl"/>\n', "")])
    add("structure", "geometry_unknown_shape", T, "holds ['cone']", "an unknown shape <cone>",
        subs=[('<mesh filename="package://corpus_pkg/meshes/box.stl"/>', '<cone radius="0.1" length="0.2"/>')])
    add("structure", "mimic_unknown_joint", T, "mimics 'ghost'", "a joint mimicking a joint that does not exist",
        subs=[(LIMIT, LIMIT + '\n    <mimic joint="ghost" multiplier="1" offset="0"/>')])

    # ---------------------------------------------------------------- physics / numbers
    INVALID = "InvalidModelError"
    fin = "not a finite number"
    for name, value, why in [
        ("mass_nan", "nan", "mass 'nan' (Pinocchio drops the whole <inertial>)"),
        ("mass_inf", "inf", "mass 'inf'"),
        ("mass_comma", "1,5", "mass '1,5' with a decimal comma (Pinocchio drops the <inertial>)"),
        ("mass_overflow", "1e400", "mass '1e400' overflows to infinity"),
        ("mass_underscore", "1_0", "mass '1_0' (Python's float() reads 10)"),
        ("mass_hex", "0x1p0", "mass '0x1p0', a hexadecimal float"),

        ("mass_word", "heavy", "a mass that is a word"),
    ]:
        add("physics", name, INVALID, fin, why, subs=[(MASS, f'<mass value="{value}"/>')])
    add("physics", "mass_empty", INVALID, "has 0 numbers, not 1", "an empty mass", subs=[(MASS, '<mass value=""/>')])
    add("physics", "mass_negative", INVALID, "is negative", "a negative mass (accepted silently by Pinocchio)",
        subs=[(MASS, '<mass value="-1.0"/>')])
    add("physics", "inertia_nan", INVALID, fin, "an inertia component 'nan'",
        subs=[('ixx="0.01"', 'ixx="nan"')])
    add("physics", "inertia_negative_moment", INVALID, "include a negative one", "a negative principal moment",
        subs=[('ixx="0.01"', 'ixx="-0.01"')])
    add("physics", "inertia_indefinite_offdiagonal", INVALID, "include a negative one", "off-diagonal terms making the inertia indefinite",
        subs=[('ixy="0"', 'ixy="0.05"')])
    add("physics", "inertia_triangle", INVALID, "violate I1 + I2 >= I3", "principal moments 0.01, 0.01, 0.03 break the triangle inequality",
        subs=[('izz="0.001"', 'izz="0.03"')])
    add("physics", "massless_with_inertia", INVALID, "massless link has non-zero inertia", "zero mass with a non-zero inertia",
        subs=[(MASS, '<mass value="0"/>')])
    add("physics", "axis_zero", INVALID, "axis is zero", "a revolute joint with axis 0 0 0 (no motion, singular M)",
        subs=[(AXIS, '<axis xyz="0 0 0"/>')])
    add("physics", "axis_nan", INVALID, fin, "an axis with a 'nan' component",
        subs=[(AXIS, '<axis xyz="0 nan 1"/>')])
    add("physics", "axis_two_numbers", INVALID, "has 2 numbers, not 3", "an axis with two numbers",
        subs=[(AXIS, '<axis xyz="0 1"/>')])
    add("physics", "origin_nan", INVALID, fin, "a joint origin with a 'nan' position",
        subs=[(AXIS, '<origin xyz="0 nan 0" rpy="0 0 0"/>\n    ' + AXIS)])
    add("physics", "limit_lower_above_upper", INVALID, "lower=1.5 > upper=-1.5", "lower limit above the upper one",
        subs=[(LIMIT, '<limit lower="1.5" upper="-1.5" effort="10" velocity="2"/>')])
    add("physics", "limit_negative_velocity", INVALID, "is negative", "a negative velocity limit",
        subs=[(LIMIT, '<limit lower="-1.5" upper="1.5" effort="10" velocity="-2"/>')])
    add("physics", "limit_negative_effort", INVALID, "is negative", "a negative effort limit",
        subs=[(LIMIT, '<limit lower="-1.5" upper="1.5" effort="-10" velocity="2"/>')])
    add("physics", "limit_inf", INVALID, fin, "an infinite upper limit",
        subs=[(LIMIT, '<limit lower="-1.5" upper="inf" effort="10" velocity="2"/>')])
    add("physics", "damping_negative", INVALID, "damping=-0.1 is negative", "a negative joint damping (energy source)",
        subs=[(LIMIT, LIMIT + '\n    <dynamics damping="-0.1" friction="0"/>')])
    add("physics", "box_size_zero", INVALID, "is not positive", "a box with a zero side",
        subs=[('<mesh filename="package://corpus_pkg/meshes/box.stl"/>', '<box size="0.1 0 0.1"/>')])
    add("physics", "sphere_radius_negative", INVALID, "is not positive", "a sphere with a negative radius",
        subs=[('<mesh filename="package://corpus_pkg/meshes/box.stl"/>', '<sphere radius="-0.1"/>')])
    add("physics", "mesh_scale_zero", INVALID, "scale has a zero component", "a mesh scaled by zero",
        subs=[(MESH, MESH + ' scale="1 0 1"')])
    add("physics", "massless_leaf_joint", INVALID, "['wrist'] move without inertia",
        "a revolute joint carrying only a massless link: M(q) singular, forward dynamics undefined",
        subs=[(END, '  <link name="hand"/>\n  <joint name="wrist" type="revolute">\n    <parent link="arm"/>\n'
                    '    <child link="hand"/>\n    <origin xyz="0 0 0.2"/>\n    <axis xyz="0 1 0"/>\n'
                    '    <limit lower="-1" upper="1" effort="1" velocity="1"/>\n  </joint>\n' + END)])
    add("physics", "point_mass_on_axis", INVALID, "['shoulder'] move without inertia",
        "a point mass (allowed) lying on the joint axis: no inertia about it, M(q) singular",
        subs=[('<origin xyz="0 0 0.1" rpy="0 0 0"/>', '<origin xyz="0 0.1 0" rpy="0 0 0"/>'),
              (INERTIA, '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>')])

    add("physics", "origin_huge_inertial", INVALID, "centre of mass lies 1e+200 m from the frame of joint 'shoulder'",
        "an <inertial> origin at 1e200 m: the spatial inertia (m |c|^2) overflows",
        subs=[('<origin xyz="0 0 0.1" rpy="0 0 0"/>', '<origin xyz="1e200 0 0.1" rpy="0 0 0"/>')])
    add("physics", "origin_huge_joint", INVALID, "M(q) is not finite at the neutral configuration",
        "a joint origin at 1e200 m: the joint space inertia matrix overflows",
        subs=[(END, '  <link name="hand">\n    <inertial>\n      <mass value="0.5"/>\n'
                    '      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/>\n    </inertial>\n  </link>\n'
                    '  <joint name="wrist" type="revolute">\n    <parent link="arm"/>\n    <child link="hand"/>\n'
                    '    <origin xyz="1e200 0 0"/>\n    <axis xyz="0 1 0"/>\n'
                    '    <limit lower="-1" upper="1" effort="1" velocity="1"/>\n  </joint>\n' + END)])
    add("physics", "origin_huge_fixed_chain", INVALID, "placement of frame 'tool_joint_2' in the model is not finite",
        "two fixed joints 1.5e308 m long each: the tool frame's position overflows to infinity",
        subs=[(END, '  <link name="tool_1"/>\n  <link name="tool_2"/>\n'
                    '  <joint name="tool_joint_1" type="fixed">\n    <parent link="arm"/>\n    <child link="tool_1"/>\n'
                    '    <origin xyz="1.5e308 0 0"/>\n  </joint>\n'
                    '  <joint name="tool_joint_2" type="fixed">\n    <parent link="tool_1"/>\n    <child link="tool_2"/>\n'
                    '    <origin xyz="1.5e308 0 0"/>\n  </joint>\n' + END)])

    # ---------------------------------------------------------------- valid
    V = "ok"
    add("valid", "minimal", V, "", "the corpus template: one revolute joint, an STL mesh")
    add("valid", "single_link", V, "", "a robot with one link and no joint",
        text='<?xml version="1.0"?>\n<!-- {why} -->\n<robot name="corpus">\n  <link name="base"/>\n</robot>\n')
    add("valid", "continuous_and_prismatic", V, "", "a continuous joint and a prismatic joint",
        subs=[('type="revolute"', 'type="continuous"'), (LIMIT, ""),
              (END, '  <link name="slider">\n    <inertial>\n      <mass value="0.5"/>\n'
                    '      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/>\n    </inertial>\n  </link>\n'
                    '  <joint name="slide" type="prismatic">\n    <parent link="arm"/>\n    <child link="slider"/>\n'
                    '    <axis xyz="0 0 1"/>\n    <limit lower="0" upper="0.3" effort="50" velocity="0.5"/>\n  </joint>\n' + END)])
    add("valid", "fixed_massless_tool", V, "", "a massless tool frame on a fixed joint (adds nothing to M)",
        subs=[(END, '  <link name="tool"/>\n  <joint name="tool_joint" type="fixed">\n    <parent link="arm"/>\n'
                    '    <child link="tool"/>\n    <origin xyz="0 0 0.2"/>\n    <axis xyz="0 0 0"/>\n  </joint>\n' + END)])
    add("valid", "point_mass_tool", V, "", "a point mass (zero inertia) on a fixed tool link",
        subs=[(END, '  <link name="tool">\n    <inertial>\n      <mass value="0.2"/>\n'
                    '      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>\n    </inertial>\n  </link>\n'
                    '  <joint name="tool_joint" type="fixed">\n    <parent link="arm"/>\n    <child link="tool"/>\n'
                    '    <origin xyz="0 0 0.2" rpy="0.3 -0.2 1.0"/>\n  </joint>\n' + END)])
    add("valid", "gimbal_massless_middle", V, "", "two orthogonal joints through a massless middle link (M still positive definite)",
        subs=[('<child link="arm"/>', '<child link="middle"/>'), ('<link name="base"/>', '<link name="base"/>\n  <link name="middle"/>'),
              (END, '  <joint name="elbow" type="revolute">\n    <parent link="middle"/>\n    <child link="arm"/>\n'
                    '    <axis xyz="1 0 0"/>\n    <limit lower="-1" upper="1" effort="5" velocity="1"/>\n  </joint>\n' + END)])
    add("valid", "flat_plate_boundary", V, "", "a flat plate, I3 = I1 + I2 up to 7-digit rounding (within the 1e-6 tolerance)",
        subs=[(INERTIA, '<inertia ixx="0.0123457" ixy="0" ixz="0" iyy="0.0234568" iyz="0" izz="0.0358025"/>')])
    add("valid", "symlink_inside", V, "", "a mesh symlink that stays inside the package",
        subs=mesh("package://corpus_pkg/meshes/inside_link.stl"))
    add("valid", "relative_mesh", V, "", "a relative mesh path, found in the package directories like Pinocchio does",
        subs=mesh("corpus_pkg/meshes/box.stl"))
    add("valid", "textured_dae", V, "", "a COLLADA mesh with a texture next to it (image-id references are not paths)",
        subs=mesh("package://corpus_pkg/meshes/textured.dae"))
    add("valid", "obj_with_material", V, "", "an OBJ mesh with its material library",
        subs=mesh("package://corpus_pkg/meshes/tetra.obj"))
    add("valid", "mimic_and_continuous_limit", V, "",
        "a revolute joint mimicking another and a continuous joint with velocity and effort limits (limits must match the model)",
        subs=[(END, '  <link name="finger">\n    <inertial>\n      <origin xyz="0 0 0.02"/>\n      <mass value="0.1"/>\n'
                    '      <inertia ixx="0.0001" ixy="0" ixz="0" iyy="0.0001" iyz="0" izz="0.0001"/>\n    </inertial>\n  </link>\n'
                    '  <joint name="finger_joint" type="revolute">\n    <parent link="arm"/>\n    <child link="finger"/>\n'
                    '    <origin xyz="0 0 0.2"/>\n    <axis xyz="1 0 0"/>\n    <limit lower="-0.5" upper="0.25" effort="3" velocity="1.5"/>\n'
                    '    <mimic joint="shoulder" multiplier="0.5" offset="0"/>\n  </joint>\n'
                    '  <link name="wheel">\n    <inertial>\n      <mass value="0.2"/>\n'
                    '      <inertia ixx="0.0002" ixy="0" ixz="0" iyy="0.0002" iyz="0" izz="0.0003"/>\n    </inertial>\n  </link>\n'
                    '  <joint name="spin" type="continuous">\n    <parent link="finger"/>\n    <child link="wheel"/>\n'
                    '    <origin xyz="0 0 0.05"/>\n    <axis xyz="0 0 1"/>\n    <limit effort="7" velocity="4"/>\n  </joint>\n' + END)])
    add("valid", "floating_and_planar", V, "",
        "a floating and a planar joint, whose <limit> URDF leaves undefined (Pinocchio ignores it: no limits)",
        subs=[(END, '  <link name="puck">\n    <inertial>\n      <mass value="0.3"/>\n'
                    '      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/>\n    </inertial>\n  </link>\n'
                    '  <link name="drone">\n    <inertial>\n      <mass value="0.2"/>\n'
                    '      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/>\n    </inertial>\n  </link>\n'
                    '  <joint name="slide_plane" type="planar">\n    <parent link="arm"/>\n    <child link="puck"/>\n'
                    '    <axis xyz="0 0 1"/>\n    <limit lower="-1" upper="1" effort="5" velocity="1"/>\n  </joint>\n'
                    '  <joint name="free" type="floating">\n    <parent link="puck"/>\n    <child link="drone"/>\n'
                    '    <limit lower="-1" upper="1" effort="5" velocity="1"/>\n  </joint>\n' + END)])
    add("valid", "rotated_inertial", V, "", "an inertial with a rotated origin and off-diagonal terms (model must match the file)",
        subs=[('<origin xyz="0 0 0.1" rpy="0 0 0"/>', '<origin xyz="0.01 -0.02 0.1" rpy="0.4 -0.3 1.2"/>'),
              (INERTIA, '<inertia ixx="0.01" ixy="0.001" ixz="-0.0005" iyy="0.012" iyz="0.0002" izz="0.004"/>')])

    # ---------------------------------------------------------------- sizes (issue 16)
    # Just past each limit, so the files stay small; the huge versions (10,000 links,
    # 100,000 levels, 10,000 children of one link) are generated by tests/robot/test_limits.py.
    def lim_joint(i, parent, jtype="fixed"):
        extra = '<axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/>' if jtype != "fixed" else ""
        return f'<link name="l{i}"/><joint name="j{i}" type="{jtype}"><parent link="{parent}"/><child link="l{i}"/>{extra}</joint>\n'

    def lim_robot(why, body):
        return f'<?xml version="1.0"?>\n<!-- {why} -->\n<robot name="limits">\n<link name="l0"/>\n{body}</robot>\n'

    why = "1,001 joints (fixed, all children of one link): more than MAX_JOINTS = 1,000"
    add("limits", "joints_1001_star", U, "has 1,001 joints, more than the limit of 1,000", why,
        text=lim_robot(why, "".join(lim_joint(i, "l0") for i in range(1, 1002))))
    why = "a chain of 501 fixed joints: deeper than MAX_TREE_DEPTH = 500 (Pinocchio's parser recurses per level)"
    add("limits", "depth_501_chain", U, "has a chain of 501 joints, deeper than the limit of 500", why,
        text=lim_robot(why, "".join(lim_joint(i, f"l{i - 1}") for i in range(1, 502))))
    why = "101 revolute joints: more than MAX_DOF = 100 (Pinocchio's Data grows faster than dof^2)"
    add("limits", "dof_101_chain", U, "has 101 degrees of freedom, more than the limit of 100", why,
        text=lim_robot(why, "".join(lim_joint(i, f"l{i - 1}", "revolute") for i in range(1, 102))))
    why = "101 nested elements inside <gazebo>: deeper than MAX_XML_DEPTH = 100"
    add("limits", "xml_nesting_101", U, "the XML nesting exceeds the limit of 100", why,
        subs=[(END, "<gazebo>" + "<g>" * 100 + "</g>" * 100 + "</gazebo>\n" + END)])
    why = "200 nested xacro-style macro calls (a macro expanding into the next): deeper than MAX_XML_DEPTH"
    add("limits", "xacro_macros_nested_200", U, "the XML nesting exceeds the limit of 100", why,
        text=BASE.replace('<robot name="corpus">', '<robot name="corpus" xmlns:xacro="http://www.ros.org/wiki/xacro">')
        .replace(END, "".join(f'<xacro:macro name="m{i}">' for i in range(200)) + "</xacro:macro>" * 200 + "\n" + END))

    # ---------------------------------------------------------------- dynamics defined (issue 16)
    I = "InvalidModelError"
    add("physics", "subnormal_mass_and_inertia", I, "ABA (joint accelerations) is not finite",
        "mass and inertia 5e-324 (subnormal): finite, positive, M(q) 'positive definite', but pin.aba returns NaN",
        subs=[(MASS, '<mass value="5e-324"/>'), (INERTIA, '<inertia ixx="5e-324" ixy="0" ixz="0" iyy="5e-324" iyz="0" izz="5e-324"/>')])
    add("physics", "long_numeric_attribute", I, "characters>...",
        "a 20 kB mass attribute that is not a number: the message quotes it elided, not whole",
        subs=[(MASS, '<mass value="' + "1" * 20000 + 'x"/>')])

    # ---------------------------------------------------------------- mimic graphs (issue 16)
    S = "URDFStructureError"
    def second(mimic_first, mimic_second):
        return [(LIMIT, LIMIT + mimic_first),
                (END, '  <link name="hand">\n    <inertial>\n      <mass value="0.1"/>\n'
                      '      <inertia ixx="0.0001" ixy="0" ixz="0" iyy="0.0001" iyz="0" izz="0.0001"/>\n    </inertial>\n  </link>\n'
                      '  <joint name="wrist" type="revolute">\n    <parent link="arm"/>\n    <child link="hand"/>\n'
                      f'    <origin xyz="0 0 0.2"/>\n    <axis xyz="1 0 0"/>\n    {LIMIT}{mimic_second}\n  </joint>\n' + END)]
    add("structure", "mimic_cycle", S, "is part of the mimic cycle 'shoulder' -> 'wrist' -> 'shoulder'",
        "two joints mimicking each other (loaded as two independent joints before)",
        subs=second('<mimic joint="wrist"/>', '<mimic joint="shoulder"/>'))
    add("structure", "mimic_chain", S, "mimics 'wrist', which mimics another joint",
        "a joint mimicking a joint that mimics a third",
        subs=second('<mimic joint="wrist"/>', '<mimic joint="elbow"/>') + [
            (END, '  <link name="tip"/>\n  <joint name="elbow" type="revolute">\n    <parent link="hand"/>\n    <child link="tip"/>\n'
                  f'    <axis xyz="1 0 0"/>\n    {LIMIT}\n  </joint>\n' + END)])
    add("structure", "mimic_fixed_joint", S, "mimics the fixed joint 'weld'",
        "a joint mimicking a fixed joint (which has no coordinate to follow)",
        subs=[(LIMIT, LIMIT + '<mimic joint="weld"/>'),
              (END, '  <link name="tool"/>\n  <joint name="weld" type="fixed">\n    <parent link="arm"/>\n    <child link="tool"/>\n  </joint>\n' + END)])

    return entries


if __name__ == "__main__":
    write_package()
    manifest = write_corpus()
    (OUT / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n")
    print(len(manifest), Counter(e["expect"] for e in manifest))
