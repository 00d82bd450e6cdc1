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
    RandomWalk,
    SpeedChange,
    Static,
    Turn,
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
        Turn([0.0, 1.0, 0.0], [0.3, 0.0, 0.1], 1.5, 2.0, 1.0, [0.0, 0.0, 1.0], rotation),
        SpeedChange([0.0, 1.0, 0.0], [0.3, 0.0, 0.1], 1.0, 0.0, 0.5, rotation),
        RandomWalk([0.1, 0.0, 0.0], [0.0, 0.0, 0.0], [0.5, 0.5, 0.2], 0.2, 7, duration=10.0, rotation=rotation),
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


def test_constant_velocity_started_before_the_run_is_at_its_position_at_zero() -> None:
    velocity = np.array([0.5, -1.0, 0.25])
    moving = ConstantVelocity([1.0, 2.0, 3.0], velocity, start_time=-4.0)
    times = np.array([-10.0, -4.0, -1.5, 0.0, 0.7, 3.0])
    expected = [1.0, 2.0, 3.0] + np.maximum(times, -4.0)[:, None] * velocity  # moving since -4 s, held before
    np.testing.assert_allclose(moving.positions(times), expected, rtol=0, atol=1e-15)
    # from t = 0 on, exactly the bits of the motion that starts at 0 (which holds before)
    at_zero = ConstantVelocity([1.0, 2.0, 3.0], velocity)
    after = np.linspace(0.0, 9.0, 37)
    np.testing.assert_array_equal(moving.positions(after), at_zero.positions(after))
    np.testing.assert_array_equal(at_zero.positions(np.array([-3.0])), [[1.0, 2.0, 3.0]])


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
    index=st.integers(0, len(all_motions()) - 1),
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
        "turn": {"position": [0, 0, 0], "velocity": [1, 0, 0], "turn_time": 1.0, "angle": 1.0},
        "stop": {"position": [0, 0, 0], "velocity": [1, 0, 0], "stop_time": 1.0},
        "speed_change": {"position": [0, 0, 0], "velocity": [1, 0, 0], "change_time": 1.0, "factor": 2.0},
        "random_walk": {"position": [0, 0, 0], "center": [0, 0, 0], "half_size": [1, 1, 1], "speed": 0.1,
                        "seed": 0},
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


# ----------------------------------------------------------------------------- motions a predictor does not know


def test_turn_at_once_closed_form() -> None:
    motion = Turn([1.0, 2.0], [0.5, 0.0], turn_time=2.0, angle=np.pi / 2)
    np.testing.assert_allclose(motion.positions(np.array([-1.0, 1.0, 2.0, 4.0])),
                               [[0.5, 2.0, 0.0], [1.5, 2.0, 0.0], [2.0, 2.0, 0.0], [2.0, 3.0, 0.0]], atol=1e-12)
    assert motion.duration == 0.0


def test_turn_at_a_rate_is_a_circular_arc() -> None:
    # a quarter turn at pi/2 rad/s of a 1 m/s velocity: an arc of radius 1/(pi/2) m, then straight up
    motion = Turn([0.0, 0.0], [1.0, 0.0], turn_time=1.0, angle=np.pi / 2, rate=np.pi / 2)
    radius = 2.0 / np.pi
    assert motion.duration == pytest.approx(1.0)
    arc = motion.positions(1.0 + np.linspace(0.0, 1.0, 11))
    centre = np.array([1.0, radius, 0.0])
    np.testing.assert_allclose(np.linalg.norm(arc - centre, axis=1), radius, atol=1e-12)
    np.testing.assert_allclose(motion.placement(3.0)[0], [1.0 + radius, radius + 1.0, 0.0], atol=1e-12)


def test_turn_keeps_the_velocity_along_its_axis_and_turns_clockwise_for_a_negative_angle() -> None:
    motion = Turn([0.0, 0.0, 0.0], [1.0, 0.0, 0.5], turn_time=0.0, angle=-np.pi, rate=np.pi)
    # half a turn about z in 1 s: x back to 0 on the arc's far side (y < 0), z climbs at 0.5 m/s throughout
    np.testing.assert_allclose(motion.placement(1.0)[0], [0.0, -2.0 / np.pi, 0.5], atol=1e-12)
    np.testing.assert_allclose(motion.placement(2.0)[0], [-1.0, -2.0 / np.pi, 1.0], atol=1e-12)


@pytest.mark.parametrize("rate", [None, 0.8])
def test_turn_velocity_matches_finite_differences(rate: float | None) -> None:
    motion = Turn([0.0, 0.0, 0.0], [0.3, 0.1, 0.2], turn_time=1.0, angle=2.0, rate=rate, axis=[1.0, 1.0, 2.0])
    times = np.linspace(0.0, 6.0, 6001)
    speeds = np.linalg.norm(np.diff(motion.positions(times), axis=0), axis=1) / np.diff(times)
    np.testing.assert_allclose(speeds, np.linalg.norm([0.3, 0.1, 0.2]), rtol=1e-6)  # a turn keeps the speed


