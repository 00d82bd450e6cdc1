"""Tests of :mod:`previewctl.scene.motion`: obstacle motions and building them from tables."""

# The constructors accept any array-like (lists included); some tests pass bad types on purpose.
# mypy: disable-error-code="arg-type"

from __future__ import annotations

import copy

import numpy as np
import pytest
from helpers import rot_x, rot_y, rot_z
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from numpy.typing import NDArray

from previewctl.errors import PreviewctlError, SceneError
from previewctl.scene.file import motion_from_dict
from previewctl.scene.motion import (
    ConstantVelocity,
    Motion,
    Periodic,
    Static,
    Waypoints,
    rpy_to_matrix,
)
from previewctl.scene.schema import MOTION_TYPES

WHERE = "obstacles[2].motion"


def all_motions() -> list[Motion]:
    """One motion of each kind, with a non-trivial rotation."""
    rotation = rot_z(0.7) @ rot_x(0.2)
    return [
        Static([0.3, 0.2, 0.1], rotation),
        ConstantVelocity([0.0, 1.0, 2.0], [0.1, -0.2, 0.3], rotation, start_time=0.5),
        Waypoints([0.0, 1.0, 3.0], [[0, 0, 0], [1, 0, 0], [1, 2, 0]], rotation),
        Waypoints([1.0, 2.0, 4.0], [[0, 0, 0], [1, 0, 0], [1, 2, 0]], rotation, loop=True),
        Periodic([0.4, 0.0, 0.3], [0.0, 0.1, 0.05], 4.0, 0.3, rotation),
    ]


# ----------------------------------------------------------------------------- closed forms


def test_static_is_constant() -> None:
    motion = Static([0.3, 0.2, 0.1])
    for t in (-5.0, 0.0, 12.5):
        position, rotation = motion.placement(t)
        np.testing.assert_array_equal(position, [0.3, 0.2, 0.1])
        np.testing.assert_array_equal(rotation, np.eye(3))


def test_constant_velocity_displacement() -> None:
    motion = ConstantVelocity([1.0, 2.0, 3.0], [0.5, -1.0, 0.25], start_time=2.0)
    np.testing.assert_allclose(motion.placement(6.0)[0], [3.0, -2.0, 4.0])
    # displacement between any two times after the start is v * dt
    p1, p2 = motion.positions(np.array([2.5, 7.5]))
    np.testing.assert_allclose(p2 - p1, 5.0 * np.array([0.5, -1.0, 0.25]))


def test_constant_velocity_holds_before_start() -> None:
    motion = ConstantVelocity([1.0, 2.0, 3.0], [0.5, -1.0, 0.25], start_time=2.0)
    np.testing.assert_array_equal(motion.positions(np.array([-10.0, 0.0, 2.0])), [[1, 2, 3]] * 3)


def test_periodic_closed_form_and_period() -> None:
    center, amplitude = np.array([0.4, 0.0, 0.3]), np.array([0.0, 0.1, 0.05])
    motion = Periodic(center, amplitude, period=4.0, phase=0.3)
    times = np.linspace(-3.0, 9.0, 31)
    expected = center + np.sin(2 * np.pi * times / 4.0 + 0.3)[:, None] * amplitude
    np.testing.assert_allclose(motion.positions(times), expected)
    np.testing.assert_allclose(motion.positions(times + 4.0), motion.positions(times), atol=1e-12)
    # a quarter period after the phase is zero the obstacle is at center + amplitude
    quarter = Periodic(center, amplitude, period=4.0)
    np.testing.assert_allclose(quarter.placement(1.0)[0], center + amplitude)
    np.testing.assert_allclose(quarter.placement(0.0)[0], center)


def test_waypoints_interpolation_and_holding() -> None:
    motion = Waypoints([0.0, 1.0, 3.0], [[0, 0, 0], [1, 0, 0], [1, 2, 0]])
    np.testing.assert_allclose(motion.placement(0.5)[0], [0.5, 0.0, 0.0])  # midpoint
    np.testing.assert_allclose(motion.placement(2.0)[0], [1.0, 1.0, 0.0])  # midpoint
    np.testing.assert_array_equal(motion.placement(1.0)[0], [1.0, 0.0, 0.0])  # at a knot
    np.testing.assert_array_equal(motion.placement(-4.0)[0], [0.0, 0.0, 0.0])  # held before
    np.testing.assert_array_equal(motion.placement(30.0)[0], [1.0, 2.0, 0.0])  # held after
    assert motion.period is None


