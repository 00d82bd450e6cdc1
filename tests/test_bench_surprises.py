"""Tests of :mod:`previewctl.bench.surprises` and of surprise scenes (``SceneSettings(motions="surprise")``)."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from previewctl.bench.runs import settings_hash
from previewctl.bench.scenes import generate
from previewctl.bench.settings import SceneSettings
from previewctl.bench.surprises import SURPRISES, surprise
from previewctl.errors import ParameterError
from previewctl.scene.file import motion_from_dict
from previewctl.scene.motion import ConstantVelocity, RandomWalk

START, VELOCITY, POINT = np.array([1.0, 1.5, 0.0]), np.array([-0.2, -0.1, 0.0]), np.array([0.4, 1.2, 0.0])
"""A straight crossing: at POINT at t = 3 s."""


def _draws(count: int, dims: int) -> list[dict[str, object]]:
    rng = np.random.default_rng(5)
    start, velocity = START.copy(), VELOCITY.copy()
    if dims == 3:
        start[2], velocity[2] = 0.3, 0.05
    return [surprise(rng, start, velocity, start + 3.0 * velocity, 3.0, 0.1, 8.0, dims) for _ in range(count)]


@pytest.mark.parametrize("dims", [2, 3])
def test_every_surprise_is_drawn_and_starts_as_the_straight_crossing(dims: int) -> None:
    tables = _draws(80, dims)
    assert set(Counter(t["type"] for t in tables)) == set(SURPRISES)
    for table in tables:
        motion = motion_from_dict(table, "motion")
        straight = ConstantVelocity(table["position"], table["velocity"])
        early = np.linspace(0.0, 0.4, 5) if table["type"] != "random_walk" else np.array([0.0, 1e-6])
        # every surprise happens after 0.5 s; a walk starts with the crossing's velocity, then wanders at once
        np.testing.assert_allclose(motion.positions(early), straight.positions(early), rtol=0.0, atol=1e-9)
        late = motion.positions(np.array([3.0, 6.0]))
        assert np.linalg.norm(late - straight.positions(np.array([3.0, 6.0]))) > 1e-3  # the prediction is wrong
        if dims == 2:
            np.testing.assert_array_equal(late[:, 2], 0.0)


def test_a_surprise_is_the_same_for_the_same_generator_state() -> None:
    assert _draws(10, 3) == _draws(10, 3)


def test_a_random_walk_surprise_keeps_to_a_box_around_the_crossing() -> None:
    walk = next(t for t in _draws(40, 2) if t["type"] == "random_walk")
    motion = motion_from_dict(walk, "motion")
    assert isinstance(motion, RandomWalk)
    np.testing.assert_allclose(motion.center, POINT)
    np.testing.assert_allclose(motion.half_size[:2], np.maximum(1.25 * np.abs(START - POINT), 0.4)[:2])
    path = motion.positions(np.linspace(0.0, 20.0, 2001))
    assert np.all(np.abs(path - POINT) <= motion.half_size + 1e-12)


def test_surprise_scenes_are_deterministic_and_keep_the_constant_scenes_hash() -> None:
    settings = SceneSettings(duration=4.0, motions="surprise")
    scene = generate("planar4", 0, 0, settings)
    assert generate("planar4", 0, 0, settings).document == scene.document
    assert {o["motion"]["type"] for o in scene.document["obstacles"]} <= set(SURPRISES)
    assert "(surprise)" in scene.document["description"]
    assert settings_hash("planar4", 0, settings) != settings_hash("planar4", 0, SceneSettings(duration=4.0))
    # results recorded before surprise scenes existed keep their key: the default settings hash as then
    assert settings_hash("planar4", 0, SceneSettings()) == "cdae7f6ae12f"


def test_scene_settings_name_a_bad_motion_kind() -> None:
    with pytest.raises(ParameterError, match=r"motions = 'wild' is not valid; valid: constant, surprise"):
        SceneSettings(motions="wild")  # type: ignore[arg-type]