def test_speed_change_closed_form_stop_and_speed_up() -> None:
    stop = SpeedChange([0.0, 0.0], [1.0, 0.0], change_time=1.0, factor=0.0, ramp_time=2.0)
    np.testing.assert_allclose(stop.positions(np.array([1.0, 2.0, 3.0, 10.0]))[:, 0], [1.0, 1.75, 2.0, 2.0])
    jump = SpeedChange([0.0, 0.0], [0.0, 0.2], change_time=2.0, factor=3.0)
    np.testing.assert_allclose(jump.positions(np.array([2.0, 4.0]))[:, 1], [0.4, 0.4 + 1.2])


@pytest.mark.parametrize("motion", [
    Turn([0.1, 0.2], [0.3, -0.1], turn_time=1.0, angle=1.2, rate=0.8),
    SpeedChange([0.1, 0.2], [0.3, -0.1], change_time=1.0, factor=0.0, ramp_time=0.5),
])
def test_surprises_come_in_straight_before_zero(motion: Motion) -> None:
    before = np.array([-5.0, -1.0, -0.25])
    np.testing.assert_allclose(motion.positions(before), [0.1, 0.2, 0.0] + before[:, None] * [0.3, -0.1, 0.0],
                               rtol=0, atol=1e-15)
    np.testing.assert_array_equal(motion.positions(np.array([0.0]))[0], [0.1, 0.2, 0.0])


def test_speed_change_is_continuous_with_a_ramp() -> None:
    motion = SpeedChange([0.0, 0.0], [1.0, 1.0], change_time=1.0, factor=2.5, ramp_time=0.5)
    times = np.linspace(0.0, 3.0, 30001)
    velocity = np.diff(motion.positions(times)[:, 0]) / np.diff(times)
    assert np.abs(np.diff(velocity)).max() < 1e-3  # the speed changes smoothly, not by a jump
    np.testing.assert_allclose(velocity[[0, -1]], [1.0, 2.5], rtol=1e-6)


def test_random_walk_stays_in_its_box_and_is_smooth() -> None:
    motion = RandomWalk([0.3, 0.0], [0.2, 0.1], [0.4, 0.3], speed=0.5, seed=3, velocity=[0.2, 0.0], duration=30.0)
    times = np.linspace(-1.0, 40.0, 41001)
    path = motion.positions(times)
    np.testing.assert_allclose(path[times == 0.0][0], [0.3, 0.0, 0.0])
    assert np.all(np.abs(path[:, :2] - [0.2, 0.1]) <= [0.4, 0.3])
    np.testing.assert_array_equal(path[:, 2], 0.0)
    walking = times <= 30.0  # it comes in with its start velocity before 0, and holds its end after 30 s
    velocity = np.diff(path[walking], axis=0) / 1e-3
    assert np.abs(velocity).max() < 5 * 0.5  # no jump: a few standard deviations of the walk's speed
    acceleration = np.diff(velocity, axis=0) / 1e-3
    assert np.abs(acceleration).max() < 100.0  # velocity continuous (a jump would give ~ 1e3 m/s^2)
    assert np.ptp(path[:, 0]) > 0.4  # it walks
    np.testing.assert_array_equal(path[times >= 30.0], np.tile(path[-1], ((times >= 30.0).sum(), 1)))


def test_random_walk_starts_with_its_velocity() -> None:
    motion = RandomWalk([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 1.0, 1.0], speed=0.3, seed=0,
                        velocity=[0.2, -0.1, 0.05], step=0.01)
    dt = 1e-6
    np.testing.assert_allclose((motion.placement(dt)[0] - motion.placement(0.0)[0]) / dt, [0.2, -0.1, 0.05],
                               rtol=1e-3)
    np.testing.assert_allclose((motion.placement(0.0)[0] - motion.placement(-dt)[0]) / dt, [0.2, -0.1, 0.05],
                               rtol=1e-3)  # and came in with it


def test_random_walk_replays_for_a_seed() -> None:
    times = np.linspace(0.0, 20.0, 101)
    walks = [RandomWalk([0.0, 0.0], [0.0, 0.0], [0.5, 0.5], 0.2, seed).positions(times) for seed in (4, 4, 5)]
    np.testing.assert_array_equal(walks[0], walks[1])
    assert np.abs(walks[0] - walks[2]).max() > 0.05


