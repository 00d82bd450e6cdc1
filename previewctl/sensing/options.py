"""What a controller's observed world is made of: :class:`Sensing` (the API, and a scenario's ``[sensing]`` table)."""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Annotated, Any, Literal, get_args

from pydantic import Field

from previewctl.errors import ParameterError, UnknownNameError
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Scene
from previewctl.sensing.predictors import ConstantVelocityKalman, ManoeuvreKalman, Predictor, Stationary
from previewctl.validation import Checked, Integer, NonNegative, Positive, Probability, Text, show

PredictorName = Literal["kalman", "imm", "stationary"]
"""The built-in predictors: :class:`~previewctl.sensing.predictors.ConstantVelocityKalman`,
:class:`~previewctl.sensing.predictors.ManoeuvreKalman` and :class:`~previewctl.sensing.predictors.Stationary`."""
PREDICTORS: tuple[str, ...] = get_args(PredictorName)


@dataclass(frozen=True)
class Sensing(Checked):
    """Obstacles the controller observes instead of reading their motion (:mod:`previewctl.sensing`).

    Attributes:
        predictor: ``"imm"`` (the default: a cruising and a manoeuvring constant-velocity Kalman filter, mixed,
            :class:`~previewctl.sensing.predictors.ManoeuvreKalman` with its own two process noises), ``"kalman"``
            (one constant-velocity Kalman filter), ``"stationary"``, or a
            :class:`~previewctl.sensing.predictors.Predictor` of your own, copied for each obstacle.
        timeout: an obstacle not observed for longer than this [s] (judged at each step's time) is dropped.
        names: the scene's obstacles that are observed; ``None``: every moving one (static ones stay known, like a
            planning scene). They enter the controller's scene when first observed. Any other name observed with a
            shape is added.
        process_noise: the ``q`` of ``kalman`` (white-noise acceleration [m²/s³]) and ``stationary`` (random-walk
            velocity [m²/s]); ``imm`` keeps its own two.
        measurement_noise: the standard deviation ``r`` [m] of an observed position.
        velocity_noise: the standard deviation [m/s] of an observed velocity (``kalman``, ``imm``).
        initial_speed: the standard deviation [m/s] of an obstacle's velocity before it is known (``kalman``, ``imm``).
        confidence: ``k`` of the margin ``min(cap, k σ(t))`` [m] by which a predicted obstacle is inflated.
        margin_cap: ``cap`` [m] of that margin.
        rate: the simulator's observations per obstacle per second [Hz] (:mod:`previewctl.sim.sensor`).
        noise: the standard deviation [m] of the Gaussian noise the simulator adds to each observed position.
        latency: the time [s] between an observation and its delivery to the controller in the simulator.
        history: how long [s] before ``t = 0`` the simulator's sensor already observes (a robot's camera runs before
            its task starts): an obstacle already moving then (its motion's own ``t < 0``) is seen moving, and the
            controller starts with a velocity estimate; 0: observations start with the run.
        dropout: the probability that the simulator drops an observation.
        seed: the seed of the simulator's noise and dropouts.
    """

    predictor: PredictorName | Any = "imm"
    timeout: Positive = 1.0
    names: tuple[Text, ...] | None = None
    process_noise: NonNegative = 0.01
    measurement_noise: Positive = 0.005
    velocity_noise: Positive = 0.05
    initial_speed: Positive = 1.0
    confidence: NonNegative = 2.0
    margin_cap: NonNegative = 0.03
    rate: Positive = 30.0
    noise: NonNegative = 0.005
    latency: NonNegative = 0.05
    history: NonNegative = 0.0
    dropout: Probability = 0.0
    seed: Annotated[Integer, Field(ge=0)] = 0

    def check(self) -> None:
        """The predictor is a built-in name or a :class:`~previewctl.sensing.predictors.Predictor`."""
        predictor = self.predictor
        if isinstance(predictor, str):
            if predictor not in PREDICTORS:
                raise UnknownNameError("predictor", predictor, PREDICTORS)
        elif not isinstance(predictor, Predictor):
            raise ParameterError(f"predictor must be one of {', '.join(PREDICTORS)} or a Predictor (update, predict, "
                                 f"sigma), got {type(predictor).__name__} {show(predictor)}")

    def observed(self, scene: Scene) -> tuple[str, ...]:
        """The names of ``scene``'s obstacles that are observed: :attr:`names`, or every moving one."""
        if self.names is not None:
            return self.names
        return tuple(o.name for o in scene.obstacles if not isinstance(o.motion, Static))

    def new_predictor(self) -> Predictor:
        """A fresh predictor for one obstacle."""
        if self.predictor == "kalman":
            return ConstantVelocityKalman(self.process_noise, self.measurement_noise, self.velocity_noise,
                                          self.initial_speed)
        if self.predictor == "imm":
            return ManoeuvreKalman(r=self.measurement_noise, velocity_noise=self.velocity_noise,
                                   initial_speed=self.initial_speed)
        if self.predictor == "stationary":
            return Stationary(self.process_noise, self.measurement_noise)
        return copy.deepcopy(self.predictor)  # type: ignore[no-any-return]

