"""Figures of a redundancy landscape: the AMSIP map over (q1, q2) (the paper's Figs. 6-8, 10-11).

Matplotlib is imported inside the functions (Agg backend), so importing this module is cheap.

* :func:`plot_landscape` -- one heat map of S per branch over the genes in degrees, ``S < 0``
  (collision or hand target out of reach) in black, the best candidate (star) and the peaks
  (numbered circles) marked, next to the arm drawn at the best configuration among the obstacles.
  For a sampled landscape (more than two genes) the map is a scatter over the first two genes.
* :func:`plot_surface` -- the 3-D surface of ``max over branches S(q1, q2)`` (grid landscapes).

The obstacles are drawn as their sections by the plane ``z = 0``
(:func:`previewctl.viz.drawing.obstacle_section`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from previewctl.errors import ConfigurationError
from previewctl.files import save_figure
from previewctl.robot.model import Robot
from previewctl.scene.shapes import Box, Capsule, Cylinder, Halfspace, Scene, Sphere
from previewctl.search.explore import Landscape
from previewctl.types import Array
from previewctl.viz.drawing import Bounds, arm_points, obstacle_section, pyplot

_OBSTACLE = "#8c8c8c"


def _colormap() -> Any:
    import matplotlib

    return matplotlib.colormaps["turbo"].with_extremes(under="black", bad="black")


# ---------------------------------------------------------------------------------------- panels


def _draw_arm(ax: Any, robot: Robot, q: Array, scene: Scene, t: float, target: Array) -> None:
    """Top view (x-y) of the arm at ``q`` among the obstacles' sections at ``z = 0``."""
    from matplotlib.patches import Polygon

    pts = arm_points(robot, np.asarray(q, dtype=float)[None, :])[0]
    reach = float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))
    base = pts[0, :2]
    pad = 0.15 * reach + 0.1
    bounds: Bounds = (base[0] - reach - pad, base[0] + reach + pad, base[1] - reach - pad, base[1] + reach + pad)
    for k, obstacle in enumerate(scene.obstacles):
        poly = obstacle_section(obstacle, t, bounds)
        if len(poly) >= 3:
            ax.add_patch(Polygon(poly, closed=True, facecolor=_OBSTACLE, edgecolor="#404040", alpha=0.7,
                                 linewidth=0.8, label="obstacles (z = 0)" if k == 0 else None))
        elif not isinstance(obstacle.shape, (Sphere, Box, Capsule, Cylinder, Halfspace)):
            c = obstacle.placement(t).translation
            ax.plot(c[0], c[1], "x", color="#404040")
    ax.plot(pts[:, 0], pts[:, 1], "-", color="#1f4e9c", linewidth=3, solid_capstyle="round", label="arm at best")
    ax.plot(pts[:-1, 0], pts[:-1, 1], "o", color="white", markeredgecolor="#1f4e9c", markersize=6, zorder=3)
    ax.plot(target[0], target[1], "*", color="#d62728", markersize=12, label="hand target", zorder=4)
    ax.set_xlim(bounds[0], bounds[1])
    ax.set_ylim(bounds[2], bounds[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=7)


def _draw_arm_3d(ax: Any, robot: Robot, q: Array, scene: Scene, t: float, target: Array) -> None:
    pts = arm_points(robot, np.asarray(q, dtype=float)[None, :])[0]
    ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], "-o", color="#1f4e9c", linewidth=2, markersize=3)
    ax.scatter(*target[:3], marker="*", color="#d62728", s=80)
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 16), np.linspace(0, np.pi, 9))
    for obstacle in scene.obstacles:
        c = obstacle.placement(t).translation
        if isinstance(obstacle.shape, Sphere):
            r = obstacle.shape.radius
            ax.plot_wireframe(c[0] + r * np.cos(u) * np.sin(v), c[1] + r * np.sin(u) * np.sin(v),
                              c[2] + r * np.cos(v), color=_OBSTACLE, linewidth=0.5)
        else:
            ax.scatter(c[0], c[1], c[2], marker="s", color=_OBSTACLE)
    centres = [np.asarray(o.placement(t).translation, float) for o in scene.obstacles if isinstance(o.shape, Sphere)]
    ends = np.concatenate([pts, np.asarray(target, float)[None, :3], *(c[None] for c in centres)])
    centre, half = ends.mean(axis=0), 0.6 * float(np.ptp(ends, axis=0).max()) + 0.1
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")


