"""The results file: JSON Lines, one record a line, appended whole (:func:`~previewctl.files.append_line`).

Reading skips a line that does not parse (the torn tail of a crashed run), so a rerun redoes that run.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from previewctl.files import append_line


def read_records(path: Path) -> list[dict[str, Any]]:
    """Every whole record of ``path`` (none if it does not exist)."""
    if not path.is_file():
        return []
    records = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            record = json.loads(line)
        except ValueError:
            continue
        if isinstance(record, dict):
            records.append(record)
    return records


def _strict(value: Any) -> Any:
    """``value`` with every non-finite float, at any depth of its dicts and lists, replaced by ``None``."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_strict(v) for v in value]
    return value


def append_record(path: Path, record: dict[str, Any]) -> None:
    """Append ``record`` as one JSON line (non-finite floats as ``null``, nested ones too)."""
    append_line(path, json.dumps(_strict(record), sort_keys=True, allow_nan=False))
