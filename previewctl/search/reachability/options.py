"""The options of :func:`~previewctl.search.reachability.reach_over_time` and its typed error."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from pydantic import Field

from previewctl.errors import ConfigurationError
from previewctl.validation import Checked, Count, Finite, Flag, Integer, NonNegative, interval


class PlanarOnlyError(ConfigurationError):
    """Reachability over time is built for planar arms (closed-form redundancy grid) only."""


@dataclass(frozen=True)
class ReachOptions(Checked):
    """Grid, time step and transition model of :func:`~previewctl.search.reachability.reach_over_time`; every
    field is checked when made (a bad one raises :class:`~previewctl.errors.ConfigurationError` naming it).

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

    error = ConfigurationError

    resolution_deg: Annotated[Finite, interval(0, 90, "(]")] = 2.0
    steps: Count = 50
    max_step_cells: Count = 3
    s_min: NonNegative = 0.0
    velocity_scale: Annotated[Finite, interval(0, 1, "(]")] = 1.0
    obstacle_substeps: Count = 8
    cross_adjacency_deg: Annotated[Finite, interval(0, 180)] = 10.0
    map_times: Annotated[Integer, Field(ge=0)] = 10
    start_families: Flag = False
