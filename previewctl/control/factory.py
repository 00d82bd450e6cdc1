"""Building a controller by name: ``none``, ``gradient``, ``single``, ``multi``, ``reach``, ``oracle`` (non-causal)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

import numpy as np

from previewctl.control.base import Controller
from previewctl.control.gradient import GradientController
from previewctl.control.params import ControllerParams, ControllerSpec
from previewctl.control.preview import PreviewController, SearchFactory, SearchLike
from previewctl.control.reach import ReachController
from previewctl.control.tracking import TrackingController
from previewctl.errors import ConfigurationError
from previewctl.index.evaluator import Evaluator
from previewctl.robot.model import Robot
from previewctl.search.ga import OneStepGA
from previewctl.search.maps import redundancy_map

ControllerName = Literal["none", "gradient", "single", "multi", "reach", "oracle"]


def make_controller(
    spec: ControllerSpec,
    robot: Robot,
    evaluator: Evaluator,
    rng: np.random.Generator,
    *,
    search_factory: SearchFactory | None = None,
) -> Controller:
    """Build the controller ``spec`` names.

    Args:
        spec: name and parameters.
        robot: the arm (the search robot: convex geometry).
        evaluator: AMSIP evaluator for the gradient and the searches.
        rng: random generator; each imaginary arm gets an independent child stream.
        search_factory: ``factory(i, rng_i)`` building the search of preview ``i``; default: a
            :class:`previewctl.search.ga.OneStepGA` over :func:`previewctl.search.maps.redundancy_map`.
    """
    params = spec.params
    if spec.name == "none":
        return TrackingController(robot, params)
    if spec.name == "gradient":
        return GradientController(robot, evaluator, params)
    if spec.name == "oracle":  # non-causal reference: plans over the whole future at its first command
        from previewctl.control.oracle import OracleController

        return OracleController(robot, params, evaluator)
    mode = "multi" if spec.name == "reach" else spec.name
    count = len(params.preview_weights(mode))
    factory = search_factory or _ga_factory(robot, evaluator, params, spec.name)
    streams = rng.spawn(count)
    searches = [factory(i, streams[i]) for i in range(count)]
    if spec.name == "reach":
        return ReachController(robot, params, evaluator, searches, redundancy_map(robot))
    return PreviewController(robot, params, spec.name, searches, evaluator)


def _ga_factory(robot: Robot, evaluator: Evaluator, params: ControllerParams, mode: str) -> SearchFactory:
    """The default search factory: one 1-step GA per imaginary arm."""
    redundancy = redundancy_map(robot)
    options: Mapping[str, Any] = dict(params.ga_options)

    def factory(i: int, rng: np.random.Generator) -> SearchLike:
        try:
            ga: SearchLike = OneStepGA(
                robot, evaluator, redundancy, rng,
                population=params.population, elite=params.elite, top_k=params.top_k, **options,
            )
        except TypeError as exc:
            raise ConfigurationError(f"controller GA options {dict(options)!r} rejected: {exc}") from exc
        return ga

    return factory
