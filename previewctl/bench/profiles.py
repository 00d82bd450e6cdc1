"""How the scenes of a robot are drawn: the hand-written :class:`Profile` of planar4, the Panda and the xArm7, and
the profile :func:`derived_profile` makes from any other arm.

A derived profile scales a template, the Panda's profile for a spatial arm and planar4's for a planar one, by the
ratio of the arm's reach to the template arm's (:data:`TEMPLATES`). The reach ``R`` [m] is the largest distance from
the first joint's origin to the hand over :data:`REACH_SAMPLES` configurations (the neutral one and random ones drawn
within the joint limits with seed 0). The template's lengths (workspace reach and height, path segments, obstacle
radii) and obstacle speeds are multiplied by ``R / R_template``; its angles, segment count, duration and controller
settings are kept. The nominal pose ``q0_center`` is the sample with the largest avoidance manipulability (AMSI,
eq. 16) among those free of self-collision, with the hand in the scaled workspace and every joint at least the
template's spread inside its limits (so the box ``q0`` is drawn from is never cut by a limit).

The spatial template's reach, 0.855 m, is the geometric mean of the Panda's (0.946 m) and the xArm7's (0.772 m),
measured so: their derived workspaces and obstacles are within 11 % of their hand-written ones (the Panda's
1.107 times them, the xArm7's 0.903 times, where the two hand-written profiles agree).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from previewctl.errors import ParameterError
from previewctl.index.evaluator import Evaluator
from previewctl.robot.model import Robot
from previewctl.scene.shapes import Scene
from previewctl.types import Array


@dataclass(frozen=True)
class Profile:
    """How scenes of one robot are drawn (lengths [m], angles [rad], speeds [m/s], times [s]).

    Attributes:
        q0_center: centre of the box ``q0`` is drawn from (clipped to the joint limits), in joint coordinates
            (``nv`` entries: a continuous joint's angle, not its (cos, sin) pair).
        q0_spread: half-widths of that box.
        segments: number of straight path segments.
        segment_length: range of each segment's length.
        reach: range of the hand's distance from the base's z axis (planar: from the base).
        height: range of the hand's height (``None``: planar).
        radius: range of the obstacle radius.
        speed: range of the obstacle speed.
        duration: default run length.
        controller: the ``[controller]`` table every controller runs with (its name is replaced).
    """

    q0_center: tuple[float, ...]
    q0_spread: tuple[float, ...]
    segments: int
    segment_length: tuple[float, float]
    reach: tuple[float, float]
    height: tuple[float, float] | None
    radius: tuple[float, float]
    speed: tuple[float, float]
    duration: float
    controller: dict[str, Any] = field(default_factory=dict)


_SPATIAL_CONTROLLER = {"gradient_gain": 1e-3, "feedback_gain": 5.0, "gain": 1.0, "preview_time": 1.0,
                       "plan_window": 6.0}
"""The settings of scenarios/panda_crossing.toml and xarm7_crossing.toml (without the local term), and the planar
scenes' 6 s ``plan_window`` [s] for the sampled searches of ``horizon`` and ``reach`` (chosen on held-out Panda
scenes: see docs/guide/controllers.md#reach)."""
_PLANAR_CONTROLLER = {"feedback_gain": 5.0, "plan_window": 6.0}
"""``plan_window``: the DP of ``horizon`` and ``reach`` looks 6 s ahead, not only to the last preview time (3 s).
How it was chosen: see docs/decisions.md#how-the-planar-bench-settings-were-chosen."""

PROFILES: dict[str, Profile] = {
    "planar4": Profile(q0_center=(0.0, 0.0, 0.0, 0.0), q0_spread=(math.pi, 2.5, 2.5, 2.5), segments=2,
                       segment_length=(0.3, 0.5), reach=(1.0, 2.6), height=None, radius=(0.08, 0.15),
                       speed=(0.15, 0.35), duration=8.0, controller=_PLANAR_CONTROLLER),
    # nominal poses: q0 of scenarios/panda_crossing.toml and scenarios/xarm7_crossing.toml
    "panda": Profile(q0_center=(-0.231, -0.1124, -0.2518, -2.1351, -0.0842, 2.0147, 0.785), q0_spread=(0.4,) * 7,
                     segments=1, segment_length=(0.3, 0.5), reach=(0.3, 0.7), height=(0.15, 0.7),
                     radius=(0.05, 0.09), speed=(0.08, 0.15), duration=10.0, controller=_SPATIAL_CONTROLLER),
    "xarm7": Profile(q0_center=(-0.2928, 0.1534, -0.2673, 1.0918, -0.0348, 1.1576, 0.0), q0_spread=(0.4,) * 7,
                     segments=1, segment_length=(0.3, 0.5), reach=(0.3, 0.65), height=(0.15, 0.7),
                     radius=(0.05, 0.09), speed=(0.08, 0.15), duration=10.0, controller=_SPATIAL_CONTROLLER),
}
"""The hand-written profiles; their scenes (and so the results recorded on them) never change."""

TEMPLATES: dict[bool, tuple[str, float]] = {True: ("planar4", 3.0), False: ("panda", 0.855)}
"""Per ``planar``: the profile a derived one scales, and the reach [m] it is scaled from (planar4: four 0.75 m
links; spatial: see the module docstring)."""
REACH_SAMPLES = 512
"""Configurations (the neutral one, then uniform within the joint limits, seed 0) that measure a reach and offer
nominal poses."""
PLANAR_JOINTS = (3, 4)
"""Joint counts of the planar arms a profile is derived for: the planar witness (the reachability DP) grids at most
two redundant joints, and a planar arm needs one."""


def derived_profile(arm: Robot) -> Profile:
    """The profile of ``arm`` scaled from its template (see the module docstring).

    Raises:
        ParameterError: an arm with no redundancy (no more joints than task rows), a planar arm the planar
            witness cannot take, or no sample that qualifies as a nominal pose.
    """
    _require_benchable(arm)
    planar = arm.task == "planar"
    name, template_reach = TEMPLATES[planar]
    template = PROFILES[name]
    samples = np.vstack([arm.neutral(), arm.random_configurations(np.random.default_rng(0), REACH_SAMPLES - 1)])
    origin, hands = _first_origin_and_hands(arm, samples)
    reach = float(np.linalg.norm(hands - origin, axis=1).max())
    k = reach / template_reach

    def scaled(pair: tuple[float, float]) -> tuple[float, float]:
        return (round(k * pair[0], 4), round(k * pair[1], 4))

    workspace, height = scaled(template.reach), None if template.height is None else scaled(template.height)
    radial = np.linalg.norm(hands[:, :2], axis=1)
    inside = (radial >= workspace[0]) & (radial <= workspace[1])
    if height is not None:
        inside &= (hands[:, 2] >= height[0]) & (hands[:, 2] <= height[1])
    spread = template.q0_spread[:1] + template.q0_spread[1:2] * (arm.nv - 1)
    angles = arm.angles_of(samples)
    inside &= np.all((angles >= arm.joints.lower + spread) & (angles <= arm.joints.upper - spread), axis=1)
    found = Evaluator(arm, Scene(()))(samples, 0.0)
    candidates = np.flatnonzero(inside & ~found.self_collision)
    if candidates.size == 0:
        raise ParameterError(f"robot {arm.name!r}: none of {REACH_SAMPLES} configurations is free of self-collision "
                             f"with the hand in its workspace (distance from the z axis {workspace} m, height "
                             f"{height} m) and the joints {spread[-1]} rad inside their limits; valid: arms with "
                             "such a configuration")
    best = candidates[int(np.argmax(found.amsi[candidates]))]
    return Profile(q0_center=tuple(round(float(v), 4) for v in angles[best]), q0_spread=spread,
                   segments=template.segments, segment_length=scaled(template.segment_length), reach=workspace,
                   height=height, radius=scaled(template.radius), speed=scaled(template.speed),
                   duration=template.duration, controller=template.controller)


def _require_benchable(arm: Robot) -> None:
    """Refuse an arm a derived profile cannot serve (see :func:`derived_profile`)."""
    rows = arm.task_rows.stop - arm.task_rows.start
    if arm.nv <= rows:
        raise ParameterError(f"robot {arm.name!r} has no redundancy: {arm.nv} joints for a {rows}-row "
                             f"{arm.task!r} task; valid: arms with more joints than task rows (e.g. 7 joints for a "
                             "3-D hand position)")
    if arm.task == "planar" and (arm.planar is None or arm.nv not in PLANAR_JOINTS):
        raise ParameterError(f"robot {arm.name!r} is a planar arm of {arm.nv} joints"
                             f"{'' if arm.planar is not None else ' whose links are not in-plane capsules'}; valid "
                             f"planar arms: {' or '.join(map(str, PLANAR_JOINTS))} joints with cylinder links in the "
                             "plane (the planar witness, the reachability DP, grids at most 2 redundant joints)")


def _first_origin_and_hands(arm: Robot, samples: Array) -> tuple[Array, Array]:
    """The first joint's origin [m] (3,) and the hand positions [m] ``(B, 3)`` of ``samples`` ``(B, nq)``."""
    data = arm.model.createData()
    hands = []
    for q in samples:
        pin.framesForwardKinematics(arm.model, data, q)
        hands.append(np.array(data.oMf[arm.tip_frame_id].translation))
    return np.array(data.oMi[1].translation), np.array(hands)
