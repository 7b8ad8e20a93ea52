"""Strict XML reading and error sites of the hostile-URDF policy (issue 6, item 1).

:func:`parse_xml_strict` parses with lxml (``resolve_entities=False``,
``no_network=True``, ``load_dtd=False``, ``huge_tree=False``) and refuses any
``DOCTYPE`` before its declarations are read, so nothing is ever expanded or
fetched; elements keep their ``sourceline``. :func:`parse_number` reads finite
decimals only. :class:`Site` and :func:`fail` give every error the same shape:
``file:line: <tag name='...'> of link '...': problem [rule: ...]``.

>>> tree = parse_xml_strict(Path("robot.urdf").read_bytes(), "robot.urdf")  # doctest: +SKIP
"""

from __future__ import annotations

import math
import os
import re
from typing import NamedTuple, NoReturn

from lxml import etree

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
    "fail",
    "limit",
    "local_name",
    "parse_number",
    "parse_xml_strict",
    "root_of",
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
#: Environment variable: ``YOUBOT_OPT_MAX_XML_DEPTH``. libxml2 itself stops at
#: 256 levels (``huge_tree=False``): a larger limit is refused as malformed XML there.
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


class Site(NamedTuple):
    """Where a rule was broken: file, element description and 1-based line."""

    path: str
    element: str
    line: int | None


def site(path: str, elem: etree._Element, owner: str = "") -> Site:
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


#: Bytes fed to the parser at a time: the size limits are checked between chunks,
#: so the tree never grows much past a limit before it is refused.
_CHUNK = 1 << 16
_DOCTYPE_RULE = "no DOCTYPE or entity declarations (nothing may be expanded or fetched)"
_SYNTAX_RULE = "the file is one complete, well-formed XML document"


def _parser_options(long_text: bool = False) -> dict[str, bool]:
    """Return the safe options of every parser here (no entity, DTD, network, huge input)."""
    return {
        "resolve_entities": False,
        "no_network": True,
        "load_dtd": False,
        "huge_tree": long_text,
        "remove_comments": True,
        "remove_pis": True,
    }


class _DoctypeFound(Exception):
    """Raised by :class:`_PrologGuard` when the prolog declares a document type."""


class _RootReached(Exception):
    """Raised by :class:`_PrologGuard` at the root element: the prolog is over."""


class _PrologGuard:
    """An lxml parser target that reads the prolog only, stopping at a DOCTYPE or the root.

    lxml calls ``doctype`` as the declaration starts, before any entity of its
    internal subset is declared, expanded or fetched.
    """

    def doctype(self, name: str, pubid: str | None, system: str | None) -> None:
        raise _DoctypeFound

    def start(self, tag: str, attrib: dict[str, str]) -> None:
        raise _RootReached

    def close(self) -> None:
        return None


def _syntax_error(path: str, error: etree.XMLSyntaxError) -> URDFError:
    line, column = error.position if error.position else (error.lineno, error.offset)
    reason = re.sub(r", line \d+, column \d+$", "", str(error.msg or error))
    logged = [e for e in error.error_log if e.level >= etree.ErrorLevels.ERROR]
    if not line and logged:  # the parser gave up ("no element found"): its last error says why
        line, column, reason = logged[-1].line, logged[-1].column, logged[-1].message
    where = Site(path, "document", line or None)
    problem = f"not well-formed XML: {reason.strip()} (column {column})"
    return fail(URDFSyntaxError, where, problem, _SYNTAX_RULE)


def _refuse_doctype(data: bytes, path: str) -> None:
    """Raise UnsafeURDFError if the prolog of ``data`` declares a document type."""
    parser = etree.XMLParser(target=_PrologGuard(), **_parser_options())
    try:
        parser.feed(data)
        parser.close()
    except _DoctypeFound:
        start = data.find(b"<!DOCTYPE")
        line = data.count(b"\n", 0, start) + 1 if start >= 0 else None
        where = Site(path, "<!DOCTYPE>", line)
        raise fail(UnsafeURDFError, where, "<!DOCTYPE> is refused", _DOCTYPE_RULE) from None
    except _RootReached:
        return
    except etree.XMLSyntaxError as e:
        raise _syntax_error(path, e) from None


#: Deepest nesting libxml2 parses without ``huge_tree`` [levels].
_LIBXML2_MAX_DEPTH = 256


