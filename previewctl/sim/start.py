"""The start check: a scenario whose arm starts in collision is bad input, refused before anything runs.

The loop (:mod:`previewctl.sim.loop`) checks every step exactly, on the robot reloaded with
``geometry="mesh"``; a start ``q0`` that already collides there would make a run that fails at
``t = 0``, which says nothing about the controller. :func:`check_start` refuses it with a
:class:`~previewctl.errors.StartCollisionError` naming every colliding pair and its penetration
depth; when a pair is one of the hand's links and an obstacle that is not a work surface, the
message says to mark the obstacle ``work_surface = true`` (the hand may touch the object it works
on, :class:`~previewctl.scene.shapes.Obstacle`).

:func:`~previewctl.sim.loop.simulate` calls it before its first step, and so do ``previewctl run`` and
``previewctl paper`` before they check or create their output folder.

Two kinds of pairs are looked at (:data:`CONTACT_SOURCES`): a guarded link against an obstacle, and two links of the
arm against each other (its self pairs). Adding a kind: write a :data:`ContactSource` that returns its pairs as
:class:`Contact` and add it to :data:`CONTACT_SOURCES`; the refusal and its message follow.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pinocchio as pin

from previewctl.errors import StartCollisionError
from previewctl.index.evaluator import Evaluation, Evaluator
from previewctl.sim.scenario import Scenario
from previewctl.types import Array

__all__ = ["CONTACT_SOURCES", "Contact", "ContactSource", "check_start", "exact_evaluator", "obstacle_contacts",
           "self_contacts", "start_contacts", "start_message"]

START_TIME = 0.0
"""The time [s] of the loop's first step, at which the start is checked."""
SHOWN_CONTACTS = 4
"""Most pairs a message lists (the deepest first); the others are counted."""
PATH_AGREEMENT = 1e-5
"""How far [m] the planar fast path and Coal may disagree about a distance (a few 1e-6 m for a cylinder)."""


@dataclass(frozen=True)
class Contact:
    """A pair in collision: a guarded link and what it touches.

    Attributes:
        link: the guarded link.
        other: the obstacle's name (``kind="obstacle"``) or the other link's (``kind="link"``).
        distance: signed distance [m], ``<= 0``: minus the penetration depth.
        kind: what ``other`` is.
        hand: ``link`` moves with the hand (:attr:`Robot.hand_links <previewctl.robot.model.Robot.hand_links>`).
        work_surface: ``other`` is an obstacle marked ``work_surface`` (never true when a pair is reported: the
            hand's links are not paired with a work surface).
    """

    link: str
    other: str
    distance: float
    kind: Literal["obstacle", "link"] = "obstacle"
    hand: bool = False
    work_surface: bool = False


ContactSource = Callable[[Evaluator, Array, float, Evaluation], list[Contact]]
"""``source(evaluator, q, t, check)``: the pairs in collision at configuration ``q`` ``(nq,)`` and time ``t`` [s],
given ``check``, the evaluator's :class:`~previewctl.index.evaluator.Evaluation` of ``q`` (batch of one)."""


def exact_evaluator(scenario: Scenario) -> Evaluator:
    """The evaluator of the run's exact check: the robot reloaded with ``geometry="mesh"`` (the exact URDF geometry;
    for planar4 the same cylinders) in the scenario's scene."""
    return Evaluator(scenario.exact_robot(), scenario.scene, scenario.index, scenario.potential)


def obstacle_contacts(evaluator: Evaluator, q: Array, t: float, check: Evaluation) -> list[Contact]:
    """The (guarded link, obstacle) pairs in collision, one per link and obstacle (its deepest geometry).

    The links in collision are those of ``check`` (the verdict the loop stops on, planar fast path included);
    each is paired with the obstacles its per-pair distances (Coal) put at ``<= 0``, or, should the two paths
    disagree at a touch (by at most :data:`PATH_AGREEMENT`), with its nearest obstacle at the distance of
    ``check``. A link in collision with no obstacle that near gets no pair here (another source's, e.g. a
    self-collision folded into ``check``).
    """
    colliding = np.flatnonzero(check.link_distances[0] <= 0.0)
    if not colliding.size:
        return []
    robot, clearance, scene = evaluator.robot, evaluator.clearance, evaluator.scene
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    clearance.set_time(t)
    pairs = np.array(clearance.pair_distances(data))
    hand = set(robot.hand_links)
    deepest: dict[tuple[str, str], Contact] = {}
    for link in colliding:
        mine = np.flatnonzero(clearance.pair_links == link)
        hits = [(int(p), float(pairs[p])) for p in mine if pairs[p] <= 0.0]
        if not hits and mine.size and pairs[mine].min() <= PATH_AGREEMENT:
            hits = [(int(mine[np.argmin(pairs[mine])]), float(check.link_distances[0, link]))]
        name = robot.guarded_links[link]
        for pair, distance in hits:
            obstacle = scene.obstacles[clearance.pair_obstacles[pair]]
            contact = Contact(name, obstacle.name, distance, "obstacle", name in hand, obstacle.work_surface)
            key = (name, obstacle.name)
            if key not in deepest or distance < deepest[key].distance:
                deepest[key] = contact
    return list(deepest.values())


