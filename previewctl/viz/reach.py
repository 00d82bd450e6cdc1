"""Figures of reachability over time (:mod:`previewctl.search.reachability`).

Matplotlib is imported inside the functions (Agg backend), so importing this module is cheap.

* :func:`plot_reach_maps` -- like the paper's Fig. 8: the AMSIP map ``S(q1, q2)`` at ten times, both
  elbow branches side by side (``S <= 0`` black), with the set of cells reachable from ``q0`` (dashed
  outline), the viable tube (the reachable cells from which the motion can still be continued to the
  end: a translucent white veil with a solid outline) and the best motion's sample (star). For an arm with one gene the
  figure is one image of ``S(t, q1)`` per branch with the tube and the motion drawn over time.
* :func:`plot_reach_motion` -- the best motion's joint angles, its S against time (with ``S*``), and
  the number of reachable and viable cells per layer, with the commit time and the dead end marked.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from previewctl.errors import ConfigurationError
from previewctl.files import save_figure
from previewctl.search.reachability import ReachResult
from previewctl.viz.drawing import pyplot

_BRANCH_LABELS = ("elbow β ≥ 0", "elbow β < 0")


def _colour_norm(result: ReachResult) -> tuple[Any, Any]:
    import matplotlib
    from matplotlib.colors import Normalize

    cmap = matplotlib.colormaps["turbo"].with_extremes(under="black", bad="black")
    top = float(np.max(result.S_maps)) if result.S_maps.size else 1.0
    top = max(top, 1e-9)
    return cmap, Normalize(vmin=1e-9 * max(top, 1.0), vmax=top)


def _outline(ax: Any, mask: np.ndarray, extent: tuple[float, float, float, float], **style: Any) -> None:
    """Outline of a boolean ``(n_x, n_y)`` mask drawn over an image with ``extent`` (degrees)."""
    if not mask.any():
        return
    nx, ny = mask.shape
    x = np.linspace(extent[0], extent[1], nx + 1)
    y = np.linspace(extent[2], extent[3], ny + 1)
    xc, yc = 0.5 * (x[1:] + x[:-1]), 0.5 * (y[1:] + y[:-1])
    ax.contour(xc, yc, mask.T.astype(float), levels=[0.5], **style)


def _veil(ax: Any, mask: np.ndarray, extent: tuple[float, float, float, float]) -> None:
    """A translucent white layer over the cells of ``mask`` (visible down to single cells, unlike a hatch)."""
    if not mask.any():
        return
    from matplotlib.colors import ListedColormap

    ax.imshow(np.ma.masked_where(~mask.T, np.ones(mask.T.shape)), origin="lower", extent=extent,
              cmap=ListedColormap(["white"]), alpha=0.55, aspect="auto", interpolation="nearest")


def plot_reach_maps(result: ReachResult, path: str | os.PathLike[str], *, title: str | None = None) -> Path:
    """Write the Fig. 8-like maps with the reachable set, the viable tube and the best motion.

    Args:
        result: from :func:`previewctl.search.reachability.reach_over_time`; two genes: one pair of
            panels per layer of ``result.map_layers`` (ten by default); one gene: every layer.
        path: output image file (PNG unless the suffix says otherwise).
        title: figure title (default: the verdict and the figures of merit).

    Returns:
        The path written.

    Raises:
        ConfigurationError: an arm without genes (a two-link arm has no map to draw), or no maps kept
            (``ReachOptions.map_times = 0``).
    """
    genes = len(result.map_axes)
    if genes == 0:
        raise ConfigurationError("plot_reach_maps needs at least one gene (a planar arm of 3 or 4 joints)")
    if not result.map_layers:
        raise ConfigurationError("plot_reach_maps: the result kept no S maps (ReachOptions.map_times = 0)")
    plt = pyplot()
    cmap, norm = _colour_norm(result)
    heading = title or _title(result)
    fig = _one_gene(result, plt, cmap, norm) if genes == 1 else _two_genes(result, plt, cmap, norm)
    try:
        fig.suptitle(heading, fontsize=10)
        return save_figure(fig, path, dpi=100)
    finally:
        plt.close(fig)


def _title(result: ReachResult) -> str:
    parts = [result.verdict()]
    if np.isfinite(result.best_min_S):
        parts.append(f"best min S = {result.best_min_S:.0f}")
    if result.commit_time is not None:
        parts.append(f"commit by t = {result.commit_time:g} s ({len(result.end_families)} end families)")
    grid = f"{result.options.resolution_deg:g}° grid, {len(result.times) - 1} steps of {result.dt:g} s"
    legend = "cyan dashed: reachable from q0; white veil, solid outline: viable tube; star: best motion"
    return "; ".join(parts) + f"\n{grid}; {legend}"


def _two_genes(result: ReachResult, plt: Any, cmap: Any, norm: Any) -> Any:
    a0, a1 = (np.degrees(a) for a in result.map_axes)
    s0 = a0[1] - a0[0] if len(a0) > 1 else 1.0
    s1 = a1[1] - a1[0] if len(a1) > 1 else 1.0
    extent = (a0[0] - s0 / 2, a0[-1] + s0 / 2, a1[0] - s1 / 2, a1[-1] + s1 / 2)
    per_row = 2  # two times per row, each with its two branches
    rows = (len(result.map_layers) + per_row - 1) // per_row
    fig = plt.figure(figsize=(4 * 2.6 + 1.2, rows * 2.5 + 0.9), layout="constrained")
    motion = result.motion
    image = None
    layers = result.map_layers
    for slot, k in enumerate(layers):
        for b in range(2):
            ax = fig.add_subplot(rows, 2 * per_row, 2 * slot + b + 1)
            image = ax.imshow(result.S_maps[slot, b].T, origin="lower", extent=extent, cmap=cmap, norm=norm,
                              aspect="auto", interpolation="nearest")
            _veil(ax, result.viable[k, b], extent)
            _outline(ax, result.viable[k, b], extent, colors="white", linewidths=0.9)
            _outline(ax, result.reachable[k, b], extent, colors="cyan", linewidths=0.8, linestyles="dashed")
            if k < len(motion.times) and motion.branch[k] == b:
                g = np.degrees(np.mod(motion.q[k, :2], 2 * np.pi))
                ax.plot(g[0], g[1], "*", color="white", markeredgecolor="black", markersize=11)
            ax.set_title(f"t = {result.times[k]:g} s, {_BRANCH_LABELS[b]}", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.set_xticks(np.arange(0, 361, 90))
            ax.set_yticks(np.arange(0, 361, 90))
            if b == 0 and slot % per_row == 0:
                ax.set_ylabel("q2 [deg]", fontsize=8)
            if slot >= len(layers) - per_row:
                ax.set_xlabel("q1 [deg]", fontsize=8)
    if image is not None:
        fig.colorbar(image, ax=fig.axes, shrink=0.6, label="AMSIP S (black: S ≤ 0)", extend="min")
    return fig


def _one_gene(result: ReachResult, plt: Any, cmap: Any, norm: Any) -> Any:
    axis = np.degrees(result.map_axes[0])
    step = axis[1] - axis[0] if len(axis) > 1 else 1.0
    times = result.times
    dt = times[1] - times[0] if len(times) > 1 else 1.0
    extent = (times[0] - dt / 2, times[-1] + dt / 2, axis[0] - step / 2, axis[-1] + step / 2)
    fig = plt.figure(figsize=(12, 4.6), layout="constrained")
    motion = result.motion
    image = None
    for b in range(2):
        ax = fig.add_subplot(1, 2, b + 1)
        image = ax.imshow(result.S_maps[:, b, :].T, origin="lower", extent=extent, cmap=cmap, norm=norm,
                          aspect="auto", interpolation="nearest")
        _veil(ax, result.viable[:, b, :], extent)
        _outline(ax, result.viable[:, b, :], extent, colors="white", linewidths=0.9)
        _outline(ax, result.reachable[:, b, :], extent, colors="cyan", linewidths=0.8, linestyles="dashed")
        on = motion.branch == b
        genes = np.degrees(np.mod(motion.q[:, 0], 2 * np.pi))
        ax.plot(motion.times[on], genes[on], "*", color="white", markeredgecolor="black", markersize=7)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("q1 [deg]")
        ax.set_title(f"S(t, q1), {_BRANCH_LABELS[b]}", fontsize=9)
    if image is not None:
        fig.colorbar(image, ax=fig.axes, shrink=0.8, label="AMSIP S (black: S ≤ 0)", extend="min")
    return fig


def plot_reach_motion(result: ReachResult, path: str | os.PathLike[str], *, title: str | None = None) -> Path:
    """Write the best motion (joint angles, S) and the size of the reachable set and viable tube over time.

    Args:
        result: from :func:`previewctl.search.reachability.reach_over_time`.
        path: output image file.
        title: figure title (default: the verdict).

    Returns:
        The path written.
    """
    plt = pyplot()
    motion = result.motion
    fig = plt.figure(figsize=(9, 8), layout="constrained")
    try:
        ax_q, ax_s, ax_n = (fig.add_subplot(3, 1, i) for i in (1, 2, 3))
        for j in range(motion.q.shape[1]):
            ax_q.plot(motion.times, np.degrees(motion.q[:, j]), "-o", markersize=2.5, label=f"q{j + 1}")
        switches = np.flatnonzero(np.diff(motion.branch) != 0)
        for i, k in enumerate(switches):
            ax_q.axvline(0.5 * (motion.times[k] + motion.times[k + 1]), color="grey", linestyle=":",
                         label="elbow switch (β = 0)" if i == 0 else None)
        ax_q.set_ylabel("joint angle [deg]")
        ax_q.legend(fontsize=7, ncol=5, loc="best")
        ax_q.grid(alpha=0.3)
        ax_s.plot(motion.times, motion.S, "-o", markersize=2.5, color="#1f4e9c", label="S along the best motion")
        if np.isfinite(result.best_min_S):
            ax_s.axhline(result.best_min_S, color="#d62728", linestyle="--",
                         label=f"S* = {result.best_min_S:.0f} (best minimum over t ≥ t_1)")
        ax_s.set_ylabel("AMSIP S")
        ax_s.legend(fontsize=7)
        ax_s.grid(alpha=0.3)
        reach = result.reachable.reshape(len(result.times), -1).sum(axis=1)
        viable = result.viable.reshape(len(result.times), -1).sum(axis=1)
        ax_n.semilogy(result.times[1:], np.maximum(reach[1:], 0.8), "-", label="cells reachable from q0")
        ax_n.semilogy(result.times[1:], np.maximum(viable[1:], 0.8), "-", label="viable tube")
        ax_n.set_ylabel("grid cells")
        ax_n.set_xlabel("t [s]")
        for ax in (ax_q, ax_s, ax_n):
            if result.commit_time is not None:
                ax.axvline(result.commit_time, color="#2ca02c", linestyle="--", linewidth=1)
            if result.dead_end is not None:
                ax.axvline(result.dead_end, color="black", linestyle="-", linewidth=1.2)
        if result.commit_time is not None:
            ax_n.plot([], [], color="#2ca02c", linestyle="--", label=f"commit time {result.commit_time:g} s")
        if result.dead_end is not None:
            ax_n.plot([], [], color="black", label=f"dead end {result.dead_end:g} s")
        ax_n.legend(fontsize=7)
        ax_n.grid(alpha=0.3, which="both")
        fig.suptitle(title or _title(result).split("\n")[0], fontsize=10)
        return save_figure(fig, path, dpi=100)
    finally:
        plt.close(fig)
