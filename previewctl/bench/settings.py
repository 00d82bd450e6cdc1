"""What every scene of a sweep shares: :class:`SceneSettings`, read by the scene generators and the witness."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

from previewctl.errors import ParameterError
from previewctl.validation import Checked, Count, Flag, NonNegative, Positive

MotionKind = Literal["constant", "surprise"]
"""How the crossing obstacles of bench scenes move: at ``constant`` velocity, or with a ``surprise``
(:mod:`previewctl.bench.surprises`)."""
MOTION_KINDS: tuple[str, ...] = get_args(MotionKind)


@dataclass(frozen=True)
class SceneSettings(Checked):
    """What every scene of a sweep shares; every field is checked when made (a bad one raises
    :class:`~previewctl.errors.ParameterError` naming it).

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
        motions: how the crossing obstacles move, one of :data:`MOTION_KINDS`.
        history: how long [s] before ``t = 0`` the crossing obstacles already move, and the sensor of the observed
            runs already observes them (:attr:`Sensing.history <previewctl.sensing.options.Sensing.history>`), as a
            robot's camera runs before its task starts; every run from ``t = 0`` on sees the same obstacles. 0: both
            start with the run (the obstacles stand still before it).
    """

    duration: Positive | None = None
    dt: Positive = 0.01
    max_draws: Count = 30
    witness_resolution_deg: Positive = 4.0
    witness_period: Positive = 0.25
    witness_samples: Count = 256
    witness_follow: Flag = True
    witness_tolerance: Positive = 1e-3
    motions: MotionKind = "constant"
    history: NonNegative = 0.0

    def check(self) -> None:
        """A run of at least two control periods (each field is checked by its annotation first).

        Raises:
            ParameterError: a duration shorter than ``2 dt``.
        """
        if self.duration is not None and self.duration < 2 * self.dt:
            raise ParameterError(f"duration must be at least two control periods ({2 * self.dt:g} s), "
                                 f"got {self.duration!r}")
