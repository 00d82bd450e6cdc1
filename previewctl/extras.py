"""Optional dependencies: the core install runs a controller; figures, replays, sweeps and the
example-robot-data arms need an extra (``pip install 'previewctl[viz]'``, ``[bench]``, ``[robots]`` or ``[all]``).
"""

from __future__ import annotations

import importlib
from types import ModuleType

from previewctl.errors import MissingExtraError


def require(module: str, extra: str, purpose: str) -> ModuleType:
    """Import ``module``, an optional dependency that the extra ``extra`` installs.

    Args:
        module: the module to import (``"viser"``, ``"matplotlib.pyplot"``).
        extra: the extra of previewctl that installs it (``"viz"``, ``"bench"``, ``"robots"``).
        purpose: what needs it, to start the message (``"the browser replay"``).

    Raises:
        MissingExtraError: ``module`` (or a module it imports) is not installed; one line naming the missing
            module and the ``pip install`` command of the extra.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        missing = exc.name or module
        raise MissingExtraError(f"{purpose} needs {missing}, which is not installed: "
                                f"pip install 'previewctl[{extra}]'") from exc
