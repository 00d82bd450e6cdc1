"""A :class:`pydantic.ValidationError` in words: the dotted key, the value, what was expected, the choices.

The ``loc`` of each pydantic error is walked through the schema that was validated, to find the
dotted key (``obstacles[1].motion.velocity``: list indices in brackets, union tags left out), the
expected type (told in words: "a list of 3 numbers"; a value of the wrong type for a bounded number is told the
bounds too: "steps must be an integer, got 2.5; valid: integers >= 1"), the valid keys of the table that holds it and
the valid choices of a ``Literal`` or a tagged union, with :mod:`difflib`'s nearest for a near miss.
"""

from __future__ import annotations

import dataclasses
import difflib
import types
from collections.abc import Mapping
from typing import Annotated, Any, Literal, Union, get_args, get_origin

import annotated_types
from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo

from previewctl.validation.arrays import show
from previewctl.validation.fields import CUSTOM, Interval, Size


@dataclasses.dataclass
class _Spot:
    """Where an error's ``loc`` leads in a schema."""

    key: str  # dotted key, e.g. "obstacles[0].radius"
    kind: Any  # the type expected there (None when unknown)
    holder: type[BaseModel] | None = None  # the model whose field the last key is
    holder_key: str = ""  # the holder's own dotted key
    variant: str = ""  # the holder's union tag, e.g. " (shape = 'sphere')"
    field: FieldInfo | None = None
    union: bool = False  # the loc chose a member of an undiscriminated union


def _unwrap(kind: Any) -> tuple[Any, list[Any], str | None]:
    """``kind`` without ``Annotated`` and ``None`` options: (type, metadata, discriminator)."""
    metadata: list[Any] = []
    discriminator = None
    while True:
        if get_origin(kind) is Annotated:
            kind, *extra = get_args(kind)
            metadata += extra
            discriminator = next((m.discriminator for m in extra if isinstance(m, FieldInfo) and m.discriminator),
                                 discriminator)
        elif _is_union(kind) and type(None) in get_args(kind):
            rest = [a for a in get_args(kind) if a is not type(None)]
            kind = rest[0] if len(rest) == 1 else Union[tuple(rest)]  # noqa: UP007
        else:
            return kind, metadata, (discriminator if isinstance(discriminator, str) else None)


def _is_union(kind: Any) -> bool:
    """Whether ``kind`` is ``Union[...]`` or ``A | B``."""
    return get_origin(kind) in (Union, types.UnionType)


def _is_model(kind: Any) -> bool:
    """Whether ``kind`` is a pydantic model (a table)."""
    return isinstance(kind, type) and issubclass(kind, BaseModel)


def _annotation(field: FieldInfo) -> Any:
    """A field's type with its constraints (pydantic keeps them apart)."""
    return Annotated[(field.annotation, *field.metadata)] if field.metadata else field.annotation


def _tags(kind: Any, discriminator: str) -> dict[str, Any]:
    """Tag value -> member model of a discriminated union."""
    out: dict[str, Any] = {}
    for member in get_args(kind):
        for tag in get_args(_unwrap(member.model_fields[discriminator].annotation)[0]):
            out[tag] = member
    return out


def _locate(root: Any, loc: tuple[int | str, ...], where: str) -> _Spot:
    """Follow an error's ``loc`` from the validated type ``root``, building the dotted key after ``where``."""
    spot, variant = _Spot(where, root), ""
    for part in loc:
        kind, _, discriminator = _unwrap(spot.kind)
        if _is_model(kind) and isinstance(part, str):
            spot.holder, spot.holder_key, spot.variant, variant = kind, spot.key, variant, ""
            spot.field = kind.model_fields.get(part)
            spot.key = f"{spot.key}.{part}" if spot.key else part
            spot.kind = _annotation(spot.field) if spot.field else None
        elif isinstance(part, int):
            spot.key += f"[{part}]"
            args = get_args(kind)
            spot.kind = args[0] if args else None
        elif discriminator is not None and part in _tags(kind, discriminator):
            spot.kind = _tags(kind, discriminator)[part]
            variant = f" ({discriminator} = {part!r})"
        elif _is_union(kind):  # pydantic names the member it tried; the message covers the union
            spot.union = True
            return spot
        else:
            spot.kind = None
    return spot


