"""Models of file tables, made by hand (:class:`Section`) or from a value object's fields (:func:`table`),
and the calls that validate against them and raise the package's errors."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar, TypeVar, get_type_hints

from pydantic import BaseModel, ConfigDict, TypeAdapter, ValidationError, create_model

from previewctl.errors import ParameterError, PreviewctlError
from previewctl.validation.messages import explain


class Section(BaseModel):
    """A table of a file: unknown keys are errors, values are checked, the result is read-only."""

    model_config = ConfigDict(extra="forbid", frozen=True)


def fields_of(cls: type, exclude: tuple[str, ...] = ()) -> dict[str, Any]:
    """The init fields of dataclass ``cls`` as :func:`pydantic.create_model` definitions
    ``name -> (annotation, default)``; the annotations carry the bounds (fields with a
    ``default_factory`` are not supported: a value object's defaults are immutable)."""
    hints = get_type_hints(cls, include_extras=True)
    return {f.name: (hints[f.name], ... if f.default is dataclasses.MISSING else f.default)
            for f in dataclasses.fields(cls) if f.init and f.name not in exclude}


def table(title: str, cls: type, /, *, exclude: tuple[str, ...] = (), base: type[Section] = Section,
          **extra: Any) -> type[Section]:
    """A :class:`Section` named ``title`` with ``extra`` fields (``key=(annotation, default)``) followed by
    the init fields of dataclass ``cls`` (but ``exclude``): the same keys, types, bounds and defaults."""
    model: type[Section] = create_model(title, __base__=base, **extra, **fields_of(cls, exclude))
    return model


_MODELS: dict[type, type[Section]] = {}


def _model_of(cls: type) -> type[Section]:
    """The (cached) model of dataclass ``cls``'s fields."""
    if cls not in _MODELS:
        _MODELS[cls] = table(cls.__name__, cls)
    return _MODELS[cls]


class Checked:
    """Base of a frozen dataclass that checks every field against its annotation when it is made.

    A rule across fields goes in :meth:`check`. The error type is :attr:`error`.
    """

    error: ClassVar[type[PreviewctlError]] = ParameterError

    def __post_init__(self) -> None:
        """Raises :attr:`error` for a bad field (named with its value) or a broken :meth:`check` rule."""
        check_fields(self, self.error)
        self.check()

    def check(self) -> None:
        """Rules across fields; none unless a subclass has some."""


def check_fields(obj: Any, error: type[PreviewctlError]) -> None:
    """Check every init field of a frozen dataclass against its annotation; store the converted values
    (an integer given for a float becomes a float, a list a tuple).

    Raises:
        error: a bad field, named with its value (see :func:`explain`).
    """
    model = _model_of(type(obj))
    checked = validate(model, {name: getattr(obj, name) for name in model.model_fields}, error)
    for name in model.model_fields:
        object.__setattr__(obj, name, getattr(checked, name))


_ADAPTERS: dict[int, tuple[Any, TypeAdapter[Any]]] = {}


def _adapter(kind: Any) -> TypeAdapter[Any]:
    """A cached validator of ``kind`` (schema types are module constants)."""
    if id(kind) not in _ADAPTERS:
        _ADAPTERS[id(kind)] = (kind, TypeAdapter(kind))
    return _ADAPTERS[id(kind)][1]


T = TypeVar("T")


def build(cls: type[T], values: Mapping[str, Any], error: type[PreviewctlError]) -> T:
    """``cls(**values)`` for a dataclass that checks itself, with an unknown name reported like a bad value
    (the valid names of ``cls`` and a "did you mean").

    Raises:
        error: an unknown key or a bad value.
    """
    checked = validate(_model_of(cls), dict(values), error, root=cls.__name__)
    return cls(**{name: getattr(checked, name) for name in values})


def validate(kind: Any, data: object, error: type[PreviewctlError], *, where: str = "", prefix: str = "",
             root: str = "the value") -> Any:
    """``data`` checked against ``kind`` (a model, or a type such as a discriminated union of models).

    Args:
        kind: the schema.
        data: the values (a mapping for a model).
        error: the error type to raise.
        where: dotted key of ``data`` itself (``"obstacles[2].motion"``), prefixed to every key.
        prefix: text before the message (e.g. the file name).
        root: what to call ``data`` itself when ``where`` is empty (e.g. "the scenario").

    Returns:
        The validated value (a model instance for a model).

    Raises:
        error: the first problem, explained by :func:`explain`.
    """
    try:
        return _adapter(kind).validate_python(data)
    except ValidationError as exc:
        raise error(prefix + explain(exc, kind, where, root)) from None