def _too_large(
    path: str, element: str, line: int | None, depth: int, limits: tuple[int, int]
) -> NoReturn:
    depth_limit, element_limit = limits
    name, value, variable = (
        ("nesting", min(depth_limit, _LIBXML2_MAX_DEPTH), "MAX_XML_DEPTH")
        if depth > depth_limit
        else ("element count", element_limit, "MAX_XML_ELEMENTS")
    )
    where = Site(path, element, line)
    problem = (
        f"the XML {name} exceeds the limit of {value:,} (raise it with "
        f"size_limits=SizeLimits({variable.lower()}=...) or the environment variable "
        f"YOUBOT_OPT_{variable})"
    )
    if depth_limit >= _LIBXML2_MAX_DEPTH and depth > depth_limit:
        problem = (
            f"the XML nesting exceeds libxml2's limit of {_LIBXML2_MAX_DEPTH} levels "
            f"(the limit asked for is {depth_limit:,})"
        )
    rule = f"XML nesting <= {depth_limit:,} levels and <= {element_limit:,} elements"
    raise fail(UnsafeURDFError, where, problem, rule)


def parse_xml_strict(
    data: bytes,
    path: str,
    *,
    max_depth: int | None = None,
    max_elements: int | None = None,
    long_text: bool = False,
) -> etree._ElementTree:
    """Parse XML bytes into a tree, strictly and without any DTD processing.

    Any ``DOCTYPE`` is refused as soon as its declaration starts, before any
    entity is declared, expanded or fetched (billion laughs, external
    entities); an entity reference without a declaration is malformed.
    Malformed, truncated and badly encoded input is an error, never
    "recovered". Nesting deeper than :data:`MAX_XML_DEPTH` and more than
    :data:`MAX_XML_ELEMENTS` elements are refused while the file is fed to the
    parser, before a walk of the tree (raise them with the environment
    variables of :func:`limit`). Comments and processing instructions are dropped.

    Parameters
    ----------
    data : bytes
        The whole file content.
    path : str
        File name, for error messages.
    max_depth : int, optional
        Deepest nesting accepted [levels]; default :data:`MAX_XML_DEPTH` (or
        the environment variable ``YOUBOT_OPT_MAX_XML_DEPTH``).
    max_elements : int, optional
        Most elements accepted [count]; default :data:`MAX_XML_ELEMENTS` (or
        ``YOUBOT_OPT_MAX_XML_ELEMENTS``).
    long_text : bool
        Accept text nodes longer than libxml2's 10 MB (lxml's ``huge_tree``):
        for COLLADA meshes, whose vertex arrays are text and whose size the
        caller has bounded. False (default) for URDF files.

    Returns
    -------
    lxml.etree._ElementTree
        The tree; each element has its 1-based ``sourceline``.

    Raises
    ------
    UnsafeURDFError
        On a ``DOCTYPE`` (raised before anything is expanded or fetched), or
        if the nesting or the element count exceeds its limit.
    URDFSyntaxError
        If the bytes are not one well-formed XML document.
    ParameterError
        If a limit (argument or environment variable) is not an integer >= 1.
    """
    limits = (
        limit("MAX_XML_DEPTH", MAX_XML_DEPTH, max_depth),
        limit("MAX_XML_ELEMENTS", MAX_XML_ELEMENTS, max_elements),
    )
    _refuse_doctype(data, path)
    parser = etree.XMLPullParser(events=("start", "end"), **_parser_options(long_text))
    depth = count = 0
    root = None
    try:
        for begin in range(0, len(data), _CHUNK):
            parser.feed(data[begin : begin + _CHUNK])
            for event, elem in parser.read_events():
                if event == "end":
                    depth -= 1
                    continue
                depth, count = depth + 1, count + 1
                root = elem if root is None else root
                if depth > limits[0] or count > limits[1]:
                    element = f"<{shorten(elem.tag)[1:-1]}>"
                    _too_large(path, element, elem.sourceline, depth, limits)
        parser.close()
    except etree.XMLSyntaxError as e:
        if "Excessive depth in document" in str(e.msg):  # libxml2's own depth limit
            line = e.position[0] if e.position else e.lineno
            _too_large(
                path, "document", line or None, max(limits[0], _LIBXML2_MAX_DEPTH) + 1, limits
            )
        raise _syntax_error(path, e) from None
    if root is None:  # no element at all: close() did not complain (it always should)
        where = Site(path, "document", None)
        raise fail(URDFSyntaxError, where, "not well-formed XML: no element found", _SYNTAX_RULE)
    return root.getroottree()


def root_of(tree: etree._ElementTree, path: str) -> etree._Element:
    """Return the root element of a parsed file.

    Parameters
    ----------
    tree : lxml.etree._ElementTree
        The parsed file.
    path : str
        Its name, for error messages.

    Returns
    -------
    lxml.etree._Element
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