def _noun(kind: Any, plural: bool = False) -> str:
    """What a value of ``kind`` must be, in words ("a finite number", "a list of 3 numbers")."""
    kind, metadata, discriminator = _unwrap(kind)
    origin = get_origin(kind)
    if _is_model(kind) or discriminator is not None or origin in (dict, Mapping):
        return "tables" if plural else "a table"
    if origin is Literal:
        names = ", ".join(map(str, get_args(kind)))
        return f"names among {names}" if plural else f"one of {names}"
    if _is_union(kind):
        return " or ".join(_noun(member, plural) for member in get_args(kind))
    if origin in (tuple, list):
        size = next((f"{m.text} " for m in metadata if isinstance(m, Size)), "")
        items = _noun(get_args(kind)[0], plural=True) if get_args(kind) else "values"
        return f"lists of {size}{items}" if plural else f"a list of {size}{items}"
    words = _WORDS.get(kind, ("a value", "values"))
    return words[plural]


def _bounds(kind: Any) -> str:
    """The bounds of a number type in words (``">= 1"``, ``"in (0, 90]"``, ``"in [4, 10000]"``), or ``""``."""
    base, metadata, _ = _unwrap(kind)
    if base not in (int, float):
        return ""
    flat = [m for item in metadata for m in (item.metadata if isinstance(item, FieldInfo) else [item])]
    low = next((f"[{m.ge:g}" if isinstance(m, annotated_types.Ge) else f"({m.gt:g}"
                for m in flat if isinstance(m, (annotated_types.Ge, annotated_types.Gt))), "")
    high = next((f"{m.le:g}]" if isinstance(m, annotated_types.Le) else f"{m.lt:g})"
                 for m in flat if isinstance(m, (annotated_types.Le, annotated_types.Lt))), "")
    words = [f"in {m.text}" for m in flat if isinstance(m, Interval)]
    if low and high:
        words.insert(0, f"in {low}, {high}")
    elif low:
        words.insert(0, (">= " if low[0] == "[" else "> ") + low[1:])
    elif high:
        words.insert(0, ("<= " if high[-1] == "]" else "< ") + high[:-1])
    return " and ".join(words)


_WORDS = {float: ("a finite number", "numbers"), int: ("an integer", "integers"), bool: ("true or false", "booleans"),
          str: ("a string", "strings")}


_TYPE_ERRORS = {"float_type", "float_parsing", "int_type", "int_parsing", "int_from_float", "bool_type", "bool_parsing",
                "string_type", "tuple_type", "list_type", "dict_type", "model_type", "model_attributes_type",
                "dataclass_type"}
_BOUNDS = {"greater_than": (">", "gt"), "greater_than_equal": (">=", "ge"), "less_than": ("<", "lt"),
           "less_than_equal": ("<=", "le")}


def _choices(names: Any, given: object) -> str:
    """``"valid: a, b, c"`` and, for a near miss of ``given``, ``" (did you mean 'b'?)"``."""
    names = [str(n) for n in names]
    close = difflib.get_close_matches(given, names, n=1) if isinstance(given, str) else []
    return f"valid: {', '.join(names)}" + (f" (did you mean {close[0]!r}?)" if close else "")


def _meant(spot: _Spot, loc: tuple[int | str, ...]) -> str | None:
    """The dotted key an unknown key at ``spot`` was probably meant to be (difflib's nearest valid key)."""
    valid = list(spot.holder.model_fields) if spot.holder else []
    close = difflib.get_close_matches(str(loc[-1]), valid, n=1)
    return (f"{spot.holder_key}." if spot.holder_key else "") + close[0] if close else None


