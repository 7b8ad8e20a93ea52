"""The package's own imports obey the layer rules of ARCHITECTURE.md (read with ast).

Rules: no import cycle between modules; no private name (``_x``, or a name from a
private module) imported from another module; no import against the layer order
L0 (plain helpers) < robot < dynamics, nlp, sweeps < trajopt, ikpath < viz,
reproduction < cli. A module may import from its own package and from lower
layers only; two packages of one layer do not import each other.
"""

from __future__ import annotations

import ast
import functools
import itertools
import os
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "youbot_opt"

#: Layer of each top-level part of the package; the root ``__init__``/``__main__`` is on top.
LAYERS: dict[str, int] = {
    "exceptions": 0,
    "_typing": 0,
    "_checks": 0,
    "_files": 0,
    "_cores": 0,
    "_version": 0,
    "robot": 1,
    "dynamics": 2,
    "nlp": 2,
    "sweeps": 2,
    "collision": 2,
    "trajopt": 3,
    "ikpath": 3,
    "viz": 4,
    "reproduction": 4,
    "cli": 5,
    "__init__": 6,
    "__main__": 6,
}


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__" and len(parts) > 1 and parts[-2] != "youbot_opt":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


MODULES = _modules()


def _top(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _resolve(module: str, name: str | None) -> str:
    """The module that ``from module import name`` reads: the submodule if it is one."""
    if name is not None and f"{module}.{name}" in MODULES:
        return f"{module}.{name}"
    return module


def _imports(module: str) -> list[tuple[str, str | None, int]]:
    """``(imported module, imported name or None, line)`` for every import of ``module``."""
    tree = ast.parse(MODULES[module].read_text(), filename=str(MODULES[module]))
    out: list[tuple[str, str | None, int]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("youbot_opt"):
                    out.append((alias.name, None, node.lineno))
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                raise AssertionError(f"{module}:{node.lineno}: relative import; use absolute")
            if node.module and node.module.startswith("youbot_opt"):
                for alias in node.names:
                    out.append((node.module, alias.name, node.lineno))
    return out


GRAPH = {m: _imports(m) for m in MODULES}


def _edges() -> dict[str, set[str]]:
    edges: dict[str, set[str]] = {m: set() for m in MODULES}
    for m, imports in GRAPH.items():
        for target, name, _ in imports:
            dep = _resolve(target, name)
            if dep != m and dep in MODULES:
                edges[m].add(dep)
    return edges


def _package_of(module: str) -> str:
    """The package a module belongs to (its own name for a package ``__init__``)."""
    if MODULES[module].name == "__init__.py":
        return module
    return module.rsplit(".", 1)[0]


def test_every_module_has_a_layer():
    """Each top-level module or package of youbot_opt is placed in a layer."""
    missing = sorted({_top(m) for m in MODULES} - set(LAYERS))
    assert not missing, f"not placed in a layer of ARCHITECTURE.md: {missing}"


def test_no_import_cycles():
    """The module import graph is acyclic (imports inside functions count too)."""
    edges = _edges()
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def visit(node: str, stack: list[str]) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(edges[node]):
            # a package __init__ that re-exports its own submodules is not a cycle
            if _package_of(node) == node and nxt.startswith(node + "."):
                continue
            if state.get(nxt) == 1:
                cycles.append(stack[stack.index(nxt) :] + [nxt])
            elif nxt not in state:
                visit(nxt, stack)
        stack.pop()
        state[node] = 2

    for m in sorted(MODULES):
        if m not in state:
            visit(m, [])
    assert not cycles, "import cycles:\n" + "\n".join(" -> ".join(c) for c in cycles)


def test_no_private_names_across_modules():
    """No module imports a private name, or from a private module, of another module."""
    bad = []
    for m, imports in GRAPH.items():
        for target, name, line in imports:
            dep = _resolve(target, name)
            if dep == m:
                continue
            private_module = any(
                p.startswith("_") and p not in {"__init__"} for p in dep.split(".")[1:]
            )
            private_name = name is not None and name.startswith("_") and name != "__version__"
            if (
                private_module
                and not dep.endswith(("_typing", "_checks", "_files", "_cores", "_version"))
            ) or (private_name and dep not in {"youbot_opt._version"}):
                bad.append(f"{m}:{line}: from {target} import {name}")
    assert not bad, "private names imported across modules:\n" + "\n".join(bad)


def test_no_upward_imports():
    """A module imports only from its own layer's package or from lower layers."""
    bad = []
    for m, imports in GRAPH.items():
        mine = _top(m)
        for target, name, line in imports:
            dep = _resolve(target, name)
            theirs = _top(dep)
            if theirs == mine or LAYERS[theirs] == LAYERS[mine] == 0:
                continue  # the plain helpers of layer 0 may import each other
            if LAYERS[theirs] >= LAYERS[mine]:
                bad.append(f"{m}:{line}: imports {dep} (layer {LAYERS[theirs]} >= {LAYERS[mine]})")
    assert not bad, "imports against the layer order:\n" + "\n".join(bad)


def test_no_module_imports_a_cli_module():
    """Only the command line itself (and ``python -m youbot_opt``) imports ``youbot_opt.cli``.

    The library never reaches up into parsing and printing: a helper that two
    commands and the library share belongs below the CLI (ARCHITECTURE.md, L5).
    """
    bad = [
        f"{m}:{line}: imports {_resolve(target, name)}"
        for m, imports in GRAPH.items()
        if _top(m) not in {"cli", "__main__"}
        for target, name, line in imports
        if _top(_resolve(target, name)) == "cli"
    ]
    assert not bad, "modules outside the CLI import it:\n" + "\n".join(bad)


def test_layer_0_imports_only_layer_0():
    """The plain helpers (exceptions, _typing, _checks, _files, _cores, _version) import only
    each other."""
    bad = [
        f"{m}:{line}: imports {_resolve(target, name)}"
        for m, imports in GRAPH.items()
        if LAYERS[_top(m)] == 0
        for target, name, line in imports
        if LAYERS[_top(_resolve(target, name))] != 0
    ]
    assert not bad, "layer-0 modules importing the rest of youbot_opt:\n" + "\n".join(bad)


#: Longest module docstring, in lines (ARCHITECTURE.md rule 8: "about ten lines"; the
#: rationale goes to docs/design.md, the measurements to benchmarks/).
MAX_DOCSTRING_LINES = 12


def _docstring_lines(path: Path) -> int:
    doc = ast.get_docstring(ast.parse(path.read_text()), clean=False)
    return len(doc.splitlines()) if doc else 0


def test_module_docstrings_are_about_ten_lines():
    """No module docstring beyond MAX_DOCSTRING_LINES lines."""
    long = {
        f"{module} ({lines} lines)"
        for module, path in MODULES.items()
        if (lines := _docstring_lines(path)) > MAX_DOCSTRING_LINES
    }
    assert not long, (
        f"module docstrings over {MAX_DOCSTRING_LINES} lines (move the rationale to "
        "docs/design.md, 'Module notes', and the API to the class/function docstrings):\n"
        + "\n".join(sorted(long))
    )


def test_one_ik_problem_type():
    """ikpath/ defines exactly one problem class (CyclicIKProblem): no planar/3-D twins."""
    problems = sorted(
        f"{module}.{node.name}"
        for module, path in MODULES.items()
        if module.startswith("youbot_opt.ikpath")
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.ClassDef) and node.name.endswith("Problem")
    )
    assert problems == ["youbot_opt.ikpath.problem.CyclicIKProblem"], problems


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ("from youbot_opt.cli import main\n", "layer"),
        ("from youbot_opt.trajopt.solver import _private\n", "private"),
        ('"""A module docstring of thirteen lines.\n' + "\n" * 12 + '"""\n', "docstring"),
        ("def f():\n    from youbot_opt.cli.solve import run\n", "cli"),
    ],
)
def test_the_rules_catch_violations(tmp_path, source, expected):
    """The checks above fail on a planted violation (an upward import, a private, a long doc)."""
    planted = "youbot_opt.robot._planted_check"
    MODULES[planted] = tmp_path / "planted.py"
    MODULES[planted].write_text(source)
    GRAPH[planted] = _imports(planted)
    try:
        check = {
            "layer": test_no_upward_imports,
            "private": test_no_private_names_across_modules,
            "docstring": test_module_docstrings_are_about_ten_lines,
            "cli": test_no_module_imports_a_cli_module,
        }[expected]
        with pytest.raises(AssertionError):
            check()
    finally:
        del MODULES[planted], GRAPH[planted]


