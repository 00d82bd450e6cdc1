"""Figures of a run: strobe plots of the arm (like the paper's Figs. 12-13), S(t), clearance, errors.

Matplotlib (Agg backend) is imported inside the functions, so importing this module is
cheap and never opens a window. Every function writes one file and returns its path.

* :func:`strobe_plot` -- planar arms: the arm drawn at evenly spaced times with a colour that darkens
  with time, the desired path, the obstacles where they are at those times (moving ones faintly), a
  red pose and marker at a collision. Spatial arms: a 3-D strobe of the joint-origin polyline.
* :func:`s_plot` -- AMSIP ``S(t)`` and AMSI ``E(t)``.
* :func:`clearance_plot` -- minimum distance per guarded link against time.
* :func:`error_plot` -- hand error and joint-speed use (``max_j |q̇_j| / q̇max_j``) against time.

:func:`make_figures` writes the ones a scenario asks for, with the GIF of
:func:`previewctl.viz.animation.animate_gif` for planar arms.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from previewctl.files import save_figure
from previewctl.robot.model import Robot
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Box, Obstacle, Sphere
from previewctl.sim.log import RunResult
from previewctl.sim.scenario import Scenario
from previewctl.types import Array
from previewctl.viz.animation import animate_gif
from previewctl.viz.drawing import COLLISION_COLOUR, OBSTACLE_COLOUR, arm_points, draw_obstacle, pyplot, view_bounds

_ARM_COLOUR_MAP = "viridis"
_COLLISION_COLOUR = COLLISION_COLOUR
_OBSTACLE_COLOUR = OBSTACLE_COLOUR


def strobe_indices(steps: int, poses: int, extra: int | None = None) -> NDArray[np.int_]:
    """``poses`` evenly spaced step indices in ``[0, steps)``, plus ``extra`` (e.g. the collision step)."""
    idx = np.unique(np.linspace(0, steps - 1, max(2, min(poses, steps))).round().astype(int))
    if extra is not None:
        idx = np.unique(np.append(idx, extra))
    return idx


def _carrying_joint(robot: Robot, link: str) -> int | None:
    """Id of the joint that moves body ``link`` (``None`` if unknown or fixed to the base)."""
    model = robot.model
    if not model.existFrame(link):
        return None
    joint = int(model.frames[model.getFrameId(link)].parentJoint)
    return joint or None


def _is_planar_run(scenario: Scenario) -> bool:
    return scenario.robot.task == "planar"


def _collision_text(result: RunResult) -> str:
    summary = result.summary()
    if summary["collided"]:
        return f"collision at t = {summary['collision_time']:.2f} s ({summary['collision_link']})"
    if summary["self_collided"]:
        a, b = summary["self_collision_links"]
        return f"self-collision at t = {summary['self_collision_time']:.2f} s ({a} / {b})"
    return "collision-free"


# ------------------------------------------------------------------------------------ figures


def strobe_plot(
    result: RunResult, scenario: Scenario, path: str | os.PathLike[str], *, poses: int | None = None
) -> Path:
    """Strobe plot of the arm along the run (PNG).

    Args:
        result: the run.
        scenario: its scenario (robot, path, obstacles).
        path: output file.
        poses: number of arm poses drawn (default: the scenario's ``output.strobe_poses``).

    Returns:
        ``path``.
    """
    if not _is_planar_run(scenario):
        return _strobe_3d(result, scenario, path, poses or scenario.outputs.strobe_poses)
    plt = pyplot()
    hit = result.collision_index
    idx = strobe_indices(result.steps, poses or scenario.outputs.strobe_poses, hit)
    points = arm_points(scenario.robot, result.q[idx])
    desired = scenario.path.position(np.linspace(scenario.path.start_time, scenario.path.end_time, 200))
    bounds = view_bounds(points, desired, scenario.scene)
    cmap = plt.get_cmap(_ARM_COLOUR_MAP)
    fig, ax = plt.subplots(figsize=(7, 7))
    try:
        for obstacle in scenario.scene.obstacles:
            if isinstance(obstacle.motion, Static):
                draw_obstacle(ax, obstacle, 0.0, bounds, 0.55)
            else:
                for n, k in enumerate(idx):
                    draw_obstacle(ax, obstacle, float(result.t[k]), bounds, 0.08 + 0.22 * n / max(1, len(idx) - 1))
        ax.plot(desired[:, 0], desired[:, 1], "--", color="black", linewidth=1.0, label="desired path")
        ax.plot(result.hand[:, 0], result.hand[:, 1], color="#ff7f0e", linewidth=1.0, label="hand")
        _draw_poses(ax, result, idx, points[:, :, :2], cmap, "-o", markersize=3, linewidth=2)
        if hit is not None:
            _mark_colliding_link(ax, result, scenario.robot, points[int(np.flatnonzero(idx == hit)[0])])
        ax.plot(0, 0, "ks", markersize=8)
        ax.set_xlim(bounds[0], bounds[1])
        ax.set_ylim(bounds[2], bounds[3])
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(f"{result.scenario} -- {result.controller}: {_collision_text(result)}")
        sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(float(result.t[0]), float(result.t[-1])))
        fig.colorbar(sm, ax=ax, label="t [s]", shrink=0.7)
        ax.legend(loc="best", fontsize=8)
        return save_figure(fig, path, dpi=110, bbox_inches="tight")
    finally:
        plt.close(fig)


def _draw_poses(ax: Any, result: RunResult, idx: NDArray[np.int_], points: Array, cmap: Any, style: str,
                **line: float) -> None:
    """The arm at the steps ``idx`` (``points (len(idx), njoints, 2 or 3)``), darkening with time; the
    colliding pose in red and opaque."""
    hit = result.collision_index
    span = max(float(result.t[-1] - result.t[0]), 1e-12)
    for n, k in enumerate(idx):
        frac = float(result.t[k] - result.t[0]) / span
        colour = _COLLISION_COLOUR if k == hit else cmap(frac)
        alpha = 1.0 if k == hit else 0.3 + 0.7 * frac
        ax.plot(*points[n].T, style, color=colour, alpha=alpha, **line)


def _mark_colliding_link(ax: Any, result: RunResult, robot: Robot, pose: Array) -> None:
    """Thicken the colliding link's segment of ``pose (njoints, 2)``, from its joint to the next joint (or
    the hand)."""
    hit = result.collision_index
    if hit is None:
        return
    name = result.link_names[int(np.argmin(result.link_distances[hit]))]
    j = _carrying_joint(robot, name)
    if j is not None:
        seg = pose[j - 1 : j + 1, :2]
        ax.plot(seg[:, 0], seg[:, 1], color=_COLLISION_COLOUR, linewidth=6, alpha=0.6,
                solid_capstyle="round", label=f"collision ({name})")


def _strobe_3d(result: RunResult, scenario: Scenario, path: str | os.PathLike[str], poses: int) -> Path:
    """:func:`strobe_plot` of a spatial arm: the joint-origin polyline in 3-D, obstacles as wireframes."""
    plt = pyplot()
    idx = strobe_indices(result.steps, poses, result.collision_index)
    points = arm_points(scenario.robot, result.q[idx])
    desired = scenario.path.position(np.linspace(scenario.path.start_time, scenario.path.end_time, 100))
    fig = plt.figure(figsize=(8, 7))
    try:
        ax = fig.add_subplot(projection="3d")
        for obstacle in scenario.scene.obstacles:
            times = [0.0] if isinstance(obstacle.motion, Static) else [float(result.t[k]) for k in idx]
            for n, t in enumerate(times):
                alpha = 0.5 if len(times) == 1 else 0.08 + 0.3 * n / max(1, len(times) - 1)
                _draw_obstacle_3d(ax, obstacle, t, alpha)
        ax.plot(*desired.T, "--", color="black", linewidth=1.0, label="desired path")
        _draw_poses(ax, result, idx, points, plt.get_cmap(_ARM_COLOUR_MAP), "-o", markersize=2.5)
        allp = np.concatenate([points.reshape(-1, 3), desired])
        centre, half = (allp.max(0) + allp.min(0)) / 2, (allp.max(0) - allp.min(0)).max() / 2 + 0.1
        ax.set_xlim(centre[0] - half, centre[0] + half)
        ax.set_ylim(centre[1] - half, centre[1] + half)
        ax.set_zlim(max(0.0, centre[2] - half), centre[2] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_zlabel("z [m]")
        ax.set_title(f"{result.scenario} -- {result.controller}: {_collision_text(result)}")
        return save_figure(fig, path, dpi=110, bbox_inches="tight")
    finally:
        plt.close(fig)


def _draw_obstacle_3d(ax: Any, obstacle: Obstacle, t: float, alpha: float) -> None:
    """An obstacle at time ``t`` [s] on 3-D axes: a sphere's wireframe, a box's edges, else its centre."""
    p = obstacle.placement(t).translation
    shape = obstacle.shape
    if isinstance(shape, Sphere):
        u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 16), np.linspace(0, np.pi, 9))
        r = shape.radius
        ax.plot_wireframe(p[0] + r * np.cos(u) * np.sin(v), p[1] + r * np.sin(u) * np.sin(v),
                          p[2] + r * np.cos(v), color=_OBSTACLE_COLOUR, alpha=alpha, linewidth=0.6)
    elif isinstance(shape, Box):
        R = obstacle.placement(t).rotation
        half = np.array(shape.size) / 2
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        corners = p + (signs * half) @ R.T
        for a in range(8):
            for b in range(a + 1, 8):
                if np.count_nonzero(signs[a] != signs[b]) == 1:
                    ax.plot(*corners[[a, b]].T, color=_OBSTACLE_COLOUR, alpha=alpha, linewidth=0.8)
    else:
        ax.scatter(*p, color=_OBSTACLE_COLOUR, alpha=alpha, s=40)


def _mark_collision(ax: Any, result: RunResult) -> None:
    hit = result.collision_index
    if hit is not None:
        ax.axvline(float(result.t[hit]), color=_COLLISION_COLOUR, linestyle=":", label="collision")


def s_plot(result: RunResult, path: str | os.PathLike[str]) -> Path:
    """AMSIP ``S(t)`` and AMSI ``E(t)`` (PNG); returns ``path``."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 4))
    try:
        ax.plot(result.t, result.amsi, color="#1f77b4", alpha=0.5, label="AMSI E")
        ax.plot(result.t, result.S, color="#2ca02c", label="AMSIP S = E + U")
        ax.axhline(0.0, color="black", linewidth=0.6)
        _mark_collision(ax, result)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("S (index length unit)")
        ax.set_title(
            f"{result.scenario} -- {result.controller}: mean S {result.S.mean():.1f}, min {result.S.min():.1f}"
        )
        ax.legend(loc="best", fontsize=8)
        ax.grid(alpha=0.3)
        return save_figure(fig, path, dpi=110, bbox_inches="tight")
    finally:
        plt.close(fig)


