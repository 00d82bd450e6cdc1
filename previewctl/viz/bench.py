"""The benchmark's success-rate figure: one panel per robot, one bar per controller and execution mode."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from previewctl.files import save_figure
from previewctl.viz.drawing import pyplot


def plot_success(rates: Mapping[str, Mapping[tuple[str, str], float]], path: str | os.PathLike[str],
                 *, label: str = "success (< 1 mm, collision-free)") -> Path:
    """Bar chart of success rates.

    Args:
        rates: per robot, ``(controller, execution) -> rate`` in [0, 1].
        path: the image file (format from the suffix).
        label: the y axis label.
    """
    plt = pyplot()
    robots = list(rates)
    fig, axes = plt.subplots(1, max(1, len(robots)), figsize=(5.5 * max(1, len(robots)), 3.8), squeeze=False,
                             layout="constrained")
    try:
        for ax, robot in zip(axes[0], robots, strict=False):
            table = rates[robot]
            controllers = list(dict.fromkeys(c for c, _ in table))
            executions = list(dict.fromkeys(e for _, e in table))
            width = 0.8 / max(1, len(executions))
            x = np.arange(len(controllers))
            for i, execution in enumerate(executions):
                values = [100 * table.get((c, execution), np.nan) for c in controllers]
                ax.bar(x + (i - (len(executions) - 1) / 2) * width, values, width, label=execution)
            ax.set_xticks(x, controllers, rotation=30)
            ax.set_ylim(0, 100)
            ax.set_title(robot)
            ax.set_ylabel(f"{label} [%]")
            ax.grid(axis="y", alpha=0.3)
            ax.legend(title="execution", fontsize=8)
        return save_figure(fig, path, dpi=100)
    finally:
        plt.close(fig)