def _twins(a: str, b: str) -> bool:
    """Whether module names ``a`` and ``b`` are one stem and its derivative (certificate, certify).

    Leading words they share are dropped (``sweep`` / ``sweep_store`` is a compound,
    not a twin); the first remaining words are twins when they share a prefix of at
    least four letters and three quarters of the shorter (refine / refinement), a
    plural or a number aside (robot_args / robots, study1 / study_guess).
    """
    wa, wb = a.strip("_").split("_"), b.strip("_").split("_")
    while wa and wb and wa[0] == wb[0]:
        wa, wb = wa[1:], wb[1:]
    if not wa or not wb:
        return False
    x, y = wa[0], wb[0]
    n = len(os.path.commonprefix([x, y]))
    if {x[n:], y[n:]} <= {"", "s"} or x[n:].isdigit() or y[n:].isdigit():
        return False  # a plural or a number (robots, study1) is not a derivative
    return n >= 4 and n >= 0.75 * min(len(x), len(y))


def test_no_twin_modules():
    """No concept split into twin modules (ARCHITECTURE.md rule 1: move ownership instead).

    No two modules of one package are one stem and its derivative (``certificate`` +
    ``certify``, ``refine`` + ``refinement``), and no module name appears both in a
    package and in its subpackage (``trajopt/radau.py`` + ``trajopt/transcription/radau.py``).
    """
    stems: dict[Path, set[str]] = {}
    for path in MODULES.values():
        if path.name != "__init__.py":
            stems.setdefault(path.parent, set()).add(path.stem)
    bad = [
        f"{folder.relative_to(PACKAGE)}: {a}.py and {b}.py"
        for folder, names in stems.items()
        for a, b in itertools.combinations(sorted(names), 2)
        if _twins(a, b)
    ]
    bad += [
        f"{sub.relative_to(PACKAGE)}/{name}.py and {folder.relative_to(PACKAGE)}/{name}.py"
        for folder, names in stems.items()
        for sub, inner in stems.items()
        if sub.parent == folder
        for name in sorted(names & inner)
    ]
    assert not bad, "twin modules (one concept in two modules):\n" + "\n".join(bad)


