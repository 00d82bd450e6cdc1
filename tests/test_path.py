"""Tests of :mod:`previewctl.path`: constant-speed piecewise-linear hand paths."""

# The constructors accept any array-like (lists included); some tests pass bad types on purpose.
# mypy: disable-error-code="arg-type"

from __future__ import annotations

import numpy as np
import pytest
from helpers import rot_z
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from numpy.typing import NDArray

from previewctl.errors import PreviewctlError, TrajectoryError
from previewctl.path import HandPath

L_SHAPE = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 4.0]])  # lengths 3 and 4, total 7 [m]
SPATIAL = np.array([[0.1, 0.2, 0.3], [0.4, 0.2, 0.3], [0.4, -0.2, 0.5], [0.0, 0.0, 0.0]])


# ----------------------------------------------------------------------------- construction


def test_properties_of_l_shaped_path() -> None:
    path = HandPath(L_SHAPE, duration=14.0, start_time=1.0)
    assert path.dim == 2
    assert path.length == pytest.approx(7.0)
    assert path.speed == pytest.approx(0.5)
    assert path.end_time == pytest.approx(15.0)
    np.testing.assert_allclose(path.waypoint_times(), [1.0, 7.0, 15.0])


def test_speed_is_length_over_duration_in_3d() -> None:
    path = HandPath(SPATIAL, duration=2.5)
    seg = np.linalg.norm(np.diff(SPATIAL, axis=0), axis=1)
    assert path.dim == 3
    assert path.length == pytest.approx(seg.sum())
    assert path.speed == pytest.approx(seg.sum() / 2.5)
    assert path.start_time == 0.0
    assert path.orientation is None


