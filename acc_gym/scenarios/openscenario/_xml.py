"""An XML element tree that remembers where each element is: file and line.

OpenSCENARIO files are read with the standard library's expat parser (no third-party XML
library). Every element becomes a :class:`Node` carrying its file and line, so that every
error the reader raises can name them. A file is treated as possibly hostile: a document
type declaration (the door to entity-expansion attacks; OpenSCENARIO uses none) is refused,
external entities are never fetched, and files above :data:`MAX_BYTES` are refused.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from xml.parsers import expat

MAX_BYTES = 32 * 1024 * 1024  # [B] a scenario, catalog or road file larger than this is refused


class OpenScenarioError(ValueError):
    """A file the reader cannot take: the message names the file and line (``file:line: ...``)."""

    def __init__(self, message: str, file: str | None = None, line: int | None = None):
        self.file, self.line, self.reason = file, line, message
        where = f"{file}:{line}: " if file and line else (f"{file}: " if file else "")
        super().__init__(where + message)


@dataclass
class Node:
    """One XML element: ``tag``, attributes, child elements, and where it was read."""

    tag: str
    attrib: dict
    file: str
    line: int
    children: list = field(default_factory=list)

    def find(self, tag: str):
        """The first child element named ``tag`` (None without)."""
        for c in self.children:
            if c.tag == tag:
                return c
        return None

    def findall(self, tag: str) -> list:
        return [c for c in self.children if c.tag == tag]

    def only(self, what: str = "element"):
        """The single child element (an XML choice such as a Position's); an error without one."""
        if len(self.children) != 1:
            raise self.error(f"<{self.tag}> must hold exactly one {what}, it holds "
                             f"{[c.tag for c in self.children] or 'none'}")
        return self.children[0]

    def error(self, message: str) -> OpenScenarioError:
        return OpenScenarioError(message, self.file, self.line)

    def iter(self):
        yield self
        for c in self.children:
            yield from c.iter()


def parse(path) -> Node:
    """The root element of the XML file ``path`` (a :class:`Node`)."""
    path = os.fspath(path)
    try:
        size = os.path.getsize(path)
        if size > MAX_BYTES:
            raise OpenScenarioError(f"file of {size} bytes is larger than the reader's limit of {MAX_BYTES}", path)
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise OpenScenarioError(f"cannot read the file ({exc.strerror or exc})", path) from None
    return parse_bytes(data, path)


def parse_bytes(data: bytes, name: str = "<string>") -> Node:
    """The root element of the XML document ``data``; ``name`` is the file named in errors."""
    p = expat.ParserCreate()
    stack: list[Node] = []
    root: list[Node] = []

    def start(tag, attrs):
        node = Node(tag, dict(attrs), name, p.CurrentLineNumber)
        if stack:
            stack[-1].children.append(node)
        else:
            root.append(node)
        stack.append(node)

    def end(tag):
        stack.pop()

    def doctype(*_):
        raise OpenScenarioError("a document type declaration (<!DOCTYPE ...>) is not accepted", name,
                                p.CurrentLineNumber)

    def entity(*_):
        raise OpenScenarioError("entity declarations are not accepted", name, p.CurrentLineNumber)

    p.StartElementHandler, p.EndElementHandler = start, end
    p.StartDoctypeDeclHandler, p.EntityDeclHandler = doctype, entity
    p.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    try:
        p.Parse(data, True)
    except expat.ExpatError as exc:
        raise OpenScenarioError(f"not well-formed XML ({expat.ErrorString(exc.code)})", name, exc.lineno) from None
    if not root:
        raise OpenScenarioError("no XML element in the file", name)
    return root[0]