def test_waypoints_single_point_is_static() -> None:
    motion = Waypoints([1.0], [[0.1, 0.2, 0.3]])
    np.testing.assert_array_equal(motion.positions(np.array([0.0, 1.0, 2.0])), [[0.1, 0.2, 0.3]] * 3)


def test_waypoints_loop_wraps() -> None:
    motion = Waypoints([1.0, 2.0, 4.0], [[0, 0, 0], [1, 0, 0], [1, 2, 0]], loop=True)
    assert motion.period == pytest.approx(3.0)
    np.testing.assert_allclose(motion.placement(1.5)[0], [0.5, 0.0, 0.0])
    np.testing.assert_allclose(motion.placement(4.5)[0], [0.5, 0.0, 0.0])  # one period later
    np.testing.assert_allclose(motion.placement(10.5)[0], [0.5, 0.0, 0.0])  # three periods
    np.testing.assert_allclose(motion.placement(0.0)[0], [1.0, 1.0, 0.0])  # before: 0 + 3 = 3
    np.testing.assert_allclose(motion.placement(-1.5)[0], [0.5, 0.0, 0.0])  # -1.5 + 2 * 3
    # at the end of a period it is back at the first waypoint (right-continuous wrap)
    np.testing.assert_array_equal(motion.placement(4.0)[0], [0.0, 0.0, 0.0])
    np.testing.assert_allclose(motion.placement(np.nextafter(4.0, 0.0))[0], [1.0, 2.0, 0.0])


def test_closed_loop_is_continuous_at_the_wrap() -> None:
    motion = Waypoints([0.0, 1.0, 2.0], [[0, 0, 0], [1, 0, 0], [0, 0, 0]], loop=True)
    times = np.linspace(-2.0, 6.0, 8001)
    jumps = np.linalg.norm(np.diff(motion.positions(times), axis=0), axis=1)
    assert jumps.max() < 2e-3


@pytest.mark.parametrize("motion", all_motions(), ids=lambda m: type(m).__name__)
def test_positions_equals_placement(motion: Motion) -> None:
    times = np.linspace(-2.0, 7.0, 37)
    batch = motion.positions(times)
    assert batch.shape == (37, 3)
    for i, t in enumerate(times):
        position, rotation = motion.placement(float(t))
        assert position.shape == (3,)
        assert rotation.shape == (3, 3)
        np.testing.assert_array_equal(position, batch[i])


@settings(max_examples=40, deadline=None)
@given(
    times=arrays(np.float64, st.integers(0, 15), elements=st.floats(-50.0, 50.0)),
    index=st.integers(0, 4),
)
def test_vectorised_equals_scalar_calls(times: NDArray[np.float64], index: int) -> None:
    motion = all_motions()[index]
    batch = motion.positions(times)
    assert batch.shape == (times.shape[0], 3)
    for i, t in enumerate(times):
        np.testing.assert_array_equal(motion.placement(float(t))[0], batch[i])


@pytest.mark.parametrize("motion", all_motions(), ids=lambda m: type(m).__name__)
def test_results_do_not_alias_state(motion: Motion) -> None:
    first_position, first_rotation = motion.placement(1.25)
    position, rotation = motion.placement(1.25)
    position[:] = 99.0
    rotation[:] = 99.0
    batch = motion.positions(np.array([1.25, 1.25]))
    batch[:] = 99.0
    again_position, again_rotation = motion.placement(1.25)
    np.testing.assert_array_equal(again_position, first_position)
    np.testing.assert_array_equal(again_rotation, first_rotation)


