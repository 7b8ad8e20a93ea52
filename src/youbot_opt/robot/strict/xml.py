"""Strict XML parsing and error sites of the strict URDF loader (issue 6, item 1).

:func:`parse_xml_strict` parses with the standard library's expat and refuses
any ``DOCTYPE``, entity or notation declaration the moment expat meets it, so
nothing is ever expanded or fetched (billion laughs, external entities).
Malformed, truncated and badly encoded input is an error, never "recovered" as
some parsers do. Elements keep their source line (``sourceline``, as in lxml).

:func:`parse_number` reads numbers strictly: finite decimals such as ``1.5``
or ``-2e-3``; not ``1,5``, ``nan``, ``inf``, ``1_0`` (which Python's
``float`` accepts), ``0x1p3`` or ``1e400`` (overflows).

:class:`Site` and :func:`fail` give every error the same shape:
``file:line: <tag name='...'> of link '...': problem [rule: ...]``.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from typing import NamedTuple, NoReturn, Protocol
from xml.parsers import expat

from youbot_opt.exceptions import (
    InvalidModelError,
    UnsafeURDFError,
    URDFError,
    URDFStructureError,
    URDFSyntaxError,
)

__all__ = [
    "NUMBER_RULE",
    "Site",
    "XMLTarget",
    "fail",
    "local_name",
    "parse_number",
    "parse_xml_strict",
    "root_of",
    "scan_xml_strict",
    "site",
]

_DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
NUMBER_RULE = "numbers are finite decimals such as 1.5 or -2e-3"


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
    text = f"<{elem.tag} name={name!r}>" if name else f"<{elem.tag}>"
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
    return cls(
        f"{where.path}{line}: {where.element}: {problem} [rule: {rule}]",
        path=where.path,
        element=where.element,
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


def scan_xml_strict(data: bytes, path: str, target: XMLTarget) -> None:
    """Stream XML bytes through ``target``, strictly and without any DTD processing.

    Parameters
    ----------
    data : bytes
        The whole file content.
    path : str
        File name, for error messages.
    target : XMLTarget
        Receives start, end and character-data events.

    Raises
    ------
    UnsafeURDFError
        On a ``DOCTYPE``, entity or notation declaration or an external entity
        reference, raised before anything is expanded or fetched.
    URDFSyntaxError
        If the bytes are not one well-formed XML document.
    """
    parser = expat.ParserCreate()
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    rule = "no DOCTYPE or entity declarations (nothing may be expanded or fetched)"

    def refuse(what: str) -> NoReturn:
        where = Site(path, what, parser.CurrentLineNumber)
        raise fail(UnsafeURDFError, where, f"{what} is refused", rule)

    parser.StartElementHandler = lambda tag, attrs: target.start(
        tag, attrs, parser.CurrentLineNumber
    )
    parser.EndElementHandler = target.end
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


def parse_xml_strict(data: bytes, path: str) -> ET.ElementTree:
    """Parse XML bytes into a tree, strictly and without any DTD processing.

    Parameters
    ----------
    data : bytes
        The whole file content.
    path : str
        File name, for error messages.

    Returns
    -------
    xml.etree.ElementTree.ElementTree
        The tree; each element has a ``sourceline`` attribute (1-based).

    Raises
    ------
    UnsafeURDFError, URDFSyntaxError
        As :func:`scan_xml_strict`.
    """
    target = _TreeTarget()
    scan_xml_strict(data, path, target)
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
        raise fail(InvalidModelError, where, f"{attr}={text!r} is not a finite number", NUMBER_RULE)
    return value
