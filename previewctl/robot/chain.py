"""Which joints of a URDF tree are the arm: floating bases and end-effector joints are locked, the rest
must be one serial chain from the base to the hand.

* floating base: a free-flyer or planar joint (a mobile base, a drone, a legged robot's trunk). It is
  always locked: previewctl drives fixed-base arms.
* end-effector joints: a joint whose name says it moves a gripper, a finger, a jaw, a thumb, a knuckle
  or a hand (``jointGripper``, ``panda_finger_joint1``, ``hand_index_flex_1_joint``), two or more leaf
  joints on one parent (unnamed fingers), and every joint below them. Locked by default: opening the
  jaw is not redundancy of the arm.
* arm: the remaining joints. They must lie on one path from the root (a serial chain); a tree that
  branches (legs, two arms, a head) or has no joint left (a drone) is not an arm, and is refused with
  the reason. ``lock=[...]`` chooses the locked joints explicitly (floating bases stay locked).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import pinocchio as pin

from previewctl.errors import RobotLoadError

FLOATING_JOINTS = ("JointModelFreeFlyer", "JointModelPlanar")
"""Pinocchio joint types that make a floating (or mobile) base."""
END_EFFECTOR_HINTS = ("gripper", "finger", "jaw", "thumb", "knuckle", "hand")
"""Words in a joint name that mark it as an end-effector joint (case-insensitive)."""


@dataclass(frozen=True)
class ArmSplit:
    """The joints of a full model (Pinocchio ids), sorted into the arm and the locked ones.

    Attributes:
        arm: the serial chain, root first.
        floating: floating-base joints (always locked).
        end_effector: gripper and finger joints (locked by default).
        locked: every joint that is not in ``arm``.
    """

    arm: tuple[int, ...]
    floating: tuple[int, ...]
    end_effector: tuple[int, ...]
    locked: tuple[int, ...]


def split_joints(name: str, model: pin.Model, lock: Iterable[str] | None) -> ArmSplit:
    """Sort ``model``'s joints (``lock``: the joints to lock instead of the end-effector ones).

    Raises:
        RobotLoadError: no arm joint is left, or the arm joints branch (with the chains found).
    """
    joints = range(1, model.njoints)
    floating = tuple(j for j in joints if model.joints[j].shortname() in FLOATING_JOINTS)
    effector = _end_effector_joints(model)
    chosen = set(effector) if lock is None else {int(model.getJointId(n)) for n in lock}
    locked = tuple(j for j in joints if j in chosen or j in floating)
    arm = tuple(j for j in joints if j not in locked)
    if not arm:
        raise RobotLoadError(f"robot {name!r} is not an arm: no joint is left to move once "
                             f"{_describe(model, floating, effector, locked)} are locked")
    _check_serial(name, model, arm)
    return ArmSplit(arm, floating, tuple(sorted(effector)), locked)


@dataclass(frozen=True)
class HandFrames:
    """Frame names that guide the default hand frame.

    Attributes:
        bases: the links a locked end-effector joint hangs from (a gripper's base, a flange).
        excluded: the frames that move with a locked end-effector joint (a jaw, a fingertip).
    """

    bases: frozenset[str]
    excluded: frozenset[str]


def hand_frames(model: pin.Model, split: ArmSplit) -> HandFrames:
    """The :class:`HandFrames` of ``model`` (the full model ``split`` was made from)."""
    effector = set(split.end_effector) - set(split.arm)
    roots = [j for j in effector if int(model.parents[j]) in split.arm]
    bases = set()
    for j in roots:
        frame = model.frames[model.getFrameId(model.names[j], pin.FrameType.JOINT)]
        bases.add(str(model.frames[int(frame.parentFrame)].name))
    excluded = {str(f.name) for f in model.frames if int(f.parentJoint) in effector}
    return HandFrames(frozenset(bases), frozenset(excluded))


def _end_effector_joints(model: pin.Model) -> set[int]:
    """Joints named like a gripper or finger, leaf siblings (two or more), and every joint below them."""
    children = {j: [int(c) for c in model.children[j]] for j in range(model.njoints)}
    marked = {j for j in range(1, model.njoints) if any(h in model.names[j].lower() for h in END_EFFECTOR_HINTS)}
    for kids in children.values():
        if len(kids) > 1 and all(not children[c] for c in kids):
            marked.update(kids)
    return {j for j in range(1, model.njoints) if marked & {int(s) for s in model.supports[j]}}


def _check_serial(name: str, model: pin.Model, arm: tuple[int, ...]) -> None:
    """Refuse arm joints that do not lie on one root-to-leaf path, naming the chains."""
    members = set(arm)
    ends = [j for j in arm if not any(j in model.supports[k] for k in members - {j})]
    if len(ends) == 1:
        return
    chains = []
    for end in ends[:6]:
        chain = [int(s) for s in model.supports[end] if int(s) in members]
        chains.append(f"{model.names[chain[0]]}..{model.names[chain[-1]]}" if len(chain) > 1 else model.names[end])
    more = ", ..." if len(ends) > 6 else ""
    raise RobotLoadError(f"robot {name!r} is not a serial arm: its joints branch into {len(ends)} chains "
                         f"({', '.join(chains)}{more}); keep one with lock=[the joints of the others]")


def _describe(model: pin.Model, floating: tuple[int, ...], effector: set[int], locked: tuple[int, ...]) -> str:
    """``"the floating base root_joint and the gripper joints a, b"``: what was locked and why."""
    parts = []
    if floating:
        parts.append("the floating base " + ", ".join(model.names[j] for j in floating))
    grippers = [j for j in locked if j in effector and j not in floating]
    if grippers:
        parts.append("the end-effector joints " + ", ".join(model.names[j] for j in grippers[:8]))
    others = [j for j in locked if j not in effector and j not in floating]
    if others:
        parts.append("the joints " + ", ".join(model.names[j] for j in others[:8]))
    return " and ".join(parts) or "no joint"
