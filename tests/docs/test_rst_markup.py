"""docs/_ext/rst_markup.py: the griffe extension that shows acc_gym's reStructuredText-ish docstrings
as Markdown in the API reference -- roles become optional cross-references resolved in the
docstring's scope, ``::`` markers, simple tables and underlined titles become their Markdown forms,
and anything else passes through unchanged."""

from __future__ import annotations

import importlib.util
import textwrap
from pathlib import Path

import pytest

griffe = pytest.importorskip("griffe", reason="the docs extension needs griffe: pip install '.[docs]' (or '.[test]')")

PATH = Path(__file__).resolve().parents[2] / "docs" / "_ext" / "rst_markup.py"
SOURCE = '''
"""A module."""
from os.path import join as joined


def get_thing(name):
    """A function."""


class Thing:
    """A class."""

    def episodes(self):
        """A method."""
'''


@pytest.fixture(scope="module")
def ext():
    spec = importlib.util.spec_from_file_location("rst_markup", PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def mod():
    return griffe.visit("pkg", filepath=Path("pkg/__init__.py"), code=SOURCE)


def ref(identifier: str, title: str) -> str:
    return f'<autoref identifier="{identifier}" optional><code>{title}</code></autoref>'


def test_roles_resolve_in_the_docstrings_scope_and_stay_optional(ext, mod):
    method = mod["Thing"]["episodes"]
    assert ext.translate("see :func:`get_thing`.", mod) == f"see {ref('pkg.get_thing', 'get_thing')}."
    assert ext.translate(":meth:`Thing.episodes`", mod) == ref("pkg.Thing.episodes", "Thing.episodes")
    # from a method, a module-level name resolves through the enclosing scopes
    assert ext.translate(":class:`Thing`", method) == ref("pkg.Thing", "Thing")
    # an imported name resolves to where it comes from
    assert ext.translate(":func:`joined`", mod) == ref("os.path.join", "joined")
    # ``~`` shows the last component; a full path is kept as written
    assert ext.translate(":mod:`~pkg.sub.mod`", mod) == ref("pkg.sub.mod", "mod")
    # an explicit title, and a name that does not resolve (kept: an optional reference renders as code)
    assert ext.translate(":data:`the table <pkg.TABLE>`", mod) == ref("pkg.TABLE", "the table")
    assert ext.translate(":func:`nowhere`", mod) == ref("nowhere", "nowhere")


def test_literal_block_markers_become_markdown(ext, mod):
    text = "Example::\n\n    code()\n\nSee below ::\n\n    more()\n\n::\n\n    last()\n\nkeep a::b here"
    assert ext.translate(text, mod) == ("Example:\n\n    code()\n\nSee below\n\n    more()\n\n\n\n    last()\n\n"
                                        "keep a::b here")


def test_a_simple_table_becomes_a_markdown_table_with_continuation_lines_joined(ext, mod):
    text = textwrap.dedent("""\
        Before.

        =====  ===============  ===
        name   what             n
        =====  ===============  ===
        a      first line,      1
               second line
        b|c    other            2
        =====  ===============  ===

        After.""")
    assert ext.translate(text, mod).splitlines() == [
        "Before.", "", "| name | what | n |", "|---|---|---|", "| a | first line, second line | 1 |",
        r"| b\|c | other | 2 |", "", "After."]


def test_an_underlined_title_becomes_a_bold_line_not_a_heading(ext, mod):
    assert ext.translate("Parameters\n----------\nx: a number.", mod) == "**Parameters**\n\nx: a number."
    assert ext.translate("a - b\n--\nshort rule kept", mod) == "a - b\n--\nshort rule kept"


def test_plain_markdown_passes_through_unchanged(ext, mod):
    text = "A ``code`` span, *emphasis*, a list:\n\n* one\n* two\n\n    indented()\n"
    assert ext.translate(text, mod) == text


def test_the_extension_rewrites_every_docstring_of_a_loaded_package(ext, tmp_path):
    pkg = tmp_path / "demo"
    pkg.mkdir()
    (pkg / "__init__.py").write_text('"""The demo.\n\nUse :func:`demo.sub.f`::\n\n    f()\n"""\n', encoding="utf-8")
    (pkg / "sub.py").write_text('def f():\n    """Calls :class:`Thing`."""\n\n\nclass Thing:\n    pass\n',
                                encoding="utf-8")
    loaded = griffe.load("demo", search_paths=[tmp_path], extensions=griffe.load_extensions(ext.RstMarkup))
    assert loaded.docstring.value == f"The demo.\n\nUse {ref('demo.sub.f', 'demo.sub.f')}:\n\n    f()"
    assert loaded["sub"]["f"].docstring.value == f"Calls {ref('demo.sub.Thing', 'Thing')}."