def test_fields_are_read_only_copies() -> None:
    points = L_SHAPE.copy()
    rotation = rot_z(0.3)
    path = HandPath(points, 1.0, orientation=rotation)
    points[0, 0] = 99.0
    rotation[0, 0] = 99.0
    assert path.waypoints[0, 0] == 0.0
    assert path.orientation is not None
    assert path.orientation[0, 0] == pytest.approx(np.cos(0.3))
    with pytest.raises(ValueError, match="read-only"):
        path.waypoints[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        path.orientation[0, 0] = 1.0


def test_dataclass_is_frozen() -> None:
    path = HandPath(L_SHAPE, 1.0)
    with pytest.raises(AttributeError):
        path.duration = 2.0  # type: ignore[misc]


def test_accepts_lists_and_ints() -> None:
    path = HandPath([[0, 0, 0], [1, 0, 0]], 2)
    assert path.waypoints.dtype == np.float64
    assert isinstance(path.duration, float)
    np.testing.assert_allclose(path.position(1.0), [0.5, 0.0, 0.0])


# ----------------------------------------------------------------------------- evaluation


@pytest.mark.parametrize("points", [L_SHAPE, SPATIAL])
def test_positions_at_waypoint_times_equal_waypoints(points: NDArray[np.float64]) -> None:
    path = HandPath(points, duration=3.0, start_time=-0.5)
    times = path.waypoint_times()
    np.testing.assert_allclose(path.position(times), points, atol=1e-12)
    for time, point in zip(times, points, strict=True):
        np.testing.assert_allclose(path.position(float(time)), point, atol=1e-12)


def test_position_inside_segments_is_linear() -> None:
    path = HandPath(L_SHAPE, duration=7.0)  # speed 1 m/s
    np.testing.assert_allclose(path.position(1.5), [1.5, 0.0])
    np.testing.assert_allclose(path.position(5.0), [3.0, 2.0])


def test_holds_before_start_and_after_end() -> None:
    path = HandPath(SPATIAL, duration=2.0, start_time=1.0)
    before = np.array([-1e9, -3.0, 0.0, 0.999])
    after = np.array([3.0, 3.5, 1e9])
    np.testing.assert_array_equal(path.position(before), np.tile(SPATIAL[0], (4, 1)))
    np.testing.assert_array_equal(path.position(after), np.tile(SPATIAL[-1], (3, 1)))
    np.testing.assert_array_equal(path.velocity(before), np.zeros((4, 3)))
    np.testing.assert_array_equal(path.velocity(after), np.zeros((3, 3)))


def test_velocity_is_right_continuous_at_waypoints_and_ends() -> None:
    path = HandPath(L_SHAPE, duration=14.0, start_time=1.0)  # speed 0.5
    start, corner, end = path.waypoint_times()
    np.testing.assert_allclose(path.velocity(start), [0.5, 0.0])  # following segment
    np.testing.assert_allclose(path.velocity(corner), [0.0, 0.5])  # following segment
    np.testing.assert_array_equal(path.velocity(end), [0.0, 0.0])  # already at rest
    np.testing.assert_allclose(path.velocity(np.nextafter(corner, 0.0)), [0.5, 0.0])
    np.testing.assert_allclose(path.velocity(np.nextafter(end, 0.0)), [0.0, 0.5])


@pytest.mark.parametrize("points", [L_SHAPE, SPATIAL])
def test_velocity_matches_finite_differences_away_from_corners(
    points: NDArray[np.float64],
) -> None:
    path = HandPath(points, duration=2.0, start_time=0.3)
    corners = path.waypoint_times()
    h = 1e-6
    times = np.linspace(path.start_time - 0.5, path.end_time + 0.5, 401)
    times = times[np.min(np.abs(times[:, None] - corners[None, :]), axis=1) > 10 * h]
    numeric = (path.position(times + h) - path.position(times - h)) / (2 * h)
    np.testing.assert_allclose(path.velocity(times), numeric, atol=1e-6)


def test_speed_is_constant_inside_the_path() -> None:
    path = HandPath(SPATIAL, duration=2.0, start_time=0.3)
    times = np.linspace(path.start_time, path.end_time, 200, endpoint=False)
    speeds = np.linalg.norm(path.velocity(times), axis=1)
    np.testing.assert_allclose(speeds, path.length / path.duration)


def test_travelled_length_over_duration_is_the_speed() -> None:
    path = HandPath(SPATIAL, duration=2.0, start_time=0.3)
    samples = path.position(np.linspace(path.start_time, path.end_time, 2001))
    # Sampling hits each corner only approximately, so the chord sum is slightly short.
    travelled = np.linalg.norm(np.diff(samples, axis=0), axis=1).sum()
    assert travelled == pytest.approx(path.length, rel=1e-3)
    assert travelled / path.duration == pytest.approx(path.speed, rel=1e-3)


def test_time_on_each_segment_is_proportional_to_its_length() -> None:
    path = HandPath(SPATIAL, duration=5.0)
    seg = np.linalg.norm(np.diff(SPATIAL, axis=0), axis=1)
    np.testing.assert_allclose(np.diff(path.waypoint_times()), 5.0 * seg / seg.sum())


def test_repeated_waypoint_is_passed_in_zero_time() -> None:
    points = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    path = HandPath(points, duration=2.0)
    times = path.waypoint_times()
    np.testing.assert_allclose(times, [0.0, 1.0, 1.0, 2.0])
    np.testing.assert_allclose(path.velocity(1.0), [0.0, 1.0])
    np.testing.assert_allclose(path.position(1.5), [1.0, 0.5])


def test_scalar_and_array_shapes() -> None:
    path = HandPath(SPATIAL, duration=2.0)
    assert path.position(0.5).shape == (3,)
    assert path.velocity(0.5).shape == (3,)
    assert path.position(np.float64(0.5)).shape == (3,)
    assert path.position(np.array(0.5)).shape == (3,)
    assert path.position(np.array([0.5])).shape == (1, 3)
    assert path.position(np.array([])).shape == (0, 3)
    assert path.velocity(np.linspace(0, 1, 7)).shape == (7, 3)


@settings(max_examples=50, deadline=None)
@given(
    times=arrays(np.float64, st.integers(1, 20), elements=st.floats(-3.0, 6.0, allow_nan=False)),
)
def test_vectorised_equals_scalar_calls(times: NDArray[np.float64]) -> None:
    path = HandPath(SPATIAL, duration=2.0, start_time=0.5)
    positions = path.position(times)
    velocities = path.velocity(times)
    for i, time in enumerate(times):
        np.testing.assert_array_equal(positions[i], path.position(float(time)))
        np.testing.assert_array_equal(velocities[i], path.velocity(float(time)))


def test_one_time_equals_the_array_path_at_waypoints_ends_and_one_ulp_around() -> None:
    """A single float takes a scalar shortcut (bisect, no arrays): bit-identical to the array path where
    segments meet, at the ends, and on a zero-length segment."""
    path = HandPath(np.vstack([SPATIAL, SPATIAL[-1:]]), duration=2.0, start_time=0.5)
    knots = path.waypoint_times()
    times = np.concatenate([knots, np.nextafter(knots, -np.inf), np.nextafter(knots, np.inf), [-1.0, 9.0]])
    for time in times:
        np.testing.assert_array_equal(path.position(np.array([time]))[0], path.position(float(time)))
        np.testing.assert_array_equal(path.velocity(np.array([time]))[0], path.velocity(float(time)))


@settings(max_examples=50, deadline=None)
@given(
    points=arrays(np.float64, (4, 3), elements=st.floats(-2.0, 2.0, allow_nan=False)),
    duration=st.floats(0.1, 10.0),
    start=st.floats(-5.0, 5.0),
)
def test_random_paths_pass_their_waypoints_at_constant_speed(
    points: NDArray[np.float64], duration: float, start: float
) -> None:
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    if seg.sum() < 1e-3:
        return
    path = HandPath(points, duration, start_time=start)
    np.testing.assert_allclose(path.position(path.waypoint_times()), points, atol=1e-9)
    inside = np.linspace(path.start_time, path.end_time, 50, endpoint=False)
    speeds = np.linalg.norm(path.velocity(inside), axis=1)
    np.testing.assert_allclose(speeds, seg.sum() / duration, rtol=1e-9)


def test_evaluation_does_not_mutate_input_or_alias_state() -> None:
    path = HandPath(L_SHAPE, duration=7.0)
    times = np.array([-1.0, 0.0, 1.0, 10.0])
    times_before = times.copy()
    out = path.position(times)
    np.testing.assert_array_equal(times, times_before)
    out[:] = 42.0  # results are fresh and writable
    np.testing.assert_array_equal(path.waypoints, L_SHAPE)
    first = path.position(-1.0)
    first[:] = 42.0
    np.testing.assert_array_equal(path.waypoints, L_SHAPE)
    wp_times = path.waypoint_times()
    wp_times[:] = 0.0
    np.testing.assert_allclose(path.waypoint_times(), [0.0, 3.0, 7.0])


def test_orientation_is_kept() -> None:
    rotation = rot_z(1.2)
    path = HandPath(SPATIAL, duration=1.0, orientation=rotation)
    assert path.orientation is not None
    np.testing.assert_allclose(path.orientation, rotation)


# ----------------------------------------------------------------------------- errors


@pytest.mark.parametrize(
    ("kwargs", "fragments"),
    [
        ({"waypoints": [[0.0, 0.0]], "duration": 1.0}, ["at least 2 points", "got 1"]),
        ({"waypoints": [0.0, 1.0, 2.0], "duration": 1.0}, ["(K, 2) or (K, 3)", "(3,)"]),
        ({"waypoints": np.zeros((3, 4)), "duration": 1.0}, ["(K, 2) or (K, 3)", "(3, 4)"]),
        ({"waypoints": [[0.0, 0.0], [0.0, np.nan]], "duration": 1.0}, ["finite", "[1, 1]", "nan"]),
        ({"waypoints": [[0.0, 0.0], [np.inf, 0.0]], "duration": 1.0}, ["finite", "inf"]),
        ({"waypoints": [[1.0, 2.0], [1.0, 2.0]], "duration": 1.0}, ["total length is 0", "1., 2."]),
        ({"waypoints": [["a", "b"], ["c", "d"]], "duration": 1.0}, ["real numbers", "'a'"]),
        ({"waypoints": [[0.0, 0.0], [1.0]], "duration": 1.0}, ["real numbers", "[1.0]"]),
        ({"waypoints": "abc", "duration": 1.0}, ["real numbers", "'abc'"]),
        ({"waypoints": L_SHAPE, "duration": 0.0}, ["duration must be > 0", "0.0"]),
        ({"waypoints": L_SHAPE, "duration": -2.5}, ["duration must be > 0", "-2.5"]),
        ({"waypoints": L_SHAPE, "duration": np.nan}, ["duration must be finite", "nan"]),
        ({"waypoints": L_SHAPE, "duration": "2"}, ["duration must be a real number", "'2'"]),
        ({"waypoints": L_SHAPE, "duration": True}, ["duration must be a real number", "True"]),
        (
            {"waypoints": L_SHAPE, "duration": 1.0, "start_time": np.inf},
            ["start_time must be finite", "inf"],
        ),
        (
            {"waypoints": L_SHAPE, "duration": 1e-20, "start_time": 1e10},
            ["lost to rounding", "1e-20"],
        ),
    ],
)
def test_bad_construction_raises_trajectory_error(kwargs: dict[str, object], fragments: list[str]) -> None:
    with pytest.raises(TrajectoryError) as info:
        HandPath(**kwargs)
    for fragment in fragments:
        assert fragment in str(info.value)
    assert isinstance(info.value, ValueError)
    assert isinstance(info.value, PreviewctlError)


@pytest.mark.parametrize(
    ("orientation", "fragments"),
    [
        (np.eye(2), ["(3, 3)", "(2, 2)"]),
        (np.diag([1.0, 1.0, -1.0]), ["rotation matrix", "det = -1", "-1."]),
        (2.0 * np.eye(3), ["rotation matrix", "2."]),
        (rot_z(0.1) + 1e-3, ["rotation matrix", "max|R^T R - I|"]),
        (np.full((3, 3), np.nan), ["orientation must be finite", "nan"]),
    ],
)
def test_bad_orientation_raises_trajectory_error(orientation: NDArray[np.float64], fragments: list[str]) -> None:
    with pytest.raises(TrajectoryError) as info:
        HandPath(L_SHAPE, 1.0, orientation=orientation)
    for fragment in fragments:
        assert fragment in str(info.value)


def test_orientation_within_tolerance_is_accepted() -> None:
    HandPath(L_SHAPE, 1.0, orientation=rot_z(0.4) + 1e-9)


@pytest.mark.parametrize(
    ("t", "fragments"),
    [
        (np.nan, ["t must be finite", "nan"]),
        (np.array([0.0, np.inf]), ["t must be finite", "[1]", "inf"]),
        (np.zeros((2, 2)), ["shape (T,)", "(2, 2)"]),
        ("1.0", ["real numbers", "'1.0'"]),
    ],
)
def test_bad_time_raises_trajectory_error(t: object, fragments: list[str]) -> None:
    path = HandPath(L_SHAPE, 1.0)
    for method in (path.position, path.velocity):
        with pytest.raises(TrajectoryError) as info:
            method(t)
        for fragment in fragments:
            assert fragment in str(info.value)