@pytest.mark.parametrize(
    ("a", "b", "twins"),
    [
        ("certificate", "certify", True),
        ("refine", "refinement", True),
        ("sweep", "sweep_store", False),
        ("spatial_io", "spatial_ipopt", False),
        ("guess", "spline_guess", False),
        ("robot_args", "robots", False),
        ("study1", "study_guess", False),
    ],
)
def test_twin_rule_tells_stems_from_compounds(a: str, b: str, twins: bool) -> None:
    """The twin rule flags a stem and its derivative, never a compound name."""
    assert _twins(a, b) is twins


#: The packages held to "no ``Any`` in a public signature" (ARCHITECTURE.md rule 9); the
#: others join as they are cleaned.
NO_ANY_PACKAGES: tuple[str, ...] = (
    "cli",
    "exceptions",
    "robot",
    "dynamics",
    "nlp",
    "ikpath",
    "collision",
    "viz",
    "sweeps",
    "reproduction",
    "trajopt",
)

_PUBLIC_DUNDERS = ("__init__", "__call__")


def _mentions_any(annotation: ast.expr | None, aliases: frozenset[str] = frozenset()) -> bool:
    """Whether an annotation names ``Any`` (bare, ``typing.Any``) or one of ``aliases``
    (``Alias`` or ``mod.Alias`` as the module spells it), also inside a string."""
    if annotation is None:
        return False
    names = {"Any", *aliases}
    for node in ast.walk(annotation):
        if isinstance(node, ast.Name) and node.id in names:
            return True
        if isinstance(node, ast.Attribute) and (node.attr == "Any" or ast.unparse(node) in names):
            return True
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            try:
                if _mentions_any(ast.parse(node.value, mode="eval").body, aliases):
                    return True
            except SyntaxError:
                continue
    return False


