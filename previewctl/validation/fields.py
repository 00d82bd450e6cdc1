"""Field types: each states a bound once, for files and API alike (``Annotated`` pydantic types).

Integers and floats are strict: a boolean, a string or a float with an integral value is refused
where a number or an integer is expected (an integer is taken as a float).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, Strict
from pydantic_core import PydanticCustomError, core_schema

from previewctl.validation.arrays import show

Finite = Annotated[float, Strict(), Field(allow_inf_nan=False)]
"""A finite real number (an integer is taken as a float; a boolean or a string is refused)."""
Positive = Annotated[Finite, Field(gt=0)]
NonNegative = Annotated[Finite, Field(ge=0)]
Negative = Annotated[Finite, Field(lt=0)]
Integer = Annotated[int, Strict()]
"""An integer (not a boolean, not a float with an integral value)."""
Count = Annotated[Integer, Field(ge=1)]
Flag = Annotated[bool, Strict()]
Text = Annotated[str, Strict()]

CUSTOM = "previewctl"
"""Error type of the rules raised with :func:`invalid` (their message is a predicate on the key)."""


def invalid(message: str, **context: Any) -> PydanticCustomError:
    """The error a validator raises for a rule of its own.

    Args:
        message: a predicate completing the key, e.g. ``"must lie in {interval}, got {value}"``;
            ``{name}`` fields are filled from ``context``.
        context: values for ``message``.
    """
    return PydanticCustomError(CUSTOM, message, context)


@dataclasses.dataclass(frozen=True)
class Interval:
    """A two-sided bound on a number, checked after its type (made by :func:`interval`); its :attr:`text`
    also completes the message of a value of the wrong type."""

    low: float
    high: float
    ends: Literal["()", "(]", "[)", "[]"] = "[]"

    @property
    def text(self) -> str:
        """``"(0, 1]"``."""
        return f"{self.ends[0]}{self.low:g}, {self.high:g}{self.ends[1]}"

    def check(self, value: float) -> float:
        """``value``, or the error that says where it must lie."""
        above = self.low <= value if self.ends[0] == "[" else self.low < value
        below = value <= self.high if self.ends[1] == "]" else value < self.high
        if not (above and below):
            raise invalid("must lie in {interval}, got {value}", interval=self.text, value=show(value))
        return value

    def __get_pydantic_core_schema__(self, source: Any, handler: Callable[[Any], Any]) -> Any:
        return core_schema.no_info_after_validator_function(self.check, handler(source))


def interval(low: float, high: float, ends: Literal["()", "(]", "[)", "[]"] = "[]") -> Interval:
    """A two-sided bound, e.g. ``Annotated[Finite, interval(0, 1, "(]")]`` for ``0 < x <= 1``."""
    return Interval(low, high, ends)


Probability = Annotated[Finite, interval(0, 1)]


@dataclasses.dataclass(frozen=True)
class Size:
    """The allowed lengths of a list, e.g. ``Annotated[tuple[Finite, ...], Size(2, 3)]``."""

    sizes: tuple[int, ...]

    def __init__(self, *sizes: int) -> None:
        object.__setattr__(self, "sizes", sizes)

    @property
    def text(self) -> str:
        """``"2 or 3"``."""
        return " or ".join(map(str, self.sizes))

    def __get_pydantic_core_schema__(self, source: Any, handler: Callable[[Any], Any]) -> Any:
        """The length check (on the value as given, so that the message shows it) before the inner schema."""

        def check(value: Any) -> Any:
            if isinstance(value, (list, tuple, np.ndarray)) and len(value) not in self.sizes:
                raise invalid("must have {sizes} entries, got {count}: {value}", sizes=self.text,
                              count=len(value), value=show(value))
            return value

        return core_schema.no_info_before_validator_function(check, handler(source))
