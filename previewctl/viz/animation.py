"""An animated GIF of a planar run: the arm, the hand's trace and the moving obstacles, frame by frame.

Matplotlib (Agg backend) and Pillow are imported inside the functions, so importing this module is
cheap. The axes, the path and the static obstacles are drawn once; each frame restores that background
and draws only what moves (blitting), then Pillow quantises it to a 64-colour palette.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from previewctl.extras import require
from previewctl.files import atomic_write
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Obstacle
from previewctl.sim.log import RunResult
from previewctl.sim.scenario import Scenario
from previewctl.types import Array
from previewctl.viz.drawing import (
    COLLISION_COLOUR,
    OBSTACLE_COLOUR,
    Bounds,
    arm_points,
    draw_obstacle,
    obstacle_outline,
    pyplot,
    view_bounds,
)

_ARM_COLOUR = "#1f77b4"


def animate_gif(result: RunResult, scenario: Scenario, path: str | os.PathLike[str], *, fps: float = 10.0,
                max_frames: int = 150) -> Path:
    """Animated GIF of a planar run (Pillow): ~``fps`` frames per simulated second, at most ``max_frames``.

    Raises:
        ValueError: a spatial (non-planar) run.
    """
    if scenario.robot.task != "planar":
        raise ValueError(f"animate_gif draws planar arms only; robot {scenario.robot.name!r} has task "
                         f"{scenario.robot.task!r}")
    span = float(result.t[-1] - result.t[0])
    count = int(min(max_frames, max(2, math.ceil(span * fps) + 1), result.steps))
    idx = np.unique(np.linspace(0, result.steps - 1, count).round().astype(int))
    frames = _frames(result, scenario, idx)
    out = Path(path)
    atomic_write(out, lambda handle: frames[0].save(handle, format="GIF", save_all=True, append_images=frames[1:],
                                                    duration=round(1000 / fps), loop=0, optimize=False))
    return out


def _frames(result: RunResult, scenario: Scenario, idx: NDArray[np.int_]) -> list[Any]:
    """One palette image per logged step in ``idx``."""
    Image = require("PIL.Image", "viz", "the GIF animation")
    plt = pyplot()
    points = arm_points(scenario.robot, result.q[idx])
    desired = scenario.path.position(np.linspace(scenario.path.start_time, scenario.path.end_time, 200))
    bounds = view_bounds(points, desired, scenario.scene)
    moving = [o for o in scenario.scene.obstacles if not isinstance(o.motion, Static)]
    fig, ax = plt.subplots(figsize=(5, 5), dpi=80)
    frames: list[Any] = []
    try:
        _draw_background(ax, result, scenario, desired, bounds)
        (arm,) = ax.plot([], [], "-o", color=_ARM_COLOUR, linewidth=2.5, markersize=4, animated=True)
        (trace,) = ax.plot([], [], color="#ff7f0e", linewidth=1.0, animated=True)
        label = ax.text(0.02, 0.97, "", transform=ax.transAxes, va="top", fontsize=9, animated=True)
        fig.canvas.draw()
        background = fig.canvas.copy_from_bbox(fig.bbox)
        hit = result.collision_index
        for n, k in enumerate(idx):
            fig.canvas.restore_region(background)
            _draw_moving(ax, moving, float(result.t[k]), bounds)
            colliding = hit is not None and k >= hit
            arm.set_data(points[n, :, 0], points[n, :, 1])
            arm.set_color(COLLISION_COLOUR if colliding else _ARM_COLOUR)
            trace.set_data(result.hand[: k + 1, 0], result.hand[: k + 1, 1])
            label.set_text(f"t = {result.t[k]:.2f} s   S = {result.S[k]:.0f}" + ("   COLLISION" if colliding else ""))
            for artist in (trace, arm, label):
                ax.draw_artist(artist)
            rgb = np.asarray(fig.canvas.buffer_rgba())[:, :, :3].copy()
            frames.append(Image.fromarray(rgb).quantize(colors=64, method=Image.Quantize.FASTOCTREE))
    finally:
        plt.close(fig)
    return frames


def _draw_background(ax: Any, result: RunResult, scenario: Scenario, desired: Array, bounds: Bounds) -> None:
    """What every frame shares: the static obstacles, the desired path, the base, the view and the title."""
    for obstacle in scenario.scene.obstacles:
        if isinstance(obstacle.motion, Static):
            draw_obstacle(ax, obstacle, 0.0, bounds, 0.55)
    ax.plot(desired[:, 0], desired[:, 1], "--", color="black", linewidth=1.0)
    ax.plot(0, 0, "ks", markersize=7)
    ax.set_xlim(bounds[0], bounds[1])
    ax.set_ylim(bounds[2], bounds[3])
    ax.set_aspect("equal")
    ax.set_title(f"{result.scenario} -- {result.controller}", fontsize=10)


def _draw_moving(ax: Any, moving: list[Obstacle], t: float, bounds: Bounds) -> None:
    """Blit the sections of the moving obstacles at time ``t`` [s] (temporary patches)."""
    from matplotlib.patches import Polygon

    for obstacle in moving:
        kind, pts = obstacle_outline(obstacle, t, bounds)
        if kind == "polygon" and len(pts) >= 3:
            patch = ax.add_patch(Polygon(pts, closed=True, facecolor=OBSTACLE_COLOUR, alpha=0.6, animated=True))
            ax.draw_artist(patch)
            patch.remove()
