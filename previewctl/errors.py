"""Typed errors. Every failure a user can cause raises a subclass of :class:`PreviewctlError`
whose message names the bad value and, where there is a finite set, the valid choices."""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterable, Iterator


class PreviewctlError(Exception):
    """Base class of every error previewctl raises on purpose."""


class RobotLoadError(PreviewctlError):
    """A robot source could not be loaded (missing file, malformed URDF, missing mesh, ...)."""


class UnknownNameError(PreviewctlError, KeyError):
    """A robot, frame, joint, link or option name that does not exist."""

    def __init__(self, kind: str, name: object, valid: Iterable[str]) -> None:
        self.kind, self.name, self.valid = kind, name, list(valid)
        shown = ", ".join(self.valid[:80]) + (", ..." if len(self.valid) > 80 else "")
        super().__init__(f"unknown {kind} {name!r}; valid: {shown}")

    def __str__(self) -> str:  # KeyError would otherwise quote the whole message
        return str(self.args[0])


class ConfigurationError(PreviewctlError, ValueError):
    """A joint configuration (or batch) of the wrong shape, or with non-finite entries."""


class ParameterError(PreviewctlError, ValueError):
    """A bad parameter of the API: a controller, index, potential, timing or GA setting out of its bounds,
    an unknown option name, an option of the wrong type, or a bad time, period or seed."""


class SceneError(PreviewctlError, ValueError):
    """An obstacle or scene description that cannot be built."""


class ScenarioError(PreviewctlError, ValueError):
    """A scenario file with a bad key, type or value."""


class StartCollisionError(ScenarioError):
    """A scenario whose start configuration ``q0`` collides at ``t = 0``: bad input, refused before the run.

    Attributes:
        pairs: the colliding pairs, deepest first: ``(link, other, distance)`` with ``other`` an obstacle's name
            (or, for a self-collision, another link's) and ``distance`` the signed distance [m] (<= 0).
    """

    def __init__(self, message: str, pairs: Iterable[tuple[str, str, float]] = ()) -> None:
        super().__init__(message)
        self.pairs = tuple(pairs)

    def __reduce__(self) -> tuple[type[StartCollisionError], tuple[str, tuple[tuple[str, str, float], ...]]]:
        return type(self), (str(self), self.pairs)  # crosses a process boundary whole (previewctl paper --jobs)


class TrajectoryError(PreviewctlError, ValueError):
    """A hand path that cannot be built (too few waypoints, non-positive duration, ...)."""


class UnreachableTargetError(PreviewctlError, ValueError):
    """A hand target that no configuration of the arm reaches."""


class OutputError(PreviewctlError, ValueError):
    """An output file or folder that cannot be written (a missing parent, a folder where a file goes, ...)."""


class MissingExtraError(PreviewctlError, ImportError):
    """An optional dependency is not installed; the message names it and the extra that installs it."""


class ObservationError(PreviewctlError, ValueError):
    """An observation of an obstacle that cannot be used: a position, rotation or velocity that is not finite or of
    the wrong shape, a shape of an unknown type or missing for a new obstacle, or a time going back by more than the
    timeout (``Controller.observe``, :mod:`previewctl.sensing`)."""


class PlanningWorkerError(PreviewctlError, RuntimeError):
    """The planning worker beside the control loop crashed, failed or stopped answering; the loop goes on without
    it (the ``qp`` fallback) and reports this in ``Controller.last_info.worker_error``."""


class IgnoredSettingWarning(UserWarning):
    """A setting was given that the chosen controller does not read (e.g. by a scenario file shared between
    controllers); the run goes on without it, and its log records it."""


@contextlib.contextmanager
def shared_settings() -> Iterator[None]:
    """Make controllers from a table shared by several of them (a scene's ``[controller]`` table, which the paper
    experiment and the bench give every controller) without an :class:`IgnoredSettingWarning` per controller: what
    each ignores is still recorded in its composition and its run's log."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IgnoredSettingWarning)
        yield
