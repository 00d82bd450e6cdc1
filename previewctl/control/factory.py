"""Resolved-rate control of the hand with a null-space input (paper eq. 19) and its preview modes.

Every controller computes the joint velocity of eq. 19 with hand-position feedback,

    q̇ = J#(ṙ_d + K_p (r_d − r)) + (I − J⁺J) v,

and differs only in the null-space input ``v``:

* ``none``: ``v = 0`` (minimum-norm tracking);
* ``gradient``: ``v = K_g ∇_q S`` (local null-space ascent of the AMSIP; ``∇S`` by central finite
  differences of the :class:`~previewctl.amsip.Evaluator`, one batch of ``2 nv`` configurations);
* ``single`` (eq. 20): ``v = K_v (q̃(t + t̃) − q)``;
* ``multi`` (eq. 21): ``v = K_v (Σ_i k_i q̃(t + i t̃) − q)``, ``0 < k_i < 1``, ``Σ k_i = 1``;
* ``reach``: a route of peaks through the future (not built yet).

``with_gradient`` (off by default; not in the paper) adds the local ascent ``K_g ∇_q S`` of
``gradient`` to the null-space input of ``single`` and ``multi``. The preview pull heads for the
imaginary arms' optima, which on a spatial arm may lie radians away. The local term keeps the
current configuration clear of an obstacle meanwhile.

The preview modes get their imaginary arms ``q̃`` from a 1-step GA (:mod:`previewctl.search`), one per
preview time, which runs one generation per camera frame.

Details of eq. 19 as built:

* ``J`` is the task Jacobian (planar: 2 rows, position: 3, pose: 6 -- linear then angular, world
  aligned). For a pose task the error is ``[p_d − p; log3(R_d Rᵀ)]`` and ``ṙ_d = [ṗ_d; 0]``.
* ``J#`` is a damped least-squares inverse: with ``J = U Σ Vᵀ`` and ``σ_min`` its smallest singular
  value, ``J# = V diag(σ / (σ² + λ²)) Uᵀ`` where

      λ² = 0                                   if σ_min ≥ ε,
      λ² = (1 − (σ_min / ε)²) λ_max²           otherwise                (Maciejewski & Klein),

  ``ε = singular_threshold`` [m/rad] and ``λ_max = damping`` [m/rad]. Away from singularities this is
  the exact pseudo-inverse; near one the damping grows smoothly and keeps ``q̇`` bounded.
* The null-space projector ``N = I − J⁺J`` uses the *undamped* pseudo-inverse, so ``J N v = 0``
  exactly: the null-space term never moves the hand.
* Task priority: the null-space term is first scaled by the largest ``α`` in [0, 1] for which
  ``q̇_task + α N v`` respects the speed limits (``α = 0`` if ``q̇_task`` alone does not), so the
  avoidance motion never slows the hand down; ``α`` is reported as ``null_scale``.
* Limits, in this order: (1) position limits -- each ``q̇_j`` is clamped to
  ``[(lo_j − q_j)/dt, (hi_j − q_j)/dt]`` so that ``q + q̇ dt`` stays within the limits (joints with
  ``nq = nv`` and finite limits only); (2) velocity limits -- the whole ``q̇`` is scaled by
  ``s = min(1, min_j q̇max_j / |q̇_j|)``, which keeps its direction and never raises ``|q̇_j|`` above
  ``velocity_scale · q̇max_j``. A non-finite or non-positive URDF speed limit counts as no limit.
  Scaling after clamping keeps the position bounds (the interval contains 0).
* For the preview modes the configuration error is taken in the tangent space,
  ``v = K_v Σ_i k_i (q̃_i ⊖ q)`` (``pin.difference``), which equals eq. 21 for ordinary joints because
  ``Σ k_i = 1``; for revolute joints whose range spans a full turn or more, each difference is
  wrapped into ``(−π, π]`` (the same physical target, reached the short way).
"""

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

ControllerName = Literal["none", "gradient", "single", "multi", "reach"]


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
            :class:`previewctl.search.OneStepGA` over :func:`previewctl.redundancy.redundancy_map`.
    """
    params = spec.params
    if spec.name == "none":
        return TrackingController(robot, params)
    if spec.name == "gradient":
        return GradientController(robot, evaluator, params)
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
