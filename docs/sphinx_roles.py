"""A griffe extension for the API reference: the docstrings' reStructuredText habits, read as Markdown.

Roles become mkdocstrings cross-references, and ``text::`` literal blocks become fenced code blocks.

The docstrings say ``:func:`~previewctl.control.factory.make_controller` `` or, inside a module, ``:meth:`step` ``.
Markdown has no such roles, so before mkdocstrings renders a docstring each role becomes an autorefs link,
``[`make_controller`][previewctl.control.factory.make_controller]``, its target resolved the way Python resolves
the name in the docstring's scope (the object, its parents, the module's imports). A role that names an object
outside previewctl (``:class:`~pathlib.Path` ``) becomes plain code; one that names nothing the package has keeps
its link, so the strict build reports it.

A paragraph ending in ``::`` followed by an indented block is reStructuredText's literal block; Markdown would
flow the block into a paragraph inside a list item. The block becomes a fenced code block at the paragraph's
indentation, and ``text::`` becomes ``text:``.
"""

from __future__ import annotations

import importlib.util
import re
from typing import Any

import griffe

# :role:`target`, :role:`~target` (shows the last name) or :role:`title <target>`; a target may wrap a line.
_ROLE = re.compile(
    r":(?:func|meth|class|mod|attr|data|exc|obj|const):`"
    r"(?:(?P<title>[^`<]+?)\s*<(?P<titled>[\w.]+)>|(?P<tilde>~?)\.?(?P<target>[\w.\s]+?))`"
)
_PACKAGE = "previewctl"
_LIST_ITEM = re.compile(r"\s*(?:[*-]|\d+\.)\s+")


class SphinxRoles(griffe.Extension):
    """Rewrite every docstring of the package once it is loaded."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        """Rewrite the roles of ``pkg`` and of every object under it."""
        if pkg.name == _PACKAGE:
            _rewrite_tree(pkg, pkg)


def _rewrite_tree(obj: griffe.Object, pkg: griffe.Module) -> None:
    if obj.docstring is not None:
        text = _ROLE.sub(lambda match: _link(match, obj, pkg), obj.docstring.value)
        obj.docstring.value = _fence_literal_blocks(text)
    for member in obj.members.values():
        if not member.is_alias:
            _rewrite_tree(member, pkg)  # type: ignore[arg-type]


def _link(match: re.Match[str], scope: griffe.Object, pkg: griffe.Module) -> str:
    if match["titled"]:
        written, text = match["titled"], " ".join(match["title"].split())
    else:
        written = re.sub(r"\s", "", match["target"])
        text = written.rsplit(".", 1)[-1] if match["tilde"] else written
    path = _resolve(written, scope)
    if path is None:
        outside = _is_importable_outside(written)
    else:
        outside = path != _PACKAGE and not path.startswith(f"{_PACKAGE}.")
    if outside:
        return f"`{text}`"
    return f"[`{text}`][{_canonical(path, pkg) if path else written}]"


def _resolve(written: str, scope: griffe.Object) -> str | None:
    """The full dotted path ``written`` names in ``scope``, or None when no name there matches."""
    head, _, rest = written.partition(".")
    if head == _PACKAGE:
        return written
    try:
        return scope.resolve(head) + (f".{rest}" if rest else "")
    except griffe.NameResolutionError:
        return None


def _canonical(path: str, pkg: griffe.Module) -> str:
    """Where ``path`` is documented: the defining module's path for a re-exported name."""
    if path == _PACKAGE:
        return path
    try:
        return str(pkg[path.removeprefix(f"{_PACKAGE}.")].canonical_path)
    except (KeyError, griffe.AliasResolutionError):
        return path


def _is_importable_outside(written: str) -> bool:
    head = written.split(".", 1)[0]
    return head != _PACKAGE and importlib.util.find_spec(head) is not None


def _fence_literal_blocks(text: str) -> str:
    lines = text.split("\n")
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        end = _block_end(lines, i)
        if end is None:
            out.append(line)
            i += 1
            continue
        indent = _content_indent(line)
        block = lines[i + 1 : end]
        while not block[-1].strip():
            block.pop()
        margin = min(len(b) - len(b.lstrip()) for b in block if b.strip())
        lead = line.rstrip()[:-2]
        if lead.strip():
            out.append(lead if lead.endswith((" ", "\t")) else f"{lead}:")
        out += ["", " " * indent + "```"]
        out += [" " * indent + b[margin:] if b.strip() else "" for b in block[1:]]
        out += [" " * indent + "```"]
        i = i + 1 + len(block)
    return "\n".join(out)


def _block_end(lines: list[str], i: int) -> int | None:
    """The index after the literal block that line ``i`` opens (``...::``, a blank line, indented lines), or None."""
    if not lines[i].rstrip().endswith("::") or i + 2 >= len(lines) or lines[i + 1].strip():
        return None
    indent = len(lines[i]) - len(lines[i].lstrip())
    end = i + 1
    while end < len(lines) and (not lines[end].strip() or len(lines[end]) - len(lines[end].lstrip()) > indent):
        end += 1
    return end if any(b.strip() for b in lines[i + 1 : end]) else None


def _content_indent(line: str) -> int:
    """Where a line's text starts: after its indentation and, in a list item, its marker."""
    item = _LIST_ITEM.match(line)
    return item.end() if item else len(line) - len(line.lstrip())
