"""Tests of :mod:`previewctl.validation`: field types, value objects that check themselves, and the
messages a pydantic error becomes (dotted key, value, expected type, valid choices, near misses)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Annotated, Any, Literal

import pydantic
import pytest
from pydantic import Field

from previewctl.errors import ParameterError, PreviewctlError, SceneError
from previewctl.scene.shapes import Box, Halfspace, Mesh, Sphere
from previewctl.search.ga import GAOptions
from previewctl.sim.schema import OutputSpec, Timing
from previewctl.validation import (
    Count,
    Finite,
    Flag,
    Integer,
    Positive,
    Section,
    Size,
    Text,
    check_fields,
    interval,
    table,
    validate,
)


@dataclass(frozen=True)
class Gear:
    """A value object for the tests: its bounds are its annotations."""

    ratio: Annotated[Finite, interval(0, 1, "(]")] = 0.5
    teeth: Count = 12
    axis: Annotated[tuple[Finite, ...], Size(2, 3)] = (0.0, 0.0, 1.0)
    oiled: Flag = False

    def __post_init__(self) -> None:
        check_fields(self, ParameterError)


class Wheel(Section):
    kind: Literal["wheel"]
    radius: Positive


class Crank(Section):
    kind: Literal["crank"]
    length: Positive


Part = Annotated[Wheel | Crank, Field(discriminator="kind")]


class Machine(Section):
    name: Text = "m"
    gear: table("gear", Gear, motor=(Text, "none")) = Field(description="the gear box")  # type: ignore[valid-type]
    parts: tuple[Part, ...] = ()
    mode: Literal["fast", "slow", "off"] = "off"


def message(data: dict[str, Any]) -> str:
    with pytest.raises(ParameterError) as info:
        validate(Machine, data, ParameterError, prefix="machine.toml: ", root="the machine")
    assert not isinstance(info.value, pydantic.ValidationError) and info.value.__cause__ is None
    return str(info.value)


# ----------------------------------------------------------------------------------- messages


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        ({"gear": {"ratoi": 0.3}},
         "machine.toml: unknown key 'gear.ratoi' (did you mean 'gear.ratio'?); valid keys in [gear]: motor, ratio, "
         "teeth, axis, oiled"),
        ({"gear": {}, "nmae": "x"}, "unknown key 'nmae' (did you mean 'name'?); valid keys of the machine: name, gear"),
        ({}, "missing section [gear] (the gear box)"),
        ({"gear": 3}, "gear must be a table, got 3"),
        ({"gear": {"ratio": "0.3"}}, "gear.ratio must be a finite number, got '0.3'; valid: numbers in (0, 1]"),
        ({"gear": {"ratio": True}}, "gear.ratio must be a finite number, got True"),
        ({"gear": {"ratio": float("inf")}}, "gear.ratio must be finite, got inf"),
        ({"gear": {"ratio": 0}}, "gear.ratio must lie in (0, 1], got 0.0"),
        ({"gear": {"teeth": 2.0}}, "gear.teeth must be an integer, got 2.0; valid: integers >= 1"),
        ({"gear": {"teeth": 0}}, "gear.teeth must be >= 1, got 0"),
        ({"gear": {"axis": [1]}}, "gear.axis must have 2 or 3 entries, got 1: [1]"),
        ({"gear": {"axis": "z"}}, "gear.axis must be a list of 2 or 3 numbers, got 'z'"),
        ({"gear": {"axis": [0, "1"]}}, "gear.axis[1] must be a finite number, got '1'"),
        ({"gear": {"oiled": "yes"}}, "gear.oiled must be true or false, got 'yes'"),
        ({"gear": {"motor": 3}}, "gear.motor must be a string, got 3"),
        ({"gear": {}, "mode": "fsat"}, "mode = 'fsat' is not valid; valid: fast, slow, off (did you mean 'fast'?)"),
        ({"gear": {}, "parts": [{"kind": "wheal", "radius": 1}]},
         "parts[0].kind = 'wheal' is not valid; valid: wheel, crank (did you mean 'wheel'?)"),
        ({"gear": {}, "parts": [{"radius": 1}]}, "parts[0].kind is missing; valid: wheel, crank"),
        ({"gear": {}, "parts": [{"kind": "crank"}]},
         "parts[0].length is missing; required keys in parts[0] (kind = 'crank'): kind, length"),
        ({"gear": {}, "parts": [{"kind": "wheel", "radius": 1, "spokes": 8}]},
         "unknown key 'parts[0].spokes'; valid keys in parts[0] (kind = 'wheel'): kind, radius"),
        ({"gear": {}, "parts": "wheel"}, "parts must be a list of tables, got 'wheel'"),
        ({"gear": {"ratio": 2, "teeth": 0}}, "gear.ratio must lie in (0, 1], got 2.0 (and 1 more problem)"),
    ],
)
def test_messages_name_the_key_the_value_and_the_choices(data: dict[str, Any], expected: str) -> None:
    assert expected in message(data)


@pytest.mark.parametrize(
    ("kind", "value", "expected"),
    [
        (Count, 2.5, "the value must be an integer, got 2.5; valid: integers >= 1"),
        (Positive, "1", "the value must be a finite number, got '1'; valid: numbers > 0"),
        (Annotated[Finite, Field(lt=0)], None, "the value must be a finite number, got None; valid: numbers < 0"),
        (Annotated[Integer, Field(ge=4, le=100)], "8", "the value must be an integer, got '8'; valid: integers in "
                                                       "[4, 100]"),
        (Annotated[Finite, interval(0, 90, "(]")], "x", "the value must be a finite number, got 'x'; valid: numbers "
                                                        "in (0, 90]"),
        (Count | None, 1.5, "the value must be an integer, got 1.5; valid: integers >= 1"),
        (Finite, "x", "the value must be a finite number, got 'x'"),  # no bound, nothing to add
        (Flag, 1, "the value must be true or false, got 1"),
    ],
)
def test_a_value_of_the_wrong_type_is_told_the_bounds_too(kind: Any, value: object, expected: str) -> None:
    with pytest.raises(ParameterError) as info:
        validate(kind, value, ParameterError)
    assert str(info.value) == expected


def test_a_misspelt_key_is_not_also_reported_missing() -> None:
    assert message({"gear": {}, "parts": [{"kind": "crank", "lenght": 2}]}) == (
        "machine.toml: unknown key 'parts[0].lenght' (did you mean 'parts[0].length'?); valid keys in parts[0] "
        "(kind = 'crank'): kind, length"
    )


def test_a_valid_document_gives_the_values_converted() -> None:
    machine = validate(Machine, {"gear": {"ratio": 1, "axis": [0, 1]}, "parts": [{"kind": "crank", "length": 2}]},
                       ParameterError)
    assert machine.gear.ratio == 1.0 and isinstance(machine.gear.ratio, float)
    assert machine.gear.axis == (0.0, 1.0) and machine.gear.motor == "none" and machine.gear.teeth == 12
    assert isinstance(machine.parts[0], Crank)


# ------------------------------------------------------------------------------ value objects


def test_value_objects_check_and_convert_their_fields() -> None:
    gear = Gear(ratio=1, axis=[1, 0])  # type: ignore[arg-type]
    assert gear.ratio == 1.0 and isinstance(gear.ratio, float) and gear.axis == (1.0, 0.0)
    with pytest.raises(ParameterError, match=r"^teeth must be >= 1, got 0$"):
        Gear(teeth=0)
    with pytest.raises(ParameterError, match=r"^ratio must lie in \(0, 1\], got 1\.5$"):
        replace(gear, ratio=1.5)


@pytest.mark.parametrize(
    ("build", "error", "expected"),
    [
        (lambda: Sphere(-0.1), SceneError, "radius must be > 0, got -0.1"),
        (lambda: Box((0.1, 0.2)), SceneError, "size must have 3 entries, got 2: (0.1, 0.2)"),
        (lambda: Halfspace((0.0, 0.0, 0.0)), SceneError, "normal must be non-zero, got [0.0, 0.0, 0.0]"),
        (lambda: Mesh("m.stl", scale="big"), SceneError, "scale must be a list of 3 numbers, got 'big'"),
        (lambda: Timing(dt=0.0), ParameterError, "dt must be > 0, got 0.0"),
        (lambda: Timing(dt=0.5, duration=0.1), ParameterError, "dt = 0.5 s is longer than duration = 0.1 s"),
        (lambda: OutputSpec(figures=("movie",)), ParameterError,
         "figures[0] = 'movie' is not valid; valid: strobe, S, clearance, error"),
        (lambda: OutputSpec(strobe_poses=1), ParameterError, "strobe_poses must be >= 2, got 1"),
        (lambda: GAOptions(immigrants=0.6), ParameterError, "immigrants must lie in [0, 0.5], got 0.6"),
        (lambda: GAOptions(tournament=0), ParameterError, "tournament must be >= 1, got 0"),
    ],
)
def test_runtime_value_objects_raise_the_package_errors(
    build: Any, error: type[PreviewctlError], expected: str
) -> None:
    with pytest.raises(error) as info:
        build()
    assert str(info.value) == expected


def test_a_scalar_mesh_scale_means_all_three_axes() -> None:
    assert Mesh("m.stl", scale=2).scale == (2.0, 2.0, 2.0)  # type: ignore[arg-type]