def self_contacts(evaluator: Evaluator, q: Array, t: float, check: Evaluation) -> list[Contact]:
    """The self pairs in collision (two links of the arm, ``kind="link"``), one per link pair (its deepest geometry
    pair), from the self pairs' exact distances (``robot.self_pairs``, on the evaluator's geometry)."""
    if not check.self_collision[0]:
        return []
    robot = evaluator.robot
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    found = evaluator.clearance.self_witnesses(data, within=PATH_AGREEMENT)
    hand = set(robot.hand_links)
    deepest: dict[tuple[str, str], Contact] = {}
    for pair, distance in zip(found.pairs, found.distance, strict=True):
        if distance > 0.0:
            continue
        a, b = robot.self_pairs.pair_names(int(pair))
        if (a, b) not in deepest or distance < deepest[(a, b)].distance:
            deepest[(a, b)] = Contact(a, b, float(distance), "link", a in hand or b in hand)
    return list(deepest.values())


CONTACT_SOURCES: tuple[ContactSource, ...] = (obstacle_contacts, self_contacts)
"""Every kind of pair the start check looks at: the arm against obstacles, and against itself."""


def start_contacts(evaluator: Evaluator, q: Array, t: float = START_TIME) -> tuple[Evaluation, list[Contact]]:
    """The evaluation of ``q`` ``(nq,)`` at time ``t`` [s] and every pair of :data:`CONTACT_SOURCES` in collision,
    the deepest first."""
    q = np.asarray(q, dtype=float)
    check = evaluator(q[None, :], t)
    contacts = [c for source in CONTACT_SOURCES for c in source(evaluator, q, t, check)]
    return check, sorted(contacts, key=lambda c: c.distance)


def check_start(scenario: Scenario, evaluator: Evaluator | None = None) -> None:
    """Refuse a scenario whose start configuration collides at the loop's first step (``t = 0``).

    Args:
        scenario: the run.
        evaluator: the run's exact evaluator (default: :func:`exact_evaluator`; pass the one the run uses).

    Raises:
        StartCollisionError: ``scenario.q0`` in collision; the message names every pair (the deepest
            :data:`SHOWN_CONTACTS`) and its penetration, and what to change.
    """
    evaluator = exact_evaluator(scenario) if evaluator is None else evaluator
    check, contacts = start_contacts(evaluator, scenario.q0, START_TIME)
    if contacts or check.collision[0]:
        origin = str(scenario.source) if scenario.source is not None else f"scenario {scenario.name!r}"
        raise StartCollisionError(f"{origin}: {start_message(contacts)}",
                                  [(c.link, c.other, c.distance) for c in contacts])


def start_message(contacts: list[Contact]) -> str:
    """What :func:`check_start` says about ``contacts`` (the deepest first): the pairs, then what to change."""
    shown = [_pair(c) for c in contacts[:SHOWN_CONTACTS]]
    if len(contacts) > SHOWN_CONTACTS:
        shown.append(f"and {len(contacts) - SHOWN_CONTACTS} more")
    pairs = ", ".join(shown) if shown else "a guarded link (no pair named)"
    text = f"the start configuration robot.q0 collides at t = {START_TIME:g} s (exact geometry): {pairs}; "
    held_by = [c for c in contacts if c.kind == "obstacle" and c.hand and not c.work_surface]
    held = list(dict.fromkeys(c.other for c in held_by))
    if held:
        links = list(dict.fromkeys(c.link for c in held_by))
        one_link, one = len(links) == 1, len(held) == 1
        text += (f"{'link' if one_link else 'links'} {', '.join(map(repr, links))} "
                 f"{'moves' if one_link else 'move'} with the hand: if the hand works on "
                 f"{', '.join(map(repr, held))} (traces or touches {'it' if one else 'them'}), mark "
                 f"{'that obstacle' if one else 'those obstacles'} work_surface = true in [[obstacles]] (the hand "
                 "may touch the object it works on); otherwise ")
    moved = "robot.q0" if contacts and all(c.kind == "link" for c in contacts) else "robot.q0 or the obstacle"
    return text + (f"move {moved}, or start from robot.q0 = \"auto\" (previewctl run --q0 auto: the best "
                   "collision-free start at the first waypoint)")


def _pair(contact: Contact) -> str:
    """``link 'link2' and obstacle 'ball' (penetration 12.50 mm)``."""
    depth = f"penetration {-contact.distance * 1e3:.2f} mm" if contact.distance < 0 else "touching"
    if contact.kind == "link":
        return f"links {contact.link!r} and {contact.other!r} ({depth})"
    return f"link {contact.link!r} and obstacle {contact.other!r} ({depth})"
