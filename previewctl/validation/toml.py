"""Reading TOML: the one place that picks ``tomllib`` (Python ≥ 3.11) or ``tomli`` (3.10) and words its errors."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from previewctl.errors import PreviewctlError


def read_toml(path: str | Path, error: type[PreviewctlError], what: str) -> dict[str, Any]:
    """The tables of the TOML file ``path``, ``what`` naming it in messages (``"scenario file"``).

    Raises:
        error: the file does not exist, cannot be read (permissions, not UTF-8) or is not valid TOML; the
            message names the file and the cause.
    """
    file = Path(path)
    if not file.is_file():
        raise error(f"{what} {str(file)!r} does not exist")
    try:
        return tomllib.loads(file.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{what} {str(file)!r} is not valid TOML: {exc}") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"{what} {str(file)!r} cannot be read: {exc}") from exc


def toml_value(text: str) -> object:
    """``text`` read as a TOML value (``2.0``, ``[0.2, 0.3]``, ``false``), or the text itself when it is none
    (``pseudoinverse``)."""
    try:
        return tomllib.loads(f"value = {text}")["value"]
    except tomllib.TOMLDecodeError:
        return text
