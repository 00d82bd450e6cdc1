"""Reading a robot's XML files (URDF, SRDF), with errors that name the file."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from previewctl.errors import RobotLoadError


def robot_root(path: Path, kind: str) -> ET.Element:
    """The ``<robot>`` root element of the ``kind`` file (``"URDF"``, ``"SRDF"``) at ``path``.

    Raises:
        RobotLoadError: not valid XML, or a root other than ``<robot>``.
    """
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise RobotLoadError(f"{kind} file {str(path)!r} is not valid XML: {exc}") from exc
    if root.tag != "robot":
        raise RobotLoadError(f"{kind} file {str(path)!r} has root <{root.tag}>, expected <robot>")
    return root
