"""The options of :func:`~previewctl.search.reachability.reach_over_time` and its typed error."""

from __future__ import annotations

import math
from dataclasses import dataclass

from previewctl.errors import ConfigurationError


class PlanarOnlyError(ConfigurationError):
    """Reachability over time is built for planar arms (closed-form redundancy grid) only."""


@dataclass(frozen=True)
class ReachOptions:
    """Grid, time step and transition model of :func:`~previewctl.search.reachability.reach_over_time`.

    Attributes:
        resolution_deg: gene grid step ``h`` [deg]: a gene with finite limits gets ``floor(range / h) + 1``
            cells from its lower limit, one without ``round(360 / h)`` periodic cells.
        steps: number of time steps ``N`` (``N + 1`` layers); ``Δt = duration / N`` [s].
        max_step_cells: cap on the gene cells moved per step (the work grows as ``(2 r + 1)^g``).
        s_min: feasible cells have ``S > s_min`` (0: collision-free and reachable).
        velocity_scale: fraction of the URDF joint speed limits the motion may use, in (0, 1].
        obstacle_substeps: samples per step used to bound the obstacles' speed.
        cross_adjacency_deg: the two elbow branches of one grid cell count as adjacent (one family)
            where the elbow angle ``|β|`` is at most this [deg] (the stretched wrist).
        map_times: how many whole-grid S maps to keep for the figures (spread over the layers; 0: none).
            Arms with one gene keep every layer's map.
        start_families: also find the start families (components at ``t_0`` and their fate). This
            evaluates the whole grid at every time and connects every feasible cell, which the DP from
            ``q0`` otherwise avoids (it evaluates only the cells one step away from the reachable set).
    """

    resolution_deg: float = 2.0
    steps: int = 50
    max_step_cells: int = 3
    s_min: float = 0.0
    velocity_scale: float = 1.0
    obstacle_substeps: int = 8
    cross_adjacency_deg: float = 10.0
    map_times: int = 10
    start_families: bool = False

    def __post_init__(self) -> None:
        """Validate every field.

        Raises:
            ConfigurationError: a bad value (the message names the field and the value).
        """
        if not (isinstance(self.resolution_deg, (int, float)) and math.isfinite(self.resolution_deg)
                and 0 < self.resolution_deg <= 90):
            raise ConfigurationError(f"resolution_deg must lie in (0, 90] [deg], got {self.resolution_deg!r}")
        for name, low in (("steps", 1), ("max_step_cells", 1), ("obstacle_substeps", 1), ("map_times", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ConfigurationError(f"{name} must be an integer >= {low}, got {value!r}")
        if not (isinstance(self.s_min, (int, float)) and math.isfinite(self.s_min) and self.s_min >= 0):
            raise ConfigurationError(f"s_min must be a finite number >= 0, got {self.s_min!r}")
        if not (isinstance(self.velocity_scale, (int, float)) and math.isfinite(self.velocity_scale)
                and 0 < self.velocity_scale <= 1):
            raise ConfigurationError(f"velocity_scale must lie in (0, 1], got {self.velocity_scale!r}")
        if not (isinstance(self.cross_adjacency_deg, (int, float)) and 0 <= self.cross_adjacency_deg <= 180):
            raise ConfigurationError(
                f"cross_adjacency_deg must lie in [0, 180] [deg], got {self.cross_adjacency_deg!r}")
        if not isinstance(self.start_families, bool):
            raise ConfigurationError(f"start_families must be true or false, got {self.start_families!r}")
