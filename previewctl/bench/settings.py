"""What every scene of a sweep shares: :class:`SceneSettings`, read by the scene generators and the witness."""

from __future__ import annotations

import math
from dataclasses import dataclass

from previewctl.errors import ParameterError


@dataclass(frozen=True)
class SceneSettings:
    """What every scene of a sweep shares.

    Attributes:
        duration: run length [s] (``None``: the profile's).
        dt: control period [s].
        max_draws: most draws per scene the witness may reject.
        witness_resolution_deg: planar witness: the reachability DP's grid step [deg] (sound at any step:
            a coarser grid only finds fewer motions, so it rejects more).
        witness_period: time between witness samples [s] (DP step for planar; check period for spatial arms).
        witness_samples: spatial witness: Halton samples of the redundancy space per check.
        witness_follow: the ``oracle`` must also follow a found motion in a run (the scene's settings and execution,
            exact check) without collision and with the hand within ``witness_tolerance``: the DP's on planar arms,
            the sampled search's on spatial ones (without it, a spatial scene passes on the necessary check alone).
        witness_tolerance: the largest hand error [m] of that run.
    """

    duration: float | None = None
    dt: float = 0.01
    max_draws: int = 30
    witness_resolution_deg: float = 4.0
    witness_period: float = 0.25
    witness_samples: int = 256
    witness_follow: bool = True
    witness_tolerance: float = 1e-3

    def __post_init__(self) -> None:
        """Check the values.

        Raises:
            ParameterError: a non-positive duration, period or step, or fewer than one draw or sample.
        """
        for name in ("dt", "witness_resolution_deg", "witness_period", "witness_tolerance"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise ParameterError(f"{name} must be > 0, got {getattr(self, name)!r}")
        if self.duration is not None and not (math.isfinite(self.duration) and self.duration >= 2 * self.dt):
            raise ParameterError(f"duration must be at least two control periods ({2 * self.dt:g} s), "
                                 f"got {self.duration!r}")
        for name in ("max_draws", "witness_samples"):
            if getattr(self, name) < 1:
                raise ParameterError(f"{name} must be >= 1, got {getattr(self, name)!r}")
