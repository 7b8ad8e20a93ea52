"""Strict XML parsing and error sites of the strict URDF loader (issue 6, item 1).

:func:`parse_xml_strict` parses with the standard library's expat and refuses
any ``DOCTYPE``, entity or notation declaration, so nothing is ever expanded or
fetched; :func:`parse_number` reads finite decimals only. :class:`Site` and
:func:`fail` give every error the same shape:
``file:line: <tag name='...'> of link '...': problem [rule: ...]``.

>>> tree = parse_xml_strict(Path("robot.urdf").read_bytes(), "robot.urdf")  # doctest: +SKIP
"""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from typing import NamedTuple, NoReturn, Protocol
from xml.parsers import expat

from youbot_opt.exceptions import (
    InvalidModelError,
    ParameterError,
    UnsafeURDFError,
    URDFError,
    URDFStructureError,
    URDFSyntaxError,
)

__all__ = [
    "MAX_XML_DEPTH",
    "MAX_XML_ELEMENTS",
    "NUMBER_RULE",
    "Site",
    "XMLTarget",
    "fail",
    "limit",
    "local_name",
    "parse_number",
    "parse_xml_strict",
    "root_of",
    "scan_xml_strict",
    "shorten",
    "site",
]

#: Unambiguous (each digit can match one way only), so a failed match of a
#: megabyte of digits is linear, not quadratic.
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
NUMBER_RULE = "numbers are finite decimals such as 1.5 or -2e-3"
#: Deepest element nesting accepted (``<robot>`` is level 1; a URDF needs about
#: 6, Gazebo plugin blocks a few more). Recursive tree walks (re-serialisation,
#: Pinocchio's parser) stay far from any stack limit below it.
#: Environment variable: ``YOUBOT_OPT_MAX_XML_DEPTH``.
MAX_XML_DEPTH: int = 100
#: Most elements accepted in one file (a 1,000-joint robot with visuals and
#: collisions has about 15,000). Each parsed element costs ~0.5 kB of memory.
#: Environment variable: ``YOUBOT_OPT_MAX_XML_ELEMENTS``.
MAX_XML_ELEMENTS: int = 200_000
#: Longest quoted value in an error message, in characters.
_QUOTE_CHARS = 60
#: Longest ``problem`` text of an error message, in characters (a backstop).
_PROBLEM_CHARS = 2000
#: Longest element description of an error message, in characters.
_ELEMENT_CHARS = 300


def limit(name: str, default: int, override: int | None = None) -> int:
    """Return a size limit: ``override``, else the environment, else ``default``.

    Parameters
    ----------
    name : str
        Name of the limit, e.g. ``"MAX_XML_DEPTH"``; the environment variable
        is ``YOUBOT_OPT_<name>`` (e.g. ``YOUBOT_OPT_MAX_XML_DEPTH=500``).
    default : int
        The module constant.
    override : int, optional
        A value passed by the caller (keyword argument), used first.

    Returns
    -------
    int
        The limit, >= 1.

    Raises
    ------
    ParameterError
        If the override or the environment variable is not an integer >= 1.
    """
    variable = f"YOUBOT_OPT_{name}"
    if override is not None:
        value, source = override, f"{name.lower()}={override!r}"
    elif os.environ.get(variable, "").strip():
        text = os.environ[variable].strip()
        source = f"{variable}={shorten(text)}"
        value = int(text) if re.fullmatch(r"[0-9]{1,18}", text) else 0
    else:
        return default
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ParameterError(f"{source} is not an integer >= 1", name=name.lower(), value=value)
    return value


def shorten(text: object, limit: int = _QUOTE_CHARS) -> str:
    """Quote a value for an error message, eliding its middle if it is long.

    Parameters
    ----------
    text : object
        The value (its ``repr`` is quoted).
    limit : int
        Longest result, in characters.

    Returns
    -------
    str
        ``repr(text)``, or its first and last characters with the number of
        characters left out, e.g. ``'1111...<999,940 characters>...1111'``.
    """
    return _elide(repr(text), limit)


def _elide(text: str, limit: int) -> str:
    if len(text) <= limit:
        return text
    keep = limit // 2
    return f"{text[:keep]}...<{len(text) - 2 * keep:,} characters>...{text[-keep:]}"


class _Element(ET.Element):
    """An element that remembers its line in the source file (``sourceline``, as lxml)."""


class Site(NamedTuple):
    """Where a rule was broken: file, element description and 1-based line."""

    path: str
    element: str
    line: int | None


