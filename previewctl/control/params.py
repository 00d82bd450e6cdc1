"""Controller names and parameters: gains, preview times and weights (eqs. 20-21), GA settings.

The one list of controller names is :data:`ControllerName`; :data:`CONTROLLER_NAMES` and
:data:`PREVIEW_MODES` are read from it. The bounds of every parameter are the annotations of
:class:`ControllerParams`' fields: the scenario file's ``[controller]`` table is made from them
(:mod:`previewctl.sim.schema`), and the GA settings are :class:`~previewctl.search.ga.GAOptions`'.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated, Any, Final, Literal, get_args

from pydantic import AfterValidator, BeforeValidator, Field

from previewctl.errors import ParameterError
from previewctl.search.ga import GAOptions, Population
from previewctl.validation import (
    Checked,
    Count,
    Finite,
    Flag,
    Integer,
    NonNegative,
    Positive,
    Text,
    interval,
    invalid,
    table,
    validate,
)

PreviewMode = Literal["single", "multi", "reach"]
"""The controllers that steer the arm towards imaginary arms at future times."""
ControllerName = Literal["none", "qp", "gradient", PreviewMode, "horizon", "oracle"]
"""Every controller: ``none`` (eq. 19 alone), ``qp`` (eq. 19 with no null-space motion, always executed by the
constrained QP: the velocity-damper method of NEO, the peer baseline), ``gradient``, the preview modes, and
``horizon`` (the reachability DP over the preview window, replanned; a sampled search on spatial arms) and
``oracle``, which is non-causal (it reads the whole future): a reference, see :mod:`previewctl.control.laws.follow`."""
ExecutionMode = Literal["qp", "pseudoinverse"]
"""How a controller's eq. 19 command is executed: ``qp`` (a constrained QP with joint limits and collision velocity
dampers, :mod:`previewctl.control.execution`) or ``pseudoinverse`` (the paper's eq. 19 with clamping and scaling)."""
ImaginaryArms = Literal["route", "peaks"]
"""Where coherent ``multi`` puts its imaginary arms: on the route planned as ``reach`` plans it (``route``: where the
plan puts the arm at the preview times), or each on one tracked GA peak (``peaks``, :mod:`previewctl.control.peaks`);
see :mod:`previewctl.control.imaginary`."""
MEASURED: Final = "measured"
"""``plan_latency = "measured"``: each plan arrives after its own measured compute time (see :data:`PlanLatency`)."""


def _latency(value: float | str) -> float | str:
    """A latency in seconds is not negative."""
    if isinstance(value, float) and value < 0:
        raise invalid("must be a time >= 0 [s] or 'measured', got {value}", value=repr(value))
    return value


PlanLatency = Annotated[Finite | Literal["measured"], AfterValidator(_latency)]
"""How long a plan takes to arrive: a fixed time [s], or ``"measured"``: the plan's own CPU time
(``time.process_time``, which a loaded host inflates less than wall time), rounded up to whole control periods; a
reproducible stand-in for planning beside the loop in sweeps, though not bit-reproducible across hosts."""
CONTROLLER_NAMES: tuple[str, ...] = get_args(ControllerName)
EXECUTION_MODES: tuple[str, ...] = get_args(ExecutionMode)
PREVIEW_MODES: tuple[str, ...] = get_args(PreviewMode)
SEEDED_CONTROLLERS: tuple[str, ...] = PREVIEW_MODES
"""The controllers that draw random numbers (their imaginary arms' GA searches); every other controller gives
the same run for every seed."""


def run_seed(name: str, seed: int) -> int:
    """The seed of the run that controller ``name`` makes with ``seed``: ``seed`` itself for the controllers of
    :data:`SEEDED_CONTROLLERS`, 0 for the others (their run is the same for every seed)."""
    return seed if name in SEEDED_CONTROLLERS else 0


FIXED_EXECUTION: dict[str, str] = {"none": "pseudoinverse", "qp": "qp"}
"""The controllers that always run one execution: ``none`` is eq. 19 alone (the pseudo-inverse), ``qp`` the same
law under the constrained QP. Every other controller runs the execution its ``execution`` setting names."""


def execution_of(name: str, params: ControllerParams) -> str:
    """The execution controller ``name`` runs with ``params``: its own (:data:`FIXED_EXECUTION`) or
    ``params.execution``."""
    return FIXED_EXECUTION.get(name, params.execution)


def controller_runs(names: Sequence[str], executions: Sequence[str]) -> list[tuple[str, str]]:
    """The runs of ``names`` × ``executions`` as ``(controller, execution)`` pairs, in order (names outer): a
    controller with its own execution (:data:`FIXED_EXECUTION`) runs under that one only, if it is asked for."""
    return [(name, execution) for name in names for execution in executions
            if FIXED_EXECUTION.get(name, execution) == execution]


SPATIAL_NEIGHBOURS = 16
"""The default ``track_neighbours`` of a spatial arm: mutants of the tracked target bred into each search, since
a spatial arm's GA population (64 individuals, 7 genes projected onto a 4-dimensional self-motion manifold) seldom
holds any other individual near it, so the target would not climb. Planar arms need none. How it was chosen: see
docs/decisions.md#mutants-of-the-tracked-peak-on-spatial-arms."""

PAPER_WEIGHTS: tuple[float, ...] = (0.3, 0.65, 0.05)
"""The paper's three-preview weights ``k_1, k_2, k_3`` (section 7.2)."""

_WEIGHT_SUM_TOL = 1e-9


def _preview_weights(weights: tuple[float, ...]) -> tuple[float, ...]:
    """The rule of eq. 21: ``0 < k_i < 1`` and ``Σ k_i = 1`` (to 1e-9)."""
    if not weights:
        raise invalid("must be a non-empty list of numbers k_i, got []")
    for i, k in enumerate(weights, start=1):
        if not 0.0 < k < 1.0:
            hint = "; for one preview use the 'single' controller" if len(weights) == 1 else ""
            raise invalid("= {weights}: k_{i} = {k} must satisfy 0 < k_i < 1{hint}", weights=list(weights), i=i,
                          k=repr(k), hint=hint)
    total = math.fsum(weights)
    if abs(total - 1.0) > _WEIGHT_SUM_TOL:
        raise invalid("= {weights}: the k_i must sum to 1, they sum to {total}", weights=list(weights),
                      total=repr(total))
    return weights


def _one_or_many(value: object) -> object:
    """A single number ``g`` means ``(g,)``."""
    return (value,) if isinstance(value, (int, float)) and not isinstance(value, bool) else value


Gains = Annotated[tuple[Positive, ...], BeforeValidator(_one_or_many), Field(min_length=1)]
"""One positive gain for every joint, or one per joint velocity."""
PreviewWeights = Annotated[tuple[Finite, ...], AfterValidator(_preview_weights)]
"""The ``k_i`` of eq. 21."""


@dataclass(frozen=True)
class ControllerParams(Checked):
    """Parameters of every controller, in the groups of :data:`SETTING_GROUPS` (eq. 19's tracking, the QP, the
    preview, the GA, the tracked peaks, the planner, the AMSIP gradient) and the mode switches ``execution``,
    ``coherent``, ``imaginary_arms``, ``with_gradient`` and ``hysteresis``.

    Each controller reads the groups and fields it needs; the factory warns about a field set (to other than its
    default) that the chosen controller does not read, and records it (:func:`~previewctl.control.factory.compose`).

    Attributes:
        gain: ``K_v`` of eqs. 20/21 [1/s]: one number or one per velocity coordinate.
        gradient_gain: ``K_g`` of the ``gradient`` mode, ``v = K_g ∇S`` [rad²/s per unit of S]
            (S is in the index's length unit, ~10⁴ for the paper's arm in cm, hence the small default).
        feedback_gain: ``K_p`` on the hand error [1/s].
        step_correction: eq. 19's task term is corrected for the period ``dt`` it is applied over: the hand
            error predicted at ``t + dt`` (forward kinematics of ``q ⊕ q̇ dt``) is brought to what the
            continuous law would leave, ``exp(−K_p dt) e`` (:func:`~previewctl.control.tracking.step_correction`).
            ``False`` is the paper's eq. 19 as printed (``ṙ_d(t) + K_p e`` held over the period).
        damping: ``λ_max`` of the damped least-squares inverse [m/rad] (0 disables damping).
        singular_threshold: ``ε``: damping starts when ``σ_min(J) < ε`` [m/rad].
        velocity_scale: fraction of the URDF joint speed limits that the controller may use, in (0, 1].
        preview_time: ``t̃`` [s], the spacing of the preview times ``t + i t̃``.
        weights: ``k_i`` of eq. 21 (``multi``; ``single`` uses ``k_1 = 1``); ``0 < k_i < 1``, ``Σ = 1``.
        previews: number of preview times of ``multi`` and ``reach``: always ``len(weights)`` (one per ``k_i``);
            ``None`` (the default) or that number, which is then checked.
        population: GA population per imaginary arm.
        elite: GA individuals copied unchanged to the next generation.
        top_k: distinct peaks the GA keeps.
        fd_step: finite-difference step of ``∇S`` [rad].
        ga_options: further :class:`~previewctl.search.ga.GAOptions` fields, as ``(name, value)`` pairs.
        with_gradient: ``single``/``multi`` also add ``K_g ∇S`` (``gradient_gain``) to ``v``.
        coherent: ``single`` keeps its imaginary arm on one tracked peak of the arm's own elbow branch and ramps
            the pull in (:mod:`previewctl.control.peaks`); ``multi`` puts its imaginary arms where
            ``imaginary_arms`` says; ``reach`` plans its moves over a window. ``False`` is the paper's literal
            eq. 20/21 (each frame's argmax of each imaginary arm, any branch) and ``reach``'s straight sweeps.
        imaginary_arms: coherent ``multi``'s imaginary arms: ``"route"``, where the route that coherent ``reach``
            plans puts the arm at the preview times; ``"peaks"``, each on one tracked peak (as ``single``); ``None``
            (the default): ``"route"`` on an arm the planner covers (spatial, or planar with at most 4 joints),
            ``"peaks"`` on other arms. ``"route"`` on an arm the planner does not cover is refused.
        hysteresis: ``reach`` in coherent mode: relative S bonus of the nodes that continue the last route.
        settle_frames: camera frames over which the pull is ramped in after a change of peak.
        track_radius: largest joint-space move [rad] of a peak between two frames to keep its identity.
        track_neighbours: mutants of each tracked peak bred into its search every frame, so that the target climbs
            its peak (:mod:`previewctl.control.peaks`); ``None`` (the default): 16 on spatial arms, 0 on planar
            arms, whose two genes the population already covers.
        replan_period: ``horizon``, coherent ``reach`` and ``multi``: time between two plans [s] (the DP's, or the
            sampled search's on a spatial arm); ``None`` (the default): half the preview time.
        plan_window: ``horizon``, coherent ``reach`` and ``multi``: how far ahead [s] each plan looks; ``None`` (the
            default): to the last preview time, ``previews · preview_time``.
        plan_latency: ``horizon``, coherent ``reach`` and ``multi``: how long [s] a plan takes to arrive, as for a
            planner beside the control loop: a plan made from the state at ``t`` is followed from
            ``t + plan_latency`` (the first one at once); at most the replan period. 0 (the default): within the
            cycle. ``"measured"``: after the plan's own CPU time, rounded up to whole control periods
            (:data:`PlanLatency`); the next plan is then made once it has arrived.
        execution: how the command is executed, one of :data:`EXECUTION_MODES` (``none`` and ``qp`` have their own,
            :data:`FIXED_EXECUTION`).
        task_weight: ``W``, the QP's weight of the hand term against the joint term
            (:mod:`~previewctl.control.execution`).
        slack_weight: when the dampers are infeasible, the penalty on their slacks against the joint term in the
            QP that finds the smallest violation (the hand term is left out of it).
        damper_gain: ``ξ`` [m/s], the approach speed a damper allows at the influence distance.
        influence_distance: ``d_i`` [m], link–obstacle distance below which a damper acts.
        safety_distance: ``d_s`` [m], the distance a damper never lets a link approach closer than; ``< d_i``.
        self_influence_distance: ``d_i`` of the dampers between two links of the arm (its self pairs) [m]: smaller
            than the obstacles' ``influence_distance``, since the arm's own links pass close to each other all the
            time.
        self_safety_distance: ``d_s`` of the self pairs' dampers [m]; ``< self_influence_distance``.
        limit_gain: ``K_l`` of the joint-limit avoidance in the null space [1/s] (0 disables it).
        limit_margin: within this fraction of a joint's range from either limit [-], the null-space avoidance
            acts and the QP brakes the joint towards the limit.
    """

    gain: Gains = (1.0,)
    gradient_gain: Gains = (1e-4,)
    feedback_gain: NonNegative = 5.0
    step_correction: Flag = True
    damping: NonNegative = 0.05
    singular_threshold: Positive = 0.05
    velocity_scale: Annotated[Finite, interval(0, 1, "(]")] = 1.0
    preview_time: Positive = 1.0
    weights: PreviewWeights = PAPER_WEIGHTS
    previews: Count | None = None
    population: Population = 64
    elite: Count = 2
    top_k: Count = 4
    fd_step: Positive = 1e-4
    ga_options: tuple[tuple[Text, Any], ...] = field(default=())
    with_gradient: Flag = False
    coherent: Flag = True
    imaginary_arms: ImaginaryArms | None = None
    hysteresis: NonNegative = 0.2
    settle_frames: Count = 15
    track_radius: Positive = 0.5
    track_neighbours: Annotated[Integer, Field(ge=0)] | None = None
    replan_period: Positive | None = None
    plan_window: Positive | None = None
    plan_latency: PlanLatency = 0.0
    execution: ExecutionMode = "qp"
    task_weight: Positive = 1e4
    slack_weight: Positive = 1e6
    damper_gain: Positive = 1.0
    influence_distance: Positive = 0.3
    safety_distance: NonNegative = 0.02
    self_influence_distance: Positive = 0.1
    self_safety_distance: NonNegative = 0.01
    limit_gain: NonNegative = 1.0
    limit_margin: Annotated[Finite, interval(0, 0.5, "[)")] = 0.1

    def check(self) -> None:
        """``previews`` matches ``weights``, each safety distance below its influence distance, and the GA settings
        together obey :class:`~previewctl.search.ga.GAOptions` (no unknown option, ``elite + top_k < population``)."""
        if self.previews is not None and self.previews != len(self.weights):
            raise ParameterError(f"previews = {self.previews} but weights = {list(self.weights)} has "
                                 f"{len(self.weights)}: multi and reach use one preview per weight k_i; give "
                                 f"{self.previews} weights or leave previews out")
        for safety, influence in (("safety_distance", "influence_distance"),
                                  ("self_safety_distance", "self_influence_distance")):
            if getattr(self, safety) >= getattr(self, influence):
                raise ParameterError(f"{safety} = {getattr(self, safety)} [m] must be smaller than {influence} = "
                                     f"{getattr(self, influence)} [m]")
        more = validate(GA_SETTINGS, dict(self.ga_options), ParameterError, where="ga_options")
        GAOptions(population=self.population, elite=self.elite, top_k=self.top_k,
                  **more.model_dump(exclude_unset=True))

    def neighbours(self, planar: bool) -> int:
        """``track_neighbours``, or when ``None`` its default: 0 on a planar arm, else :data:`SPATIAL_NEIGHBOURS`."""
        if self.track_neighbours is not None:
            return self.track_neighbours
        return 0 if planar else SPATIAL_NEIGHBOURS

    def preview_weights(self, mode: str) -> tuple[float, ...]:
        """The ``k_i`` used by a preview mode: ``(1,)`` for ``single`` (eq. 20), ``weights`` otherwise."""
        return (1.0,) if mode == "single" else self.weights


SETTING_GROUPS: dict[str, tuple[str, ...]] = {
    "tracking": ("feedback_gain", "step_correction", "damping", "singular_threshold", "velocity_scale", "limit_gain",
                 "limit_margin"),
    "qp": ("task_weight", "slack_weight", "damper_gain", "influence_distance", "safety_distance",
           "self_influence_distance", "self_safety_distance"),
    "preview": ("gain", "preview_time", "weights", "previews"),
    "ga": ("population", "elite", "top_k", "ga_options"),
    "peaks": ("track_radius", "settle_frames", "track_neighbours"),
    "plan": ("replan_period", "plan_window", "plan_latency"),
    "gradient": ("gradient_gain", "fd_step"),
}
"""The fields of :class:`ControllerParams` by what reads them (the controllers compose these parts)."""

GA_SETTINGS = table("ga", GAOptions, exclude=("population", "elite", "top_k"))
"""The GA settings besides ``population``, ``elite`` and ``top_k``: ``ga_options``, ``[controller.ga]``."""


@dataclass(frozen=True)
class ControllerSpec:
    """A controller choice: its name (one of :data:`CONTROLLER_NAMES`) and parameters."""

    name: str = "none"
    params: ControllerParams = field(default_factory=ControllerParams)

    def __post_init__(self) -> None:
        """Check the name.

        Raises:
            ParameterError: unknown controller name (lists the valid ones and a near miss).
        """
        validate(ControllerName, self.name, ParameterError, root="controller")
