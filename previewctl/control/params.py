"""Controller names and parameters: gains, preview times and weights (eqs. 20-21), GA settings."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from previewctl.errors import ConfigurationError

CONTROLLER_NAMES: tuple[str, ...] = ("none", "gradient", "single", "multi", "reach", "oracle")
"""``oracle`` is non-causal (it reads the whole future): a reference, see :mod:`previewctl.control.oracle`."""
PREVIEW_MODES: tuple[str, ...] = ("single", "multi", "reach")
PAPER_WEIGHTS: tuple[float, ...] = (0.3, 0.65, 0.05)
"""The paper's three-preview weights ``k_1, k_2, k_3`` (section 7.2)."""

_WEIGHT_SUM_TOL = 1e-9


def check_preview_weights(weights: object, where: str = "weights") -> tuple[float, ...]:
    """Validate the multi-preview weights ``k_i`` of eq. 21.

    Args:
        weights: a sequence of numbers.
        where: the name used in messages (e.g. ``"controller.weights"``).

    Returns:
        The weights as a tuple of floats.

    Raises:
        ConfigurationError: not a non-empty list of numbers, some ``k_i`` outside ``(0, 1)`` or
            ``Σ k_i ≠ 1`` (to 1e-9); the message names the value.
    """
    if (
        isinstance(weights, (str, bytes))
        or not isinstance(weights, Sequence)
        or not weights
        or not all(isinstance(k, (int, float)) and not isinstance(k, bool) for k in weights)
    ):
        raise ConfigurationError(f"{where} must be a non-empty list of numbers k_i, got {weights!r}")
    values = tuple(float(k) for k in weights)
    for i, k in enumerate(values, start=1):
        if not (math.isfinite(k) and 0.0 < k < 1.0):
            hint = "; for one preview use the 'single' controller" if len(values) == 1 else ""
            raise ConfigurationError(f"{where} = {list(values)}: k_{i} = {k!r} must satisfy 0 < k_i < 1{hint}")
    total = math.fsum(values)
    if abs(total - 1.0) > _WEIGHT_SUM_TOL:
        raise ConfigurationError(f"{where} = {list(values)}: the k_i must sum to 1, they sum to {total!r}")
    return values


def _gain_tuple(value: object, where: str) -> tuple[float, ...]:
    """A positive scalar gain as ``(g,)`` or a per-joint gain vector as a tuple."""
    items = (value,) if isinstance(value, (int, float)) and not isinstance(value, bool) else value
    if (
        isinstance(items, (str, bytes))
        or not isinstance(items, Sequence)
        or not items
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in items)
    ):
        raise ConfigurationError(f"{where} must be a positive number or a list of positive numbers, got {value!r}")
    out = tuple(float(v) for v in items)
    if not all(math.isfinite(v) and v > 0 for v in out):
        raise ConfigurationError(f"{where} must be positive and finite, got {value!r}")
    return out


def _positive(value: object, where: str, *, allow_zero: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigurationError(f"{where} must be a finite number, got {value!r}")
    if value < 0 or (value == 0 and not allow_zero):
        raise ConfigurationError(f"{where} must be {'>= 0' if allow_zero else '> 0'}, got {value!r}")
    return float(value)


def _count(value: object, where: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ConfigurationError(f"{where} must be an integer >= {minimum}, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class ControllerParams:
    """Parameters of every controller (each mode reads the ones it needs).

    Attributes:
        gain: ``K_v`` of eqs. 20/21 [1/s]: one number or one per velocity coordinate.
        gradient_gain: ``K_g`` of the ``gradient`` mode, ``v = K_g ∇S`` [rad²/s per unit of S]
            (S is in the index's length unit, ~10⁴ for the paper's arm in cm, hence the small default).
        feedback_gain: ``K_p`` on the hand error [1/s].
        damping: ``λ_max`` of the damped least-squares inverse [m/rad] (0 disables damping).
        singular_threshold: ``ε``: damping starts when ``σ_min(J) < ε`` [m/rad].
        velocity_scale: fraction of the URDF joint speed limits that the controller may use, in (0, 1].
        preview_time: ``t̃`` [s], the spacing of the preview times ``t + i t̃``.
        weights: ``k_i`` of eq. 21 (``multi``; ``single`` uses ``k_1 = 1``); ``0 < k_i < 1``, ``Σ = 1``.
        previews: number of future nodes of the ``reach`` mode.
        population: GA population per imaginary arm.
        elite: GA individuals copied unchanged to the next generation.
        top_k: distinct peaks the GA keeps.
        fd_step: finite-difference step of ``∇S`` [rad].
        ga_options: further keyword arguments for the GA, as ``(name, value)`` pairs.
        with_gradient: ``single``/``multi`` also add ``K_g ∇S`` (``gradient_gain``) to ``v``.
    """

    gain: tuple[float, ...] = (1.0,)
    gradient_gain: tuple[float, ...] = (1e-4,)
    feedback_gain: float = 5.0
    damping: float = 0.05
    singular_threshold: float = 0.05
    velocity_scale: float = 1.0
    preview_time: float = 1.0
    weights: tuple[float, ...] = PAPER_WEIGHTS
    previews: int = 3
    population: int = 64
    elite: int = 2
    top_k: int = 4
    fd_step: float = 1e-4
    ga_options: tuple[tuple[str, Any], ...] = field(default=())
    with_gradient: bool = False

    def __post_init__(self) -> None:
        """Validate every field.

        Raises:
            ConfigurationError: a bad value; the message names the field and the value.
        """
        object.__setattr__(self, "gain", _gain_tuple(self.gain, "gain"))
        object.__setattr__(self, "gradient_gain", _gain_tuple(self.gradient_gain, "gradient_gain"))
        _positive(self.feedback_gain, "feedback_gain", allow_zero=True)
        _positive(self.damping, "damping", allow_zero=True)
        _positive(self.singular_threshold, "singular_threshold")
        if not (_positive(self.velocity_scale, "velocity_scale") <= 1.0):
            raise ConfigurationError(f"velocity_scale must lie in (0, 1], got {self.velocity_scale!r}")
        _positive(self.preview_time, "preview_time")
        object.__setattr__(self, "weights", check_preview_weights(self.weights, "weights"))
        _count(self.previews, "previews", 1)
        _count(self.population, "population", 2)
        _count(self.elite, "elite", 0)
        _count(self.top_k, "top_k", 1)
        _positive(self.fd_step, "fd_step")
        if not isinstance(self.with_gradient, bool):
            raise ConfigurationError(f"with_gradient must be true or false, got {self.with_gradient!r}")
        if self.elite >= self.population:
            raise ConfigurationError(f"elite ({self.elite}) must be smaller than population ({self.population})")

    def preview_weights(self, mode: str) -> tuple[float, ...]:
        """The ``k_i`` used by a preview mode: ``(1,)`` for ``single`` (eq. 20), ``weights`` otherwise."""
        return (1.0,) if mode == "single" else self.weights


@dataclass(frozen=True)
class ControllerSpec:
    """A controller choice: its name (one of :data:`CONTROLLER_NAMES`) and parameters."""

    name: str = "none"
    params: ControllerParams = field(default_factory=ControllerParams)

    def __post_init__(self) -> None:
        """Check the name.

        Raises:
            ConfigurationError: unknown controller name (lists the valid ones).
        """
        if self.name not in CONTROLLER_NAMES:
            raise ConfigurationError(f"unknown controller {self.name!r}; valid: {', '.join(CONTROLLER_NAMES)}")