def _message(error: Any, root: Any, where: str, root_name: str) -> str:
    """One pydantic error as a sentence about the dotted key."""
    kind, loc, value, ctx = error["type"], tuple(error["loc"]), error["input"], error.get("ctx") or {}
    spot = _locate(root, loc, where)
    key = spot.key or root_name
    got = f", got {show(value)}"
    if spot.union or kind in _TYPE_ERRORS:
        bounds = "" if spot.union else _bounds(spot.kind)
        expected = f"; valid: {_noun(spot.kind, plural=True)} {bounds}" if bounds else ""
        return f"{key} must be {_noun(spot.kind)}{got}{expected}"
    if kind == CUSTOM:
        return f"{key} {error['msg']}"
    if kind == "literal_error":
        return f"{key} = {show(value)} is not valid; {_choices(get_args(_unwrap(spot.kind)[0]), value)}"
    holder = spot.holder_key
    place = f"of {root_name}" if not holder else f"in [{holder}]" if "[" not in holder else f"in {holder}"
    place += spot.variant
    if kind == "extra_forbidden":
        valid = list(spot.holder.model_fields) if spot.holder else []
        close = _meant(spot, loc)
        hint = f" (did you mean {close!r}?)" if close else ""
        return f"unknown key {spot.key!r}{hint}; valid keys {place}: {', '.join(valid)}"
    if kind == "missing":
        about = f" ({spot.field.description})" if spot.field and spot.field.description else ""
        if _is_model(_unwrap(spot.kind)[0]):
            return f"missing section [{key}]{about}"
        required = [name for name, f in spot.holder.model_fields.items() if f.is_required()] if spot.holder else []
        return f"{key} is missing{about}; required keys {place}: {', '.join(required)}"
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        name = ctx["discriminator"].strip("'")
        tags = _tags(_unwrap(spot.kind)[0], name)
        if kind == "union_tag_not_found":
            return f"{key}.{name} is missing; valid: {', '.join(tags)}"
        given = value.get(name) if isinstance(value, Mapping) else value
        return f"{key}.{name} = {show(given)} is not valid; {_choices(tags, given)}"
    if kind == "finite_number":
        return f"{key} must be finite{got}"
    if kind in _BOUNDS:
        sign, bound = _BOUNDS[kind]
        return f"{key} must be {sign} {ctx[bound]:g}{got}"
    if kind == "string_too_short":
        return f"{key} must not be empty"
    if kind in ("too_short", "too_long"):
        count = ctx["min_length"] if kind == "too_short" else ctx["max_length"]
        limit = "at least" if kind == "too_short" else "at most"
        return f"{key} must have {limit} {count} entr{'y' if count == 1 else 'ies'}{got}"
    if kind == "value_error":
        return f"{key}: {ctx.get('error', error['msg'])}"
    return f"{key}: {error['msg']}{got}"


def explain(exc: ValidationError, root: Any, where: str = "", root_name: str = "the value") -> str:
    """The first problem of ``exc`` in words (and how many more there are). An unknown key comes first,
    and the key it was probably meant to be is not also reported missing.

    Args:
        exc: the error pydantic raised when validating against ``root``.
        root: the model (or type) that was validated.
        where: dotted key of the validated value, prefixed to every key.
        root_name: what to call the validated value itself when ``where`` is empty.
    """
    errors = sorted(exc.errors(), key=lambda e: e["type"] != "extra_forbidden")
    meant = {_meant(_locate(root, tuple(e["loc"]), where), tuple(e["loc"]))
             for e in errors if e["type"] == "extra_forbidden"}
    errors = [e for e in errors if e["type"] != "missing" or _locate(root, tuple(e["loc"]), where).key not in meant]
    messages = list(dict.fromkeys(_message(e, root, where, root_name) for e in errors))
    more = len(messages) - 1
    return messages[0] + (f" (and {more} more problem{'s' if more > 1 else ''})" if more else "")
