"""Figures of a run: strobe plots of the arm (like the paper's Figs. 12-13), S(t), clearance, a GIF.

Matplotlib (Agg backend) and Pillow are imported inside the functions, so importing this module is
cheap and never opens a window. Every function writes one file and returns its path.

* :func:`strobe_plot` -- planar arms: the arm drawn at evenly spaced times with a colour that darkens
  with time, the desired path, the obstacles where they are at those times (moving ones faintly), a
  red pose and marker at a collision. Spatial arms: a 3-D strobe of the joint-origin polyline.
* :func:`s_plot` -- AMSIP ``S(t)`` and AMSI ``E(t)``.
* :func:`clearance_plot` -- minimum distance per guarded link against time.
* :func:`error_plot` -- hand error and joint-speed use (``max_j |q̇_j| / q̇max_j``) against time.
* :func:`animate_gif` -- planar arms: an animated GIF (~10 fps, at most 150 frames).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from previewctl.files import atomic_write, save_figure
from previewctl.robot.model import Robot
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Box, Capsule, Cylinder, Mesh, Obstacle, Plane, Sphere
from previewctl.sim.log import RunResult
from previewctl.sim.scenario import Scenario
from previewctl.types import Array
from previewctl.viz.drawing import arm_points, clip_halfplane, obstacle_section, pyplot

_ARM_COLOUR_MAP = "viridis"
_COLLISION_COLOUR = "#d62728"
_OBSTACLE_COLOUR = "#7f7f7f"


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


# ------------------------------------------------------------------------- planar obstacle shapes


def obstacle_outline(obstacle: Obstacle, t: float, bounds: tuple[float, float, float, float]) -> tuple[str, Array]:
    """How an obstacle looks in the plane ``z = 0`` at time ``t`` [s].

    Args:
        obstacle: the obstacle.
        t: time [s].
        bounds: ``(xmin, xmax, ymin, ymax)`` of the view [m] (for half-spaces and planes).

    Returns:
        ``(kind, points)``: ``("polygon", (K, 2))`` a filled outline, ``("line", (2, 2))`` a line, or
        ``("marker", (1, 2))`` a position marker (meshes).
    """
    section = obstacle_section(obstacle, t, bounds)
    if len(section):
        return "polygon", section
    pose = obstacle.placement(t)
    p, R, shape = np.array(pose.translation), np.array(pose.rotation), obstacle.shape
    if isinstance(shape, Plane):
        normal = R @ np.array(shape.normal)
        offset = shape.offset + float(normal @ p)
        n2 = normal[:2]
        if np.linalg.norm(n2) < 1e-9:
            return "line", np.zeros((0, 2))
        xmin, xmax, ymin, ymax = bounds
        view = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]])
        inside = clip_halfplane(view, n2, offset)
        on_line = inside[np.abs(inside @ n2 - offset) < 1e-9 * max(1.0, abs(offset))]
        return "line", on_line[:2] if len(on_line) >= 2 else np.zeros((0, 2))
    if isinstance(shape, Mesh):
        return "marker", p[None, :2]
    return "polygon", np.zeros((0, 2))  # does not meet the plane z = 0


def _draw_obstacle(ax: Any, obstacle: Obstacle, t: float, bounds: tuple[float, float, float, float],
                   alpha: float, label: str | None = None) -> None:
    from matplotlib.patches import Polygon

    kind, pts = obstacle_outline(obstacle, t, bounds)
    if len(pts) == 0:
        return
    if kind == "polygon" and len(pts) >= 3:
        ax.add_patch(Polygon(pts, closed=True, facecolor=_OBSTACLE_COLOUR, edgecolor="#404040", alpha=alpha,
                             linewidth=0.8, label=label))
    elif kind == "line":
        ax.plot(pts[:, 0], pts[:, 1], color="#404040", alpha=alpha, label=label)
    else:
        ax.plot(pts[:, 0], pts[:, 1], "x", color="#404040", alpha=alpha, label=label)


def _view_bounds(
    points: Array, path: Array, scenario: Scenario, pad: float = 0.25
) -> tuple[float, float, float, float]:
    xy = [points.reshape(-1, 3)[:, :2], path[:, :2]]
    for obstacle in scenario.scene.obstacles:
        if isinstance(obstacle.shape, (Sphere, Box, Cylinder, Capsule)):
            xy.append(obstacle.placement(0.0).translation[None, :2])
    allxy = np.concatenate(xy)
    xmin, ymin = allxy.min(axis=0) - pad
    xmax, ymax = allxy.max(axis=0) + pad
    return float(xmin), float(xmax), float(ymin), float(ymax)


def _collision_text(result: RunResult) -> str:
    summary = result.summary()
    if summary["collided"]:
        return f"collision at t = {summary['collision_time']:.2f} s ({summary['collision_link']})"
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
    bounds = _view_bounds(points, desired, scenario)
    cmap = plt.get_cmap(_ARM_COLOUR_MAP)
    fig, ax = plt.subplots(figsize=(7, 7))
    try:
        for obstacle in scenario.scene.obstacles:
            if isinstance(obstacle.motion, Static):
                _draw_obstacle(ax, obstacle, 0.0, bounds, 0.55)
            else:
                for n, k in enumerate(idx):
                    _draw_obstacle(ax, obstacle, float(result.t[k]), bounds, 0.08 + 0.22 * n / max(1, len(idx) - 1))
        ax.plot(desired[:, 0], desired[:, 1], "--", color="black", linewidth=1.0, label="desired path")
        ax.plot(result.hand[:, 0], result.hand[:, 1], color="#ff7f0e", linewidth=1.0, label="hand")
        span = max(float(result.t[-1] - result.t[0]), 1e-12)
        for n, k in enumerate(idx):
            frac = float(result.t[k] - result.t[0]) / span
            colour = _COLLISION_COLOUR if k == hit else cmap(frac)
            alpha = 1.0 if k == hit else 0.3 + 0.7 * frac
            ax.plot(points[n, :, 0], points[n, :, 1], "-o", color=colour, alpha=alpha, markersize=3, linewidth=2)
        if hit is not None:
            n = int(np.flatnonzero(idx == hit)[0])
            name = result.link_names[int(np.argmin(result.link_distances[hit]))]
            j = _carrying_joint(scenario.robot, name)
            if j is not None:  # the colliding link's segment, from its joint to the next joint (or the hand)
                seg = points[n, j - 1 : j + 1, :2]
                ax.plot(seg[:, 0], seg[:, 1], color=_COLLISION_COLOUR, linewidth=6, alpha=0.6,
                        solid_capstyle="round", label=f"collision ({name})")
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


def _strobe_3d(result: RunResult, scenario: Scenario, path: str | os.PathLike[str], poses: int) -> Path:
    plt = pyplot()
    hit = result.collision_index
    idx = strobe_indices(result.steps, poses, hit)
    points = arm_points(scenario.robot, result.q[idx])
    desired = scenario.path.position(np.linspace(scenario.path.start_time, scenario.path.end_time, 100))
    cmap = plt.get_cmap(_ARM_COLOUR_MAP)
    fig = plt.figure(figsize=(8, 7))
    try:
        ax = fig.add_subplot(projection="3d")
        u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 16), np.linspace(0, np.pi, 9))
        for obstacle in scenario.scene.obstacles:
            times = [0.0] if isinstance(obstacle.motion, Static) else [float(result.t[k]) for k in idx]
            for n, t in enumerate(times):
                alpha = 0.5 if len(times) == 1 else 0.08 + 0.3 * n / max(1, len(times) - 1)
                p = obstacle.placement(t).translation
                shape = obstacle.shape
                if isinstance(shape, Sphere):
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
        ax.plot(*desired.T, "--", color="black", linewidth=1.0, label="desired path")
        span = max(float(result.t[-1] - result.t[0]), 1e-12)
        for n, k in enumerate(idx):
            frac = float(result.t[k] - result.t[0]) / span
            colour = _COLLISION_COLOUR if k == hit else cmap(frac)
            ax.plot(*points[n].T, "-o", color=colour, alpha=1.0 if k == hit else 0.3 + 0.7 * frac, markersize=2.5)
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


def animate_gif(result: RunResult, scenario: Scenario, path: str | os.PathLike[str], *, fps: float = 10.0,
                max_frames: int = 150) -> Path:
    """Animated GIF of a planar run (Pillow): ~``fps`` frames per simulated second, at most ``max_frames``.

    Raises:
        ValueError: a spatial (non-planar) run.
    """
    if not _is_planar_run(scenario):
        raise ValueError(f"animate_gif draws planar arms only; robot {scenario.robot.name!r} has task "
                         f"{scenario.robot.task!r}")
    from matplotlib.patches import Polygon
    from PIL import Image

    plt = pyplot()
    span = float(result.t[-1] - result.t[0])
    count = int(min(max_frames, max(2, math.ceil(span * fps) + 1), result.steps))
    idx = np.unique(np.linspace(0, result.steps - 1, count).round().astype(int))
    points = arm_points(scenario.robot, result.q[idx])
    desired = scenario.path.position(np.linspace(scenario.path.start_time, scenario.path.end_time, 200))
    bounds = _view_bounds(points, desired, scenario)
    moving = [o for o in scenario.scene.obstacles if not isinstance(o.motion, Static)]
    fig, ax = plt.subplots(figsize=(5, 5), dpi=80)
    frames: list[Any] = []
    try:
        for obstacle in scenario.scene.obstacles:
            if isinstance(obstacle.motion, Static):
                _draw_obstacle(ax, obstacle, 0.0, bounds, 0.55)
        ax.plot(desired[:, 0], desired[:, 1], "--", color="black", linewidth=1.0)
        ax.plot(0, 0, "ks", markersize=7)
        ax.set_xlim(bounds[0], bounds[1])
        ax.set_ylim(bounds[2], bounds[3])
        ax.set_aspect("equal")
        ax.set_title(f"{result.scenario} -- {result.controller}", fontsize=10)
        # blitting: the axes, ticks and static obstacles are drawn once; each frame restores them and
        # draws only the moving artists
        (arm,) = ax.plot([], [], "-o", color="#1f77b4", linewidth=2.5, markersize=4, animated=True)
        (trace,) = ax.plot([], [], color="#ff7f0e", linewidth=1.0, animated=True)
        label = ax.text(0.02, 0.97, "", transform=ax.transAxes, va="top", fontsize=9, animated=True)
        fig.canvas.draw()
        background = fig.canvas.copy_from_bbox(fig.bbox)
        hit = result.collision_index
        for n, k in enumerate(idx):
            fig.canvas.restore_region(background)
            for obstacle in moving:
                kind, pts = obstacle_outline(obstacle, float(result.t[k]), bounds)
                if kind == "polygon" and len(pts) >= 3:
                    patch = ax.add_patch(Polygon(pts, closed=True, facecolor=_OBSTACLE_COLOUR, alpha=0.6,
                                                 animated=True))
                    ax.draw_artist(patch)
                    patch.remove()
            colliding = hit is not None and k >= hit
            arm.set_data(points[n, :, 0], points[n, :, 1])
            arm.set_color(_COLLISION_COLOUR if colliding else "#1f77b4")
            trace.set_data(result.hand[: k + 1, 0], result.hand[: k + 1, 1])
            label.set_text(f"t = {result.t[k]:.2f} s   S = {result.S[k]:.0f}" + ("   COLLISION" if colliding else ""))
            for artist in (trace, arm, label):
                ax.draw_artist(artist)
            rgb = np.asarray(fig.canvas.buffer_rgba())[:, :, :3].copy()
            frames.append(Image.fromarray(rgb).quantize(colors=64, method=Image.Quantize.FASTOCTREE))
    finally:
        plt.close(fig)
    out = Path(path)
    atomic_write(out, lambda handle: frames[0].save(handle, format="GIF", save_all=True, append_images=frames[1:],
                                                    duration=round(1000 / fps), loop=0, optimize=False))
    return out


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