def clearance_plot(result: RunResult, path: str | os.PathLike[str], *, influence_distance: float | None = None) -> Path:
    """Minimum distance per guarded link against time (PNG); returns ``path``."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 4))
    try:
        finite = np.isfinite(result.link_distances)
        if not finite.any():
            ax.text(0.5, 0.5, "no obstacles", ha="center", va="center", transform=ax.transAxes)
        for i, name in enumerate(result.link_names):
            if finite[:, i].any():
                ax.plot(result.t, result.link_distances[:, i], label=name)
        if influence_distance is not None and finite.any():
            ax.axhline(influence_distance, color="grey", linestyle="--", linewidth=0.8, label="influence distance")
        ax.axhline(0.0, color="black", linewidth=0.6)
        _mark_collision(ax, result)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("minimum distance [m]")
        ax.set_title(f"{result.scenario} -- {result.controller}: clearance per link")
        if finite.any():
            ax.legend(loc="best", fontsize=8)
        ax.grid(alpha=0.3)
        return save_figure(fig, path, dpi=110, bbox_inches="tight")
    finally:
        plt.close(fig)


def error_plot(result: RunResult, path: str | os.PathLike[str]) -> Path:
    """Hand error [mm] and joint-speed use ``max_j |q̇_j|/q̇max_j`` against time (PNG); returns ``path``."""
    plt = pyplot()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    try:
        top.plot(result.t, 1e3 * result.hand_error, color="#ff7f0e")
        top.set_ylabel("hand error [mm]")
        top.grid(alpha=0.3)
        finite = np.isfinite(result.velocity_limits)
        if finite.any():
            use = (np.abs(result.qdot[:, finite]) / result.velocity_limits[finite]).max(axis=1)
            bottom.plot(result.t, use, color="#9467bd")
            bottom.axhline(1.0, color="black", linewidth=0.6)
        bottom.set_ylabel("max |q̇_j| / limit")
        bottom.set_xlabel("t [s]")
        bottom.grid(alpha=0.3)
        for ax in (top, bottom):
            _mark_collision(ax, result)
        top.set_title(f"{result.scenario} -- {result.controller}: tracking and joint speed")
        return save_figure(fig, path, dpi=110, bbox_inches="tight")
    finally:
        plt.close(fig)


def make_figures(result: RunResult, scenario: Scenario, out_dir: str | os.PathLike[str], *,
                 figures: Sequence[str] | None = None, gif: bool | None = None) -> list[Path]:
    """Write the figures a scenario asks for (``[output]``) into ``out_dir``.

    Args:
        result: the run.
        scenario: its scenario.
        out_dir: folder (created if needed).
        figures: override of ``output.figures`` (names among strobe, S, clearance, error).
        gif: override of ``output.gif`` (ignored for spatial arms).

    Returns:
        The files written.
    """
    folder = Path(out_dir)
    folder.mkdir(parents=True, exist_ok=True)
    wanted = tuple(figures if figures is not None else scenario.outputs.figures)
    written: list[Path] = []
    if "strobe" in wanted:
        written.append(strobe_plot(result, scenario, folder / "strobe.png"))
    if "S" in wanted:
        written.append(s_plot(result, folder / "S.png"))
    if "clearance" in wanted:
        written.append(clearance_plot(result, folder / "clearance.png",
                                      influence_distance=scenario.potential.influence_distance))
    if "error" in wanted:
        written.append(error_plot(result, folder / "error.png"))
    if (scenario.outputs.gif if gif is None else gif) and _is_planar_run(scenario):
        written.append(animate_gif(result, scenario, folder / "run.gif"))
    return written
