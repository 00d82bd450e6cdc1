"""A griffe extension for the API reference: Sphinx roles in docstrings become mkdocstrings cross-references.

The docstrings say ``:func:`~previewctl.control.factory.make_controller` `` or, inside a module, ``:meth:`step` ``.
Markdown has no such roles, so before mkdocstrings renders a docstring each role becomes an autorefs link,
``[`make_controller`][previewctl.control.factory.make_controller]``, its target resolved the way Python resolves
the name in the docstring's scope (the object, its parents, the module's imports). A role that names an object
outside previewctl (``:class:`~pathlib.Path` ``) becomes plain code; one that names nothing the package has keeps
its link, so the strict build reports it.
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


class SphinxRoles(griffe.Extension):
    """Rewrite every docstring of the package once it is loaded."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        """Rewrite the roles of ``pkg`` and of every object under it."""
        if pkg.name == _PACKAGE:
            _rewrite_tree(pkg, pkg)


def _rewrite_tree(obj: griffe.Object, pkg: griffe.Module) -> None:
    if obj.docstring is not None:
        obj.docstring.value = _ROLE.sub(lambda match: _link(match, obj, pkg), obj.docstring.value)
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