def site(path: str, elem: ET.Element, owner: str = "") -> Site:
    """Describe ``elem`` for an error message.

    Parameters
    ----------
    path : str
        File the element comes from.
    elem : Element
        The element.
    owner : str
        Its link or joint, e.g. ``"link 'arm_link_1'"``, if not the element itself.

    Returns
    -------
    Site
        Path, ``"<tag name='...'> of owner"`` and the line (None if unknown).
    """
    name = elem.get("name")
    text = f"<{elem.tag} name={shorten(name)}>" if name else f"<{elem.tag}>"
    if owner:
        text += f" of {owner}"
    return Site(path, text, getattr(elem, "sourceline", None))


def fail(cls: type[URDFError], where: Site, problem: str, rule: str) -> URDFError:
    """Build an error of class ``cls`` naming the file, element, line and rule.

    Parameters
    ----------
    cls : type
        A subclass of :class:`~youbot_opt.exceptions.URDFError`.
    where : Site
        Where the rule was broken.
    problem : str
        What is wrong, with the offending value.
    rule : str
        The rule, in words.

    Returns
    -------
    URDFError
        The error, ready to raise.
    """
    line = f":{where.line}" if where.line is not None else ""
    problem = _elide(problem, _PROBLEM_CHARS)  # a backstop: values are quoted with shorten()
    element = _elide(where.element, _ELEMENT_CHARS)  # a huge owner name
    return cls(
        f"{where.path}{line}: {element}: {problem} [rule: {rule}]",
        path=where.path,
        element=element,
        line=where.line,
        rule=rule,
    )


def local_name(tag: object) -> str:
    """Return a tag's name without its namespace (``{ns}image`` or ``ns:image`` -> ``image``).

    Parameters
    ----------
    tag : object
        The tag as the parser reports it.

    Returns
    -------
    str
        The local name.
    """
    return str(tag).rsplit("}", 1)[-1].rsplit(":", 1)[-1]


class XMLTarget(Protocol):
    """Receives the events of :func:`scan_xml_strict` (like ElementTree's parser targets)."""

    def start(self, tag: str, attrs: dict[str, str], line: int) -> None:
        """Open element ``tag`` with ``attrs`` at 1-based ``line``."""

    def end(self, tag: str) -> None:
        """Close element ``tag``."""

    def data(self, text: str) -> None:
        """Character data inside the current element."""


def scan_xml_strict(
    data: bytes,
    path: str,
    target: XMLTarget,
    *,
    max_depth: int | None = None,
    max_elements: int | None = None,
) -> None:
    """Stream XML bytes through ``target``, strictly and without any DTD processing.

    Parameters
    ----------
    data : bytes
        The whole file content.
    path : str
        File name, for error messages.
    target : XMLTarget
        Receives start, end and character-data events.
    max_depth : int, optional
        Deepest nesting accepted; default :data:`MAX_XML_DEPTH` (or the
        environment variable ``YOUBOT_OPT_MAX_XML_DEPTH``).
    max_elements : int, optional
        Most elements accepted; default :data:`MAX_XML_ELEMENTS` (or
        ``YOUBOT_OPT_MAX_XML_ELEMENTS``).

    Raises
    ------
    UnsafeURDFError
        On a ``DOCTYPE``, entity or notation declaration or an external entity
        reference, raised before anything is expanded or fetched.
    URDFSyntaxError
        If the bytes are not one well-formed XML document.
    UnsafeURDFError
        If the nesting or the element count exceeds its limit, raised when the
        first element past it is met.
    ParameterError
        If a limit (argument or environment variable) is not an integer >= 1.
    """
    depth_limit = limit("MAX_XML_DEPTH", MAX_XML_DEPTH, max_depth)
    element_limit = limit("MAX_XML_ELEMENTS", MAX_XML_ELEMENTS, max_elements)
    parser = expat.ParserCreate()
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    rule = "no DOCTYPE or entity declarations (nothing may be expanded or fetched)"

    def refuse(what: str) -> NoReturn:
        where = Site(path, what, parser.CurrentLineNumber)
        raise fail(UnsafeURDFError, where, f"{what} is refused", rule)

    depth, count = 0, 0

    def start(tag: str, attrs: dict[str, str]) -> None:
        nonlocal depth, count
        depth, count = depth + 1, count + 1
        if depth > depth_limit or count > element_limit:
            name, value, variable = (
                ("nesting", depth_limit, "MAX_XML_DEPTH")
                if depth > depth_limit
                else ("element count", element_limit, "MAX_XML_ELEMENTS")
            )
            where = Site(path, f"<{shorten(tag)[1:-1]}>", parser.CurrentLineNumber)
            problem = (
                f"the XML {name} exceeds the limit of {value:,} (raise it with "
                f"size_limits=SizeLimits({variable.lower()}=...) or the environment variable "
                f"YOUBOT_OPT_{variable})"
            )
            rule = f"XML nesting <= {depth_limit:,} levels and <= {element_limit:,} elements"
            raise fail(UnsafeURDFError, where, problem, rule)
        target.start(tag, attrs, parser.CurrentLineNumber)

    def end(tag: str) -> None:
        nonlocal depth
        depth -= 1
        target.end(tag)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = target.data
    parser.StartDoctypeDeclHandler = lambda *_: refuse("<!DOCTYPE>")
    parser.EntityDeclHandler = lambda *_: refuse("<!ENTITY>")
    parser.UnparsedEntityDeclHandler = lambda *_: refuse("<!ENTITY>")
    parser.NotationDeclHandler = lambda *_: refuse("<!NOTATION>")
    parser.ExternalEntityRefHandler = lambda *_: refuse("external entity reference")
    parser.buffer_text = True
    try:
        parser.Parse(data, True)
    except expat.ExpatError as e:
        where = Site(path, "document", e.lineno)
        raise fail(
            URDFSyntaxError,
            where,
            f"not well-formed XML: {expat.ErrorString(e.code)} (column {e.offset})",
            "the file is one complete, well-formed XML document",
        ) from None