@pytest.mark.parametrize("motion", all_motions(), ids=lambda m: type(m).__name__)
def test_satisfies_protocol_and_fields_are_read_only(motion: Motion) -> None:
    assert isinstance(motion, Motion)
    rotation = motion.rotation  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match="read-only"):
        rotation[0, 0] = 2.0
    with pytest.raises(AttributeError):
        motion.rotation = np.eye(3)  # type: ignore[attr-defined]


def test_constructors_copy_their_inputs() -> None:
    position, velocity, rotation = np.array([1.0, 2.0, 3.0]), np.array([0.1, 0.0, 0.0]), rot_z(1)
    times, points = np.array([0.0, 1.0]), np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    inputs = [position, velocity, rotation, times, points]
    saved = copy.deepcopy(inputs)
    motions = [
        Static(position, rotation),
        ConstantVelocity(position, velocity, rotation),
        Waypoints(times, points, rotation),
        Periodic(position, velocity, 2.0, 0.0, rotation),
    ]
    for array in inputs:
        assert array.flags.writeable
        array[...] = 7.0
    np.testing.assert_array_equal(motions[0].placement(0.0)[0], saved[0])
    np.testing.assert_array_equal(motions[0].placement(0.0)[1], saved[2])
    np.testing.assert_allclose(motions[1].placement(1.0)[0], saved[0] + saved[1])
    np.testing.assert_array_equal(motions[2].placement(1.0)[0], saved[4][1])
    np.testing.assert_allclose(motions[3].placement(0.5)[0], saved[0] + saved[1])


def test_evaluation_does_not_mutate_times() -> None:
    times = np.array([3.0, -1.0, 0.5])
    saved = times.copy()
    for motion in all_motions():
        motion.positions(times)
    np.testing.assert_array_equal(times, saved)


def test_planar_vectors_are_padded() -> None:
    motion = ConstantVelocity([1.0, 2.0], [0.5, 0.5])
    np.testing.assert_allclose(motion.placement(2.0)[0], [2.0, 3.0, 0.0])
    waypoints = Waypoints([0.0, 1.0], [[0.0, 0.0], [1.0, 1.0]])
    np.testing.assert_allclose(waypoints.waypoints, [[0, 0, 0], [1, 1, 0]])
    assert Periodic([1.0, 1.0], [0.1, 0.0], 1.0).center.shape == (3,)


# ----------------------------------------------------------------------------- rotations


