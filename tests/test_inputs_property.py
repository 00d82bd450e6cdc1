"""Property tests: whatever a scenario file or an API call holds, previewctl either accepts it or raises one
of its own typed errors (:class:`~previewctl.errors.PreviewctlError`), never a bare Python or NumPy error.

Hypothesis runs derandomized (profile ``ci`` in ``conftest.py``): the same examples on every machine."""

from __future__ import annotations

import copy
from typing import Any

import coal
import numpy as np
import pytest
from helpers import planar_doc
from hypothesis import given, settings
from hypothesis import strategies as st

import previewctl
from previewctl.control.params import ControllerParams
from previewctl.errors import PreviewctlError
from previewctl.index.amsi import IndexParams
from previewctl.index.potential import Potential
from previewctl.robot.model import Robot
from previewctl.scene.shapes import Box, Capsule, Cylinder, Halfspace, Plane, Sphere
from previewctl.sim.scenario import scenario_from_dict

NUMBERS = st.one_of(
    st.integers(-(10**12), 10**12),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, -1, 1e-300, 1e300, 0.5, 3]),
)
SCALARS = st.one_of(NUMBERS, st.booleans(), st.text(max_size=8))
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                      st.dictionaries(st.text(max_size=6), inner, max_size=3)),
                      max_leaves=8)
"""What a TOML value can be: numbers (NaN, inf and extremes included), booleans, strings, lists, tables."""

KEYS: dict[str, list[str]] = {
    "": ["name", "seed", "description", "unknown"],
    "robot": ["source", "q0", "q0_deg", "tip", "lock", "task", "geometry", "control_points", "guarded_links"],
    "path": ["waypoints", "duration", "start_time", "orientation_rpy"],
    "controller": ["name", "gain", "weights", "previews", "population", "elite", "top_k", "preview_time",
                   "velocity_scale", "ga", "execution"],
    "timing": ["dt", "frame", "duration"],
    "index": ["weights", "length_unit"],
    "potential": ["influence_distance"],
    "output": ["figures", "gif", "strobe_poses"],
    "obstacles": ["shape", "radius", "size", "position", "motion", "normal", "name"],
}


@st.composite
def scenario_documents(draw: st.DrawFn) -> dict[str, Any]:
    """The planar4 test scenario with one to three keys set to arbitrary values (one obstacle to mutate)."""
    doc = planar_doc(obstacles=[{"name": "ball", "shape": "sphere", "radius": 0.2, "position": [-1.5, -1.0]}])
    doc = copy.deepcopy(doc)
    for _ in range(draw(st.integers(1, 3))):
        section = draw(st.sampled_from(sorted(KEYS)))
        key = draw(st.sampled_from(KEYS[section]))
        value = draw(VALUES)
        if section == "":
            doc[key] = value
        elif section == "obstacles":
            doc["obstacles"][0][key] = value
        else:
            doc.setdefault(section, {})
            if isinstance(doc[section], dict):
                doc[section][key] = value
    return doc


@settings(max_examples=150, deadline=None)
@given(doc=scenario_documents())
def test_any_scenario_document_is_accepted_or_refused_with_a_typed_error(doc: dict[str, Any]) -> None:
    try:
        scenario = scenario_from_dict(doc)
    except PreviewctlError as exc:
        assert str(exc) and "\n" not in str(exc)  # one line, with words
        return
    assert scenario.timing.steps <= 1_000_000


ARRAYS = st.one_of(
    st.lists(NUMBERS, max_size=6),
    st.lists(st.lists(NUMBERS, min_size=4, max_size=4), max_size=3),
    st.just([]),
    st.just([[]]),
    SCALARS,
    st.lists(st.text(max_size=2), max_size=4),
)


@settings(max_examples=80, deadline=None)
@given(q=ARRAYS)
def test_any_configuration_is_evaluated_or_refused_with_a_typed_error(q: Any, planar4: Robot, kinova: Robot) -> None:
    for robot in (planar4, kinova):
        try:
            result = previewctl.avoidance(robot, q)
            evaluation = previewctl.evaluate(robot, None, q)
        except PreviewctlError:
            continue
        assert np.all(np.isfinite(result.amsi)) and np.all(np.isfinite(evaluation.amsi))


SHAPES = [
    (Sphere, st.tuples(VALUES)),
    (Box, st.tuples(VALUES)),
    (Capsule, st.tuples(VALUES, VALUES)),
    (Cylinder, st.tuples(VALUES, VALUES)),
    (Halfspace, st.tuples(VALUES, VALUES)),
    (Plane, st.tuples(VALUES, VALUES)),
]


@pytest.mark.parametrize(("shape", "arguments"), SHAPES, ids=[s.__name__ for s, _ in SHAPES])
def test_any_obstacle_shape_is_built_or_refused_with_a_typed_error(shape: type, arguments: Any) -> None:
    @settings(max_examples=60, deadline=None)
    @given(args=arguments)
    def check(args: tuple[Any, ...]) -> None:
        try:
            built = shape(*args)
        except PreviewctlError:
            return
        assert isinstance(built.geometry(), coal.CollisionGeometry)  # accepted: Coal builds it

    check()


PARAMETERS = [
    (ControllerParams, ["gain", "weights", "previews", "population", "elite", "top_k", "damping", "ga_options"]),
    (IndexParams, ["weights", "length_unit", "rank_tolerance"]),
    (Potential, ["influence_distance"]),
]


@pytest.mark.parametrize(("kind", "keys"), PARAMETERS, ids=[k.__name__ for k, _ in PARAMETERS])
def test_any_parameter_value_is_accepted_or_refused_with_a_typed_error(kind: type, keys: list[str]) -> None:
    @settings(max_examples=60, deadline=None)
    @given(values=st.dictionaries(st.sampled_from(keys), VALUES, min_size=1, max_size=2))
    def check(values: dict[str, Any]) -> None:
        try:
            kind(**values)
        except PreviewctlError as exc:
            assert str(exc)

    check()