def _degrees(genes: Array, grid: bool) -> Array:
    """Genes in degrees: on ``[0, 360)`` like the grid axes, else as they are."""
    return np.degrees(np.mod(genes, 2 * np.pi) if grid else genes)


def _mark(ax: Any, landscape: Landscape, branch: int | None) -> None:
    best = landscape.best
    grid = landscape.S_map is not None
    if branch is None or best.branch == branch:
        g = _degrees(best.genes[:2], grid)
        ax.plot(g[0], g[1] if len(g) > 1 else 0.0, "*", color="white", markeredgecolor="black", markersize=15,
                label=f"best S = {best.S:.0f}")
    for k, peak in enumerate(landscape.peaks, start=1):
        if branch is not None and peak.branch != branch:
            continue
        g = _degrees(peak.genes[:2], grid)
        y = g[1] if len(g) > 1 else 0.0
        ax.plot(g[0], y, "o", markerfacecolor="none", markeredgecolor="white", markersize=11, markeredgewidth=1.5)
        ax.annotate(f"{k}", (g[0], y), xytext=(6, 6), textcoords="offset points", color="white", fontsize=9)


def plot_landscape(
    landscape: Landscape,
    robot: Robot,
    scene: Scene | None = None,
    path: str | Path = "map.png",
    *,
    title: str | None = None,
) -> Path:
    """Write the AMSIP map(s) and the arm at the best configuration to a PNG.

    Args:
        landscape: from :func:`previewctl.search.explore.explore`.
        robot: the arm.
        scene: the obstacles (drawn at ``landscape.t``).
        path: output PNG file.
        title: figure title (default: the target and time).

    Returns:
        The path written.
    """
    plt = pyplot()
    from matplotlib.colors import Normalize

    scene = scene or Scene()
    valid = landscape.S[landscape.S >= 0]
    vmax = float(valid.max()) if valid.size else 1.0
    norm = Normalize(vmin=1e-9 * max(vmax, 1.0), vmax=max(vmax, 1e-9))
    grid = landscape.S_map is not None and len(landscape.axes) == 2
    panels = landscape.S_map.shape[0] if grid and landscape.S_map is not None else 1
    fig = plt.figure(figsize=(5.0 * (panels + 1) + 1.0, 4.8), layout="constrained")
    try:
        image = _grid_panels(fig, landscape, norm, panels) if grid else _samples_panel(fig, landscape, norm)
        if image is not None:
            fig.colorbar(image, ax=fig.axes[:panels], shrink=0.85, label="AMSIP S (black: S < 0)", extend="min")
        q_best = landscape.best.q
        if robot.task == "planar":
            _draw_arm(fig.add_subplot(1, panels + 1, panels + 1), robot, q_best, scene, landscape.t, landscape.target)
        else:
            _draw_arm_3d(fig.add_subplot(1, panels + 1, panels + 1, projection="3d"), robot, q_best, scene,
                         landscape.t, landscape.target)
        target = np.round(landscape.target[:2] if robot.task == "planar" else landscape.target, 3).tolist()
        fig.suptitle(title or f"{robot.name}: hand target {target} m, t = {landscape.t:g} s, best S = "
                     f"{landscape.best.S:.1f}", fontsize=11)
        return save_figure(fig, path, dpi=110)
    finally:
        plt.close(fig)