class _TreeTarget:
    def __init__(self) -> None:
        self.builder = ET.TreeBuilder(element_factory=_Element)

    def start(self, tag: str, attrs: dict[str, str], line: int) -> None:
        self.builder.start(tag, attrs).sourceline = line  # type: ignore[attr-defined]

    def end(self, tag: str) -> None:
        self.builder.end(tag)

    def data(self, text: str) -> None:
        self.builder.data(text)


def parse_xml_strict(
    data: bytes, path: str, *, max_depth: int | None = None, max_elements: int | None = None
) -> ET.ElementTree:
    """Parse XML bytes into a tree, strictly and without any DTD processing.

    Any ``DOCTYPE``, entity or notation declaration is refused the moment
    expat meets it, so nothing is ever expanded or fetched (billion laughs,
    external entities). Malformed, truncated and badly encoded input is an
    error, never "recovered" as some parsers do. Nesting deeper than
    :data:`MAX_XML_DEPTH` and more than :data:`MAX_XML_ELEMENTS` elements are
    refused while streaming, before any tree or recursive walk exists (raise
    them with the environment variables of :func:`limit`).

    Parameters
    ----------
    data : bytes
        The whole file content.
    path : str
        File name, for error messages.
    max_depth, max_elements : int, optional
        As :func:`scan_xml_strict` [levels], [count].

    Returns
    -------
    xml.etree.ElementTree.ElementTree
        The tree; each element has a ``sourceline`` attribute (1-based).

    Raises
    ------
    UnsafeURDFError, URDFSyntaxError, ParameterError
        As :func:`scan_xml_strict`.
    """
    target = _TreeTarget()
    scan_xml_strict(data, path, target, max_depth=max_depth, max_elements=max_elements)
    return ET.ElementTree(target.builder.close())


def root_of(tree: ET.ElementTree, path: str) -> ET.Element:
    """Return the root element of a parsed file.

    Parameters
    ----------
    tree : xml.etree.ElementTree.ElementTree
        The parsed file.
    path : str
        Its name, for error messages.

    Returns
    -------
    xml.etree.ElementTree.Element
        The root element.

    Raises
    ------
    URDFStructureError
        If the tree is empty (only possible for trees not made by this module).
    """
    root = tree.getroot()
    if root is None:
        where = Site(path, "document", None)
        raise fail(URDFStructureError, where, "has no root element", "a URDF has a <robot> root")
    return root


def parse_number(text: str | None, where: Site, attr: str) -> float:
    """Parse one finite decimal number strictly.

    Accepted: finite decimals such as ``1.5`` or ``-2e-3``; refused: ``1,5``,
    ``nan``, ``inf``, ``1_0`` (which Python's ``float`` accepts), ``0x1p3``
    and ``1e400`` (overflows).

    Parameters
    ----------
    text : str or None
        The attribute text.
    where : Site
        The element, for error messages.
    attr : str
        The attribute name, for error messages.

    Returns
    -------
    float
        The value.

    Raises
    ------
    InvalidModelError
        If ``text`` is not a decimal number (``1,5``, ``nan``, ``inf``,
        ``1_0``, empty) or overflows to infinity (``1e400``).
    """
    value = math.inf
    stripped = text.strip(" \t\r\n") if text is not None else ""
    if _DECIMAL.fullmatch(stripped):
        value = float(stripped)
    if not math.isfinite(value):
        problem = f"{attr}={shorten(text)} is not a finite number"
        raise fail(InvalidModelError, where, problem, NUMBER_RULE)
    return value