def _signature_any(
    func: ast.FunctionDef | ast.AsyncFunctionDef, aliases: frozenset[str] = frozenset()
) -> list[str]:
    args = func.args
    every = [*args.posonlyargs, *args.args, *args.kwonlyargs, args.vararg, args.kwarg]
    found = [a.arg for a in every if a is not None and _mentions_any(a.annotation, aliases)]
    return found + (["return"] if _mentions_any(func.returns, aliases) else [])


def _public(name: str) -> bool:
    return not name.startswith("_") or name in _PUBLIC_DUNDERS


def _any_in_public_signatures(
    module: str, path: Path, aliases: frozenset[str] = frozenset()
) -> list[str]:
    """``module.name(param)`` for each public function, method or field annotated with Any.

    ``aliases``: the module's names of types holding Any (:func:`_any_names`), seen as Any.
    """
    if any(part.startswith("_") and part != "__init__" for part in module.split(".")[1:]):
        return []  # a private module has no public signature
    found = []
    for node in _parsed(path, path.read_text()).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and _public(node.name):
            found += [f"{module}.{node.name}({p})" for p in _signature_any(node, aliases)]
        elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
            for item in node.body:
                if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef)) and _public(item.name):
                    where = f"{module}.{node.name}.{item.name}"
                    found += [f"{where}({p})" for p in _signature_any(item, aliases)]
                elif isinstance(item, ast.AnnAssign) and _mentions_any(item.annotation, aliases):
                    found.append(f"{module}.{node.name}.{ast.unparse(item.target)} (field)")
    return found


def _module_level(tree: ast.Module) -> list[ast.stmt]:
    """The module's statements, those under a top-level ``if`` (``TYPE_CHECKING``) included."""
    out: list[ast.stmt] = []
    todo = list(tree.body)
    while todo:
        node = todo.pop(0)
        out.append(node)
        if isinstance(node, ast.If):
            todo += [*node.body, *node.orelse]
    return out


def _alias_values(tree: ast.Module) -> dict[str, ast.expr]:
    """Module-level type aliases by name: ``Name: TypeAlias = value``, and ``Name = value``
    where the value can be a type (a name, ``a.b``, ``x[...]``, ``x | y``; not a literal)."""
    out: dict[str, ast.expr] = {}
    for node in _module_level(tree):
        if isinstance(node, ast.Assign) and isinstance(
            node.value, (ast.Name, ast.Attribute, ast.Subscript, ast.BinOp)
        ):
            out |= {t.id: node.value for t in node.targets if isinstance(t, ast.Name)}
        elif (
            isinstance(node, ast.AnnAssign)
            and node.value is not None
            and isinstance(node.target, ast.Name)
            and "TypeAlias" in ast.unparse(node.annotation)
        ):
            out[node.target.id] = node.value
    return out


@functools.cache
def _parsed(path: Path, text: str) -> ast.Module:
    """The module's tree, parsed once per text (the alias rule reads every module often)."""
    return ast.parse(text)