def _grid_panels(fig: Any, landscape: Landscape, norm: Any, panels: int) -> Any:
    """One heat map of S over (q1, q2) [deg] per branch, best and peaks marked; the last image drawn."""
    if landscape.S_map is None:
        return None
    cmap = _colormap()
    ax0, ax1 = (np.degrees(a) for a in landscape.axes)
    step0 = ax0[1] - ax0[0] if len(ax0) > 1 else 1.0
    step1 = ax1[1] - ax1[0] if len(ax1) > 1 else 1.0
    extent = (ax0[0] - step0 / 2, ax0[-1] + step0 / 2, ax1[0] - step1 / 2, ax1[-1] + step1 / 2)
    image = None
    for b in range(panels):
        ax = fig.add_subplot(1, panels + 1, b + 1)
        image = ax.imshow(landscape.S_map[b].T, origin="lower", extent=extent, cmap=cmap, norm=norm,
                          aspect="auto", interpolation="nearest")
        _mark(ax, landscape, b)
        ax.set_xlabel("q1 [deg]")
        ax.set_ylabel("q2 [deg]")
        label = ("elbow q_n >= 0", "elbow q_n < 0")[b] if panels == 2 else f"branch {b}"
        ax.set_title(f"S over (q1, q2), {label}", fontsize=10)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="upper right", fontsize=7, facecolor="#dddddd")
    return image


def _samples_panel(fig: Any, landscape: Landscape, norm: Any) -> Any:
    """A scatter of the samples' S over their first two genes [deg], best and peaks marked; the image."""
    ax = fig.add_subplot(1, 2, 1)
    genes = _degrees(landscape.genes, grid=False)
    x = genes[:, 0] if genes.shape[1] else np.zeros(len(genes))
    y = genes[:, 1] if genes.shape[1] > 1 else np.zeros(len(genes))
    order = np.argsort(landscape.S)
    image = ax.scatter(x[order], y[order], c=landscape.S[order], cmap=_colormap(), norm=norm, s=6)
    _mark(ax, landscape, None)
    ax.set_facecolor("#202020")
    ax.set_xlabel("gene 1 [deg]")
    ax.set_ylabel("gene 2 [deg]")
    ax.set_title(f"S of {len(landscape.S)} samples (black: S < 0)", fontsize=10)
    return image


def plot_surface(landscape: Landscape, path: str | Path = "map_surface.png", *, title: str | None = None) -> Path:
    """Write the 3-D surface of ``max_branch S(q1, q2)`` (``S < 0`` drawn black at S = 0) to a PNG.

    Raises:
        ConfigurationError: the landscape is not a two-gene grid.
    """
    if landscape.S_map is None or len(landscape.axes) != 2:
        raise ConfigurationError("plot_surface needs a grid landscape over two genes (e.g. planar4)")
    plt = pyplot()
    from matplotlib.colors import Normalize

    S = landscape.S_map.max(axis=0)
    step = max(1, int(np.ceil(max(S.shape) / 120)))  # at most ~120 x 120 facets
    S = S[::step, ::step]
    a0, a1 = (np.degrees(a)[::step] for a in landscape.axes)
    X, Y = np.meshgrid(a0, a1, indexing="ij")
    cmap = _colormap()
    vmax = float(max(S.max(), 1e-9))
    colours = cmap(Normalize(vmin=1e-9 * max(vmax, 1.0), vmax=vmax)(np.where(S >= 0, S, -1.0)))
    fig = plt.figure(figsize=(7.5, 6))
    try:
        ax = fig.add_subplot(1, 1, 1, projection="3d")
        ax.plot_surface(X, Y, np.maximum(S, 0.0), facecolors=colours, linewidth=0, antialiased=False, shade=False)
        for k, peak in enumerate(landscape.peaks, start=1):
            g = np.degrees(np.mod(peak.genes, 2 * np.pi))
            ax.scatter(g[0], g[1], peak.S, color="white", edgecolor="black", s=40)
            ax.text(g[0], g[1], peak.S * 1.03, f"peak {k}", fontsize=8)
        ax.set_xlabel("q1 [deg]")
        ax.set_ylabel("q2 [deg]")
        ax.set_zlabel("S")
        where = np.round(landscape.target[:2], 3).tolist()
        ax.set_title(title or f"AMSIP max over branches, target {where} m", fontsize=10)
        return save_figure(fig, path, dpi=110)
    finally:
        plt.close(fig)