def test_rpy_to_matrix_matches_elementary_rotations() -> None:
    roll, pitch, yaw = 0.3, -0.7, 1.9
    expected = rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)
    np.testing.assert_allclose(rpy_to_matrix([roll, pitch, yaw]), expected, atol=1e-15)
    np.testing.assert_allclose(rpy_to_matrix([0.0, 0.0, np.pi / 2]) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(rpy_to_matrix([np.pi / 2, 0.0, 0.0]) @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(rpy_to_matrix([0.0, np.pi / 2, 0.0]) @ [0, 0, 1], [1, 0, 0], atol=1e-15)


@settings(max_examples=50, deadline=None)
@given(rpy=arrays(np.float64, (3,), elements=st.floats(-10.0, 10.0)))
def test_rpy_to_matrix_is_a_rotation(rpy: NDArray[np.float64]) -> None:
    matrix = rpy_to_matrix(rpy)
    np.testing.assert_allclose(matrix.T @ matrix, np.eye(3), atol=1e-12)
    assert np.linalg.det(matrix) == pytest.approx(1.0)
    Static([0.0, 0.0, 0.0], matrix)  # accepted as a rotation


@pytest.mark.parametrize(
    ("rpy", "fragments"),
    [([0.0, 1.0], ["rpy", "(2,)"]), ([0.0, np.nan, 0.0], ["rpy must be finite", "nan"])],
)
def test_rpy_to_matrix_rejects_bad_input(rpy: list[float], fragments: list[str]) -> None:
    with pytest.raises(SceneError) as info:
        rpy_to_matrix(rpy)
    for fragment in fragments:
        assert fragment in str(info.value)


# ----------------------------------------------------------------------------- constructor errors


@pytest.mark.parametrize(
    ("build", "fragments"),
    [
        (lambda: Static([1.0, 2.0, 3.0, 4.0]), ["position", "2 or 3 entries", "(4,)"]),
        (lambda: Static([1.0, np.nan]), ["position must be finite", "nan"]),
        (lambda: Static("abc"), ["position", "real numbers", "'abc'"]),
        (lambda: Static([0.0, 0.0, 0.0], np.diag([1.0, 1.0, -1.0])), ["rotation", "det = -1"]),
        (lambda: Static([0.0, 0.0, 0.0], 2 * np.eye(3)), ["rotation matrix", "2."]),
        (lambda: Static([0.0, 0.0, 0.0], np.eye(2)), ["rotation", "(3, 3)", "(2, 2)"]),
        (lambda: ConstantVelocity([0, 0, 0], [1, 2, 3, 4]), ["velocity", "(4,)"]),
        (lambda: ConstantVelocity([0, 0, 0], [1, 0, 0], start_time=np.inf), ["start_time", "inf"]),
        (
            lambda: Waypoints([0.0, 1.0, 1.0], [[0, 0]] * 3),
            ["strictly increasing", "times[2] = 1.0"],
        ),
        (lambda: Waypoints([1.0, 0.0], [[0, 0]] * 2), ["strictly increasing", "times[0] = 1.0"]),
        (lambda: Waypoints([], np.zeros((0, 3))), ["times", "K >= 1", "(0,)"]),
        (lambda: Waypoints([0.0, 1.0], [[0, 0, 0]]), ["one row per time", "1 rows for 2 times"]),
        (lambda: Waypoints([0.0], [[0, 0, 0]], loop=True), ["loop needs at least 2", "[0.]"]),
        (lambda: Waypoints([0.0, 1.0], [[0, 0]] * 2, loop="yes"), ["loop", "'yes'"]),
        (lambda: Waypoints([0.0, np.nan], [[0, 0]] * 2), ["times must be finite", "nan"]),
        (lambda: Periodic([0, 0, 0], [1, 0, 0], 0.0), ["period must be > 0", "0.0"]),
        (lambda: Periodic([0, 0, 0], [1, 0, 0], -3.0), ["period must be > 0", "-3.0"]),
        (lambda: Periodic([0, 0, 0], [1, 0, 0], 1.0, phase="x"), ["phase", "'x'"]),
    ],
)
def test_bad_constructor_arguments_raise_scene_error(build: object, fragments: list[str]) -> None:
    with pytest.raises(SceneError) as info:
        build()  # type: ignore[operator]
    for fragment in fragments:
        assert fragment in str(info.value)
    assert isinstance(info.value, ValueError)
    assert isinstance(info.value, PreviewctlError)


@pytest.mark.parametrize(("t", "fragments"), [(np.nan, ["t must be finite", "nan"]), ("1", ["t", "'1'"])])
def test_bad_placement_time_raises_scene_error(t: object, fragments: list[str]) -> None:
    for motion in all_motions():
        with pytest.raises(SceneError) as info:
            motion.placement(t)
        for fragment in fragments:
            assert fragment in str(info.value)


@pytest.mark.parametrize(
    ("times", "fragments"),
    [(np.zeros((2, 2)), ["(T,)", "(2, 2)"]), (np.array([0.0, np.inf]), ["finite", "inf"])],
)
def test_bad_positions_times_raise_scene_error(times: NDArray[np.float64], fragments: list[str]) -> None:
    for motion in all_motions():
        with pytest.raises(SceneError) as info:
            motion.positions(times)
        for fragment in fragments:
            assert fragment in str(info.value)


# ----------------------------------------------------------------------------- from tables


def test_from_dict_static() -> None:
    motion = motion_from_dict({"type": "static", "position": [0.3, 0.2, 0]}, WHERE)
    assert isinstance(motion, Static)
    np.testing.assert_array_equal(motion.placement(5.0)[0], [0.3, 0.2, 0.0])
    np.testing.assert_array_equal(motion.placement(5.0)[1], np.eye(3))


def test_from_dict_constant_velocity() -> None:
    spec = {"type": "constant_velocity", "position": [0, 1, 2], "velocity": [1, 0, -1]}
    motion = motion_from_dict(spec, WHERE)
    assert isinstance(motion, ConstantVelocity)
    np.testing.assert_allclose(motion.placement(2.0)[0], [2.0, 1.0, 0.0])
    delayed = motion_from_dict({**spec, "start_time": 1.0}, WHERE)
    np.testing.assert_allclose(delayed.placement(2.0)[0], [1.0, 1.0, 1.0])


def test_from_dict_waypoints() -> None:
    spec = {
        "type": "waypoints",
        "times": [0, 2],
        "positions": [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
        "loop": True,
    }
    motion = motion_from_dict(spec, WHERE)
    assert isinstance(motion, Waypoints)
    assert motion.loop
    np.testing.assert_allclose(motion.placement(1.0)[0], [1.0, 0.0, 0.0])
    np.testing.assert_allclose(motion.placement(3.0)[0], [1.0, 0.0, 0.0])
    held = motion_from_dict({k: v for k, v in spec.items() if k != "loop"}, WHERE)
    assert isinstance(held, Waypoints)
    assert not held.loop
    np.testing.assert_allclose(held.placement(3.0)[0], [2.0, 0.0, 0.0])


def test_from_dict_periodic() -> None:
    spec = {"type": "periodic", "center": [0.4, 0, 0.3], "amplitude": [0, 0.1, 0], "period": 4.0}
    motion = motion_from_dict(spec, WHERE)
    assert isinstance(motion, Periodic)
    np.testing.assert_allclose(motion.placement(1.0)[0], [0.4, 0.1, 0.3])
    shifted = motion_from_dict({**spec, "phase": np.pi / 2}, WHERE)
    np.testing.assert_allclose(shifted.placement(0.0)[0], [0.4, 0.1, 0.3])


@pytest.mark.parametrize("kind", MOTION_TYPES)
def test_from_dict_rpy_for_every_type(kind: str) -> None:
    specs: dict[str, dict[str, object]] = {
        "static": {"position": [0, 0, 0]},
        "constant_velocity": {"position": [0, 0, 0], "velocity": [1, 0, 0]},
        "waypoints": {"times": [0, 1], "positions": [[0, 0, 0], [1, 0, 0]]},
        "periodic": {"center": [0, 0, 0], "amplitude": [1, 0, 0], "period": 1.0},
    }
    rpy = [0.1, 0.2, 0.3]
    motion = motion_from_dict({"type": kind, **specs[kind], "rpy": rpy}, WHERE)
    np.testing.assert_allclose(motion.placement(0.0)[1], rpy_to_matrix(rpy))


def test_from_dict_planar_positions_are_padded() -> None:
    specs = [
        {"type": "static", "position": [0.3, 0.2]},
        {"type": "constant_velocity", "position": [0.3, 0.2], "velocity": [0.0, 0.0]},
        {"type": "waypoints", "times": [0.0, 1.0], "positions": [[0.3, 0.2], [0.3, 0.2]]},
        {"type": "periodic", "center": [0.3, 0.2], "amplitude": [0.0, 0.0], "period": 1.0},
    ]
    for spec in specs:
        np.testing.assert_array_equal(motion_from_dict(spec, WHERE).placement(0.5)[0], [0.3, 0.2, 0])


def test_from_dict_does_not_mutate_spec() -> None:
    spec = {
        "type": "waypoints",
        "times": [0.0, 1.0],
        "positions": [[0.0, 0.0], [1.0, 1.0]],
        "rpy": [0.0, 0.0, 1.0],
    }
    saved = copy.deepcopy(spec)
    motion = motion_from_dict(spec, WHERE)
    assert spec == saved
    spec["positions"][0][0] = 5.0  # type: ignore[index]
    np.testing.assert_array_equal(motion.placement(0.0)[0], [0.0, 0.0, 0.0])


@pytest.mark.parametrize(
    ("spec", "fragments"),
    [
        # unknown / missing type: lists the valid types
        (
            {"type": "teleport", "position": [0, 0, 0]},
            [f"{WHERE}.type = 'teleport' is not valid", "valid: static, constant_velocity, waypoints, periodic"],
        ),
        ({"position": [0, 0, 0]}, [f"{WHERE}.type is missing", "valid: static, constant_velocity"]),
        ({"type": 3}, [f"{WHERE}.type = 3 is not valid", "waypoints"]),
        ("static", [WHERE, "table", "'static'"]),
        # unknown key: names it and lists the valid keys for the type
        (
            {"type": "static", "position": [0, 0, 0], "velocity": [1, 0, 0]},
            [f"unknown key '{WHERE}.velocity'", f"valid keys in {WHERE} (type = 'static'): type, position, rpy"],
        ),
        (
            {
                "type": "periodic",
                "center": [0, 0, 0],
                "amplitude": [0, 0, 0],
                "period": 1,
                "frequency": 2,
            },
            [f"unknown key '{WHERE}.frequency'", "type, center, amplitude, period, phase, rpy"],
        ),
        # missing key
        (
            {"type": "constant_velocity", "position": [0, 0, 0]},
            [f"{WHERE}.velocity is missing", "position, velocity"],
        ),
        # wrong type of value
        ({"type": "static", "position": "abc"}, [f"{WHERE}.position", "'abc'", "2 or 3 numbers"]),
        ({"type": "static", "position": 0.5}, [f"{WHERE}.position", "0.5"]),
        ({"type": "static", "position": [0, 0, 0, 0]}, [f"{WHERE}.position", "[0, 0, 0, 0]"]),
        ({"type": "static", "position": [0, "1", 0]}, [f"{WHERE}.position[1] must be a finite number", "'1'"]),
        ({"type": "static", "position": [True, 0]}, [f"{WHERE}.position[0] must be a finite number", "True"]),
        ({"type": "static", "position": [0, float("nan")]}, [f"{WHERE}.position", "finite", "nan"]),
        ({"type": "static", "position": [0, 0], "rpy": [0, 0]}, [f"{WHERE}.rpy must have 3 entries", "[0, 0]"]),
        ({"type": "static", "position": [0, 0], "rpy": "up"}, [f"{WHERE}.rpy", "'up'"]),
        (
            {
                "type": "constant_velocity",
                "position": [0, 0],
                "velocity": [0, 0],
                "start_time": "now",
            },
            [f"{WHERE}.start_time", "'now'"],
        ),
        (
            {"type": "waypoints", "times": "0 1", "positions": [[0, 0], [1, 1]]},
            [f"{WHERE}.times", "'0 1'"],
        ),
        (
            {"type": "waypoints", "times": [0, 1], "positions": [[0, 0], "b"]},
            [f"{WHERE}.positions[1]", "'b'"],
        ),
        (
            {"type": "waypoints", "times": [0, 1], "positions": [[0, 0], [1, 1]], "loop": "yes"},
            [f"{WHERE}.loop", "'yes'", "true or false"],
        ),
        (
            {"type": "waypoints", "times": [0, 1], "positions": [[0, 0], [1, 1]], "loop": 1},
            [f"{WHERE}.loop", "1"],
        ),
        (
            {"type": "periodic", "center": [0, 0], "amplitude": [0, 0], "period": "4s"},
            [f"{WHERE}.period", "'4s'"],
        ),
        # invalid values
        (
            {"type": "periodic", "center": [0, 0], "amplitude": [0, 0], "period": 0},
            [f"{WHERE}.period must be > 0", "0.0"],
        ),
        (
            {"type": "waypoints", "times": [0, 2, 1], "positions": [[0, 0]] * 3},
            [f"{WHERE}.times must be strictly increasing", "times[1] = 2.0", "times[2] = 1.0"],
        ),
        (
            {"type": "waypoints", "times": [0, 1, 2], "positions": [[0, 0]] * 2},
            [f"{WHERE}.positions", "2 positions for 3 times"],
        ),
        (
            {"type": "waypoints", "times": [0], "positions": [[0, 0]], "loop": True},
            [f"{WHERE}.loop needs at least 2 times"],
        ),
    ],
)
def test_from_dict_errors(spec: object, fragments: list[str]) -> None:
    with pytest.raises(SceneError) as info:
        motion_from_dict(spec, WHERE)
    message = str(info.value)
    for fragment in fragments:
        assert fragment in message, message