def _imported_any_names(tree: ast.Module, names: dict[str, set[str]]) -> set[str]:
    """The names (``Alias``, ``mod.Alias``) by which a module sees other modules' Any aliases."""

    def plain(module: str) -> set[str]:
        return {name for name in names.get(module, ()) if "." not in name}

    found: set[str] = set()
    for node in _module_level(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            for a in node.names:
                local = a.asname or a.name
                if f"{node.module}.{a.name}" in MODULES:  # a module: ``local.Alias``
                    found |= {f"{local}.{name}" for name in plain(f"{node.module}.{a.name}")}
                elif a.name in plain(node.module):
                    found.add(local)
        elif isinstance(node, ast.Import):
            for a in node.names:
                found |= {f"{a.asname or a.name}.{name}" for name in plain(a.name)}
    return found


def _any_names() -> dict[str, frozenset[str]]:
    """Per module, the names that stand for a type holding Any.

    A name is one if the module binds it to a value naming Any or such a name
    (``JSON = dict[str, Any]``, ``Rows = list[JSON]``), or imports it from a module
    where it is one (re-exports included; ``mod.JSON`` for an imported module), found
    to a fixed point over the package.
    """
    trees = {module: _parsed(path, path.read_text()) for module, path in MODULES.items()}
    names: dict[str, set[str]] = {module: set() for module in MODULES}
    changed = True
    while changed:
        changed = False
        for module, tree in trees.items():
            known = frozenset(names[module])
            found = {
                name for name, value in _alias_values(tree).items() if _mentions_any(value, known)
            }
            found |= _imported_any_names(tree, names)
            if found - names[module]:
                names[module] |= found
                changed = True
    return {module: frozenset(found) for module, found in names.items()}


def test_no_any_in_a_public_signature():
    """No public signature of the covered packages names Any, directly or through an alias."""
    aliases = _any_names()
    found = [
        hit
        for module, path in MODULES.items()
        if _top(module) in NO_ANY_PACKAGES
        for hit in _any_in_public_signatures(module, path, aliases[module])
    ]
    assert not found, "\n".join(found)


@pytest.mark.parametrize(
    ("source", "caught"),
    [
        ("from typing import Any\ndef f(x: Any) -> None: ...\n", True),
        ("import typing\ndef f(*, x: int = 0) -> dict[str, typing.Any]: ...\n", True),
        ("def f(**kw: 'Any') -> None: ...\n", True),
        ("class C:\n    def m(self, x: list[Any]) -> None: ...\n", True),
        ("class C:\n    def __init__(self, x: Any) -> None: ...\n", True),
        ("@dataclass\nclass C:\n    field: Any | None = None\n", True),
        ("from typing import Any\nExpr = Any\ndef f(x: Expr) -> Expr: ...\n", True),
        (
            "from typing import Any\nJS = dict[str, Any]\nclass C:\n    def m(self) -> JS: ...\n",
            True,
        ),
        (
            "import typing as t\nF: t.TypeAlias = 't.Callable[..., t.Any]'\n"
            "def f(g: 'F') -> int: ...\n",
            True,
        ),
        (
            "from typing import Any\nA = list[Any]\nB = tuple[A, int]\n"
            "def f(x: B | None) -> int: ...\n",
            True,
        ),
        (
            "if TYPE_CHECKING:\n    Row = dict[str, Any]\n@dataclass\nclass C:\n    r: list[Row]\n",
            True,
        ),
        ("def _f(x: Any) -> Any: ...\nclass _C:\n    x: Any\n", False),
        ("def f(x: object) -> dict[str, object]: ...\n", False),
        ("from typing import Any\nJSON = dict[str, Any]\ndef _f(x: JSON) -> JSON: ...\n", False),
        ("OPTIONS: dict[str, Any] = {}\ndef f(x: int = 0) -> dict[str, bool]: ...\n", False),
        ("from typing import Any\nNAMES = ['Any']\ndef f(x: 'NAMES') -> None: ...\n", False),
        (
            "from typing import Any\ndef g() -> None:\n    E = Any\ndef f(x: 'E') -> None: ...\n",
            False,
        ),
    ],
)
def test_the_any_rule_catches_a_planted_violation(tmp_path, source, caught):
    """A planted public Any in a covered package fails the rule, bare or through an alias;
    private names, object and a variable (not an alias) annotated with Any pass."""
    planted = f"youbot_opt.{NO_ANY_PACKAGES[0]}.planted_check"
    MODULES[planted] = tmp_path / "planted_check.py"
    MODULES[planted].write_text(source)
    try:
        hits = _any_in_public_signatures(planted, MODULES[planted], _any_names()[planted])
        assert bool(hits) is caught, hits
        if caught:
            with pytest.raises(AssertionError):
                test_no_any_in_a_public_signature()
    finally:
        del MODULES[planted]


def test_the_any_rule_follows_an_imported_alias(tmp_path):
    """An alias holding Any, imported (through a re-export) into a covered package, is caught."""
    sources = {
        "youbot_opt.robot.planted_types": "from typing import Any\nJSON = dict[str, Any]\n",
        "youbot_opt.robot.planted_init": "from youbot_opt.robot.planted_types import JSON\n",
        f"youbot_opt.{NO_ANY_PACKAGES[0]}.planted_use": (
            "from youbot_opt.robot.planted_init import JSON as Doc\ndef f(d: Doc) -> None: ...\n"
        ),
        f"youbot_opt.{NO_ANY_PACKAGES[0]}.planted_dotted": (
            "from youbot_opt.robot import planted_types as pt\n"
            "import youbot_opt.robot.planted_init\n"
            "class C:\n    def m(self) -> pt.JSON: ...\n"
            "def g() -> youbot_opt.robot.planted_init.JSON: ...\n"
        ),
    }
    for module, source in sources.items():
        MODULES[module] = tmp_path / f"{module.rsplit('.', 1)[1]}.py"
        MODULES[module].write_text(source)
    try:
        names = _any_names()
        use, dotted = (f"youbot_opt.{NO_ANY_PACKAGES[0]}.planted_{s}" for s in ("use", "dotted"))
        assert _any_in_public_signatures(use, MODULES[use], names[use]) == [f"{use}.f(d)"]
        assert _any_in_public_signatures(dotted, MODULES[dotted], names[dotted]) == [
            f"{dotted}.C.m(return)",
            f"{dotted}.g(return)",
        ]
        with pytest.raises(AssertionError, match="planted_use.f"):
            test_no_any_in_a_public_signature()
    finally:
        for module in sources:
            del MODULES[module]


def _any_aliases(path: Path) -> list[str]:
    """Module-level names bound to ``Any`` itself (``X = Any``, ``X: TypeAlias = typing.Any``)."""

    def is_any(value: ast.expr | None) -> bool:
        return (isinstance(value, ast.Name) and value.id == "Any") or (
            isinstance(value, ast.Attribute) and value.attr == "Any"
        )

    found = []
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Assign) and is_any(node.value):
            found += [ast.unparse(t) for t in node.targets]
        elif isinstance(node, ast.AnnAssign) and is_any(node.value):
            found.append(ast.unparse(node.target))
    return found


def test_no_alias_of_any():
    """No module names ``Any`` under another name: such an alias hides what it stands for."""
    bad = [
        f"{module}.{name} = Any" for module, path in MODULES.items() for name in _any_aliases(path)
    ]
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize(
    ("source", "caught"),
    [
        ("from typing import Any\nExpr = Any\n", True),
        ("import typing\nExpr: typing.TypeAlias = typing.Any\n", True),
        ("import typing as t\nA = B = t.Any\n", True),
        ("from typing import Any\nJSON = dict[str, Any]\n", False),
        ("from typing import Any\ndef f() -> None:\n    x = Any\n", False),
    ],
)
def test_the_alias_rule_catches_a_planted_alias(tmp_path, source, caught):
    """A module-level alias of Any is found; Any used inside a type or a function is not."""
    path = tmp_path / "planted_alias.py"
    path.write_text(source)
    assert bool(_any_aliases(path)) is caught