@pytest.mark.parametrize(
    ("build", "fragments"),
    [
        (lambda: Turn([0, 0], [1, 0], -1.0, 1.0), ["turn_time must be >= 0 [s]", "-1.0"]),
        (lambda: Turn([0, 0], [1, 0], 1.0, np.nan), ["angle must be finite", "nan"]),
        (lambda: Turn([0, 0], [1, 0], 1.0, 1.0, rate=0.0), ["rate must be > 0 [rad/s]", "0.0"]),
        (lambda: Turn([0, 0], [1, 0], 1.0, 1.0, axis=[0, 0, 0]), ["axis must be 3 finite numbers", "not all 0"]),
        (lambda: Turn([0, 0], [1, 0], 1.0, 1.0, axis=[0, 1]), ["axis must be 3 finite numbers", "[0., 1.]"]),
        (lambda: SpeedChange([0, 0], [1, 0], 1.0, -2.0), ["factor must be >= 0", "-2.0"]),
        (lambda: SpeedChange([0, 0], [1, 0], 1.0, 1.0, ramp_time=-1), ["ramp_time must be >= 0 [s]", "-1"]),
        (lambda: RandomWalk([0, 0], [0, 0], [0.5, -0.1], 0.1, 0), ["half_size must be >= 0", "-0.1"]),
        (lambda: RandomWalk([0.6, 0], [0, 0], [0.5, 0.5], 0.1, 0),
         ["position [0.6,", "strictly inside", "half_size [0.5, 0.5"]),
        (lambda: RandomWalk([0, 0], [0, 0], [0.5, 0.5], -0.1, 0), ["speed must be >= 0 [m/s]", "-0.1"]),
        (lambda: RandomWalk([0, 0], [0, 0], [0.5, 0.5], 0.1, -3), ["seed must be an integer >= 0", "-3"]),
        (lambda: RandomWalk([0, 0], [0, 0], [0.5, 0.5], 0.1, 1.5), ["seed must be an integer >= 0", "1.5"]),
        (lambda: RandomWalk([0, 0], [0, 0], [0.5, 0.5], 0.1, 0, step=0.0), ["step must be > 0 [s]", "0.0"]),
        (lambda: RandomWalk([0, 0], [0, 0], [0.5, 0.5], 0.1, 0, duration=1e6, step=1e-3),
         ["more than 1,000,000", "valid: a longer step"]),
    ],
)
def test_bad_surprise_motions_raise_scene_error(build: object, fragments: list[str]) -> None:
    with pytest.raises(SceneError) as info:
        build()  # type: ignore[operator]
    for fragment in fragments:
        assert fragment in str(info.value), str(info.value)


def test_from_dict_surprise_motions() -> None:
    stop = motion_from_dict({"type": "stop", "position": [0, 0], "velocity": [1, 0], "stop_time": 1.0,
                             "braking_time": 2.0}, WHERE)
    np.testing.assert_allclose(stop.placement(5.0)[0], [2.0, 0.0, 0.0])
    turn = motion_from_dict({"type": "turn", "position": [0, 0], "velocity": [1, 0], "turn_time": 1.0,
                             "angle": np.pi / 2}, WHERE)
    np.testing.assert_allclose(turn.placement(2.0)[0], [1.0, 1.0, 0.0], atol=1e-12)
    walk = {"type": "random_walk", "position": [0, 0], "center": [0, 0], "half_size": [1, 1], "speed": 0.2,
            "seed": 9}
    times = np.linspace(0.0, 10.0, 51)
    np.testing.assert_array_equal(motion_from_dict(walk, WHERE).positions(times),
                                  RandomWalk([0, 0], [0, 0], [1, 1], 0.2, 9).positions(times))


@pytest.mark.parametrize(
    ("spec", "fragments"),
    [
        ({"type": "stop", "position": [0, 0], "velocity": [1, 0], "stop_time": -1},
         [f"{WHERE}.stop_time must be >= 0", "-1"]),
        ({"type": "turn", "position": [0, 0], "velocity": [1, 0], "turn_time": 1, "angle": 1, "rate": 0},
         [f"{WHERE}.rate must be > 0", "0"]),
        ({"type": "random_walk", "position": [0, 0], "center": [0, 0], "half_size": [1, 1], "speed": 0.2,
          "seed": "a"}, [f"{WHERE}.seed", "'a'"]),
        ({"type": "random_walk", "position": [2, 0], "center": [0, 0], "half_size": [1, 1], "speed": 0.2,
          "seed": 1}, [f"{WHERE}.position [2.,", "must be strictly inside"]),
    ],
)
def test_from_dict_surprise_errors(spec: object, fragments: list[str]) -> None:
    with pytest.raises(SceneError) as info:
        motion_from_dict(spec, WHERE)
    for fragment in fragments:
        assert fragment in str(info.value), str(info.value)
