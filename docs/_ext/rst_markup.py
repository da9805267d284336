"""A griffe extension for the API reference: acc_gym's reStructuredText-ish docstrings as Markdown.

mkdocstrings renders a docstring's text as Markdown. acc_gym's docstrings are written for
reStructuredText readers (Sphinx roles, ``::`` literal blocks, simple tables, underlined
section titles), most of which Markdown shows literally. Rather than rewrite the package's
docstrings for one renderer, this extension translates the few constructs they use when
the site is built (the package itself is untouched):

* ``:func:`name```, ``:class:`~mod.Name```, ... -> a cross-reference, resolved in the
  docstring owner's scope the way Python resolves the name, shown as code. It is an
  *optional* reference of mkdocs-autorefs: it links when the target is on the site and
  stays plain code when it is not (a private helper, a module left out of the reference),
  so an undocumented target is never a broken link or a build warning;
* a paragraph ending in ``::`` -> ``:`` (the indented block after it is already a
  Markdown code block);
* a simple table (``=====  =====`` borders) -> a Markdown table;
* a title underlined with ``---`` / ``===`` (numpydoc's ``Parameters``) -> a bold line, not
  a page-level heading.

Decision: the docstring style is ``sphinx`` (griffe parses ``:param x:`` fields if a
docstring ever has them; acc_gym's current docstrings have none), and anything else passes
through unchanged.
"""

from __future__ import annotations

import html
import re

import griffe

ROLE = re.compile(r":(?:py:)?(?P<role>func|meth|class|mod|data|attr|exc|obj|const):`(?P<body>[^`]+)`")
EXPLICIT = re.compile(r"^(?P<title>.+?)\s*<(?P<target>[^<>]+)>$")  # :role:`title <target>`
BORDER = re.compile(r"^(?P<indent>\s*)=+( +=+)+\s*$")
UNDERLINE = re.compile(r"^\s*(-{3,}|={3,}|~{3,})\s*$")


def resolve(obj, target: str) -> str:
    """The full path of ``target`` as named in ``obj``'s docstring (itself when it does not resolve)."""
    target = target.lstrip(".")
    head, _, rest = target.partition(".")
    if head == obj.module.package.name:
        return target
    scope = obj
    while scope is not None:
        try:
            full = scope.resolve(head)
            return f"{full}.{rest}" if rest else full
        except (griffe.NameResolutionError, griffe.AliasResolutionError, griffe.CyclicAliasError, KeyError):
            scope = scope.parent
    return target


def roles(text: str, obj) -> str:
    def one(match: re.Match) -> str:
        body = match["body"].strip()
        explicit = EXPLICIT.match(body)
        if explicit:
            title, target = explicit["title"], explicit["target"]
        else:
            target = body.lstrip("~")
            title = target.rsplit(".", 1)[-1] if body.startswith("~") else target
        identifier = resolve(obj, target.lstrip("~"))
        return (f'<autoref identifier="{html.escape(identifier)}" optional>'
                f"<code>{html.escape(title)}</code></autoref>")

    return ROLE.sub(one, text)


def table(lines: list[str]) -> list[str]:
    """A simple table's lines (three borders) as a Markdown table."""
    border = lines[0]
    indent = len(border) - len(border.lstrip())
    starts = [m.start() for m in re.finditer(r"=+", border)]
    borders = [k for k, line in enumerate(lines) if BORDER.match(line)]

    def cells(line: str) -> list[str]:
        line = line.ljust(len(border))
        bounds = starts[1:] + [None]
        return [line[a:b].strip() for a, b in zip(starts, bounds)]

    def rows(block: list[str]) -> list[list[str]]:
        out: list[list[str]] = []
        for line in block:
            if not line.strip():
                continue
            parts = cells(line)
            if parts[0] or not out:
                out.append(parts)
            else:  # a continuation line: the first column is empty
                out[-1] = [f"{a} {b}".strip() for a, b in zip(out[-1], parts)]
        return out

    head = rows(lines[borders[0] + 1:borders[1]])
    body = rows(lines[borders[1] + 1:borders[2]])
    fmt = lambda row: " " * indent + "| " + " | ".join(c.replace("|", r"\|") for c in row) + " |"  # noqa: E731
    out = [fmt(r) for r in head] + [" " * indent + "|" + "|".join("---" for _ in starts) + "|"]
    return out + [fmt(r) for r in body]


def blocks(text: str) -> str:
    lines = text.split("\n")
    out: list[str] = []
    k = 0
    while k < len(lines):
        line = lines[k]
        if BORDER.match(line):  # a simple table: the border, the header, a border, the rows, a border
            ends = [j for j in range(k + 1, len(lines)) if lines[j].rstrip() == line.rstrip()][:2]
            if len(ends) == 2:
                out.extend(table(lines[k:ends[1] + 1]))
                k = ends[1] + 1
                continue
        nxt = lines[k + 1] if k + 1 < len(lines) else ""
        if line.strip() and UNDERLINE.match(nxt) and len(nxt.strip()) >= len(line.strip()):
            out.append(f"**{line.strip()}**")
            out.append("")
            k += 2
            continue
        if line.rstrip().endswith("::") and not line.strip().startswith(("..", ">>>")):
            stripped = line.rstrip()[:-2]
            line = stripped.rstrip() if (not stripped.strip() or stripped.endswith(" ")) else stripped + ":"
        out.append(line)
        k += 1
    return "\n".join(out)


def translate(text: str, obj) -> str:
    """``text`` (a docstring of ``obj``) with its reStructuredText constructs in Markdown."""
    return roles(blocks(text), obj)


class RstMarkup(griffe.Extension):
    """Rewrite every docstring of a loaded package once the whole package is known (so that
    names resolve across modules)."""

    def on_package(self, *, pkg: griffe.Module, **kwargs) -> None:
        seen: set[int] = set()

        def walk(obj) -> None:
            if id(obj) in seen or obj.is_alias:
                return
            seen.add(id(obj))
            if obj.docstring is not None:
                obj.docstring.value = translate(obj.docstring.value, obj)
            for member in obj.members.values():
                walk(member)

        walk(pkg)
