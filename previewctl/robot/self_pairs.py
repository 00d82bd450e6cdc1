"""Self-collision pairs: which pairs of an arm's own links are checked against each other.

The self geometry is every link that carries collision geometry (the fixed base link and the hand's fingers
included), in the robot's geometry choice (convex, capsules or mesh). Joints locked at load time (a gripper's
fingers) move with their link, so their geometry is part of that rigid body: no pair inside it.

Which pairs are checked, in this order:

1. **An SRDF** (the robot's shipped one, or ``load_robot(..., srdf=path)``): every pair of geometries on
   different joints (``geom_model.addAllCollisionPairs()``) minus the SRDF's ``<disable_collisions>``
   (``pin.removeCollisionPairs``), exactly as Pinocchio reads it. A shipped SRDF that disables no pair (some
   example-robot-data SRDFs hold reference postures only) says nothing about collisions: it is passed over for 2.
2. **Sampled**, as MoveIt's setup assistant does: every pair of links with collision geometry, minus the adjacent
   ones (on the same joint, or on a joint and its parent joint), minus those in collision at almost every
   configuration drawn uniformly within the joint limits (:class:`Sampling`).
3. **Screened in the chosen geometry**, on the same random configurations:

   * a pair in collision at almost every sample is left out (:attr:`SelfPairs.always`). Step 2 is this screen over
     the non-adjacent pairs. After an SRDF it matters for the coarse covers: a convex or capsule cover is coarser
     than the URDF meshes the SRDF was made for, and may keep two neighbours in contact everywhere (the UR5's
     capsules: ``wrist_2_link`` and ``ee_link``). Such a pair cannot be told apart in that geometry; the exact
     (mesh) check still has it.
   * a pair whose distance is the same at every sample, and positive, cannot come into contact: its geometry turns
     about one axis with rotational symmetry (the UR5's ``ee_link``, a box on the flange axis, stays 2 cm from
     ``wrist_2_link``). It is left out (:attr:`SelfPairs.rigid`): it would only scale the index down everywhere.

A screen costs a few hundred milliseconds; its result is cached per process and on disk
(``$XDG_CACHE_HOME/previewctl/``, default ``~/.cache/previewctl/``), keyed by a hash of the URDF text, the locked
joints, the geometry choice, the candidate pairs and the sampling settings. A cache that cannot be read or written
is skipped: the pairs are computed and returned all the same.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from previewctl.errors import RobotLoadError
from previewctl.files import atomic_write_bytes
from previewctl.robot.joints import JointFacts
from previewctl.robot.xml import robot_root
from previewctl.types import IntArray

_log = logging.getLogger(__name__)

LinkPair = tuple[str, str]
"""Two link names, the one nearer the base first."""

CACHE_VERSION = 1
"""Bumped whenever the cached result would change for the same key."""


@dataclass(frozen=True)
class Sampling:
    """How pairs are screened on random configurations (MoveIt's "always in collision" test).

    Attributes:
        samples: configurations drawn uniformly within the joint limits (``+-pi`` where a joint has none).
        always: fraction of the samples in collision from which a pair counts as always in contact.
        seed: seed of the ``np.random.default_rng`` that draws them.
        rigid_samples: the first samples at which distances are measured for the rigid test.
        rigid_tolerance: [m] a pair whose distance varies less than this over them is rigid.
    """

    samples: int = 1000
    always: float = 0.95
    seed: int = 0
    rigid_samples: int = 16
    rigid_tolerance: float = 1e-5


@dataclass(frozen=True, eq=False)
class SelfPairs:
    """The self-collision pairs of a loaded arm.

    Attributes:
        links: the checked link pairs ``(a, b)``, ``a`` nearer the base (in chain order).
        geometry: the self geometry: every geometry of a checked pair (in the robot's geometry choice), with one
            collision pair per checked geometry pair (``a``'s geometry first).
        pair_links: ``(P,)`` for each collision pair of ``geometry``, the index of its link pair in ``links``.
        kind: the geometry choice the pairs are checked in: ``"convex"``, ``"capsules"`` or ``"mesh"``.
        source: where the pairs come from: ``"SRDF <path>"``, ``"sampled (...)"`` or ``"none"`` (not loaded from a
            robot source). Either way they are screened (``always``, ``rigid``).
        always: link pairs left out because this geometry has them in contact at nearly every sample (checked
            by the exact mesh check only; see the module docstring).
        rigid: link pairs left out because their distance is the same positive value at every sample.
    """

    links: tuple[LinkPair, ...] = ()
    geometry: pin.GeometryModel = field(default_factory=pin.GeometryModel)
    pair_links: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    kind: str = "convex"
    source: str = "none"
    always: tuple[LinkPair, ...] = ()
    rigid: tuple[LinkPair, ...] = ()

    def __len__(self) -> int:
        """The number of geometry pairs checked (``P``)."""
        return len(self.geometry.collisionPairs)

    def pair_names(self, pair: int) -> LinkPair:
        """The link names of geometry pair ``pair``."""
        return self.links[int(self.pair_links[pair])]


def find_self_pairs(
    model: pin.Model,
    geometry: pin.GeometryModel,
    kind: str,
    *,
    srdf: Path | None,
    fingerprint: str | None,
    locked: Sequence[str] = (),
    shipped_srdf: bool = False,
    sampling: Sampling = Sampling(),
) -> SelfPairs:
    """The self pairs of an arm (see the module docstring).

    Args:
        model: the (reduced) kinematic model.
        geometry: every link's collision geometry in the geometry choice ``kind`` (not only the guarded links').
        kind: ``"convex"``, ``"capsules"`` or ``"mesh"``.
        srdf: the SRDF to read, or ``None`` to sample the pairs.
        fingerprint: text that identifies the robot's geometry (its URDF), for the caches; ``None``: no cache.
        locked: the joints locked at load time (part of the cache key).
        shipped_srdf: ``srdf`` is the robot's default, not the user's: one that disables no pair is passed over.
        sampling: the screening settings.

    Raises:
        RobotLoadError: the SRDF is missing, malformed or disables no pair (a user's SRDF).
    """
    order = sorted(range(geometry.ngeoms), key=lambda g: (int(geometry.geometryObjects[g].parentJoint), g))
    geoms = [geometry.geometryObjects[g] for g in order]
    candidates: list[tuple[int, int]]
    if srdf is not None and _disables_pairs(srdf, shipped_srdf, {str(f.name) for f in model.frames}):
        candidates, source = _srdf_candidates(model, geoms, srdf), f"SRDF {srdf}"
    else:
        candidates = [(i, j) for i in range(len(geoms)) for j in range(i + 1, len(geoms))
                      if not _adjacent(model, geoms[i].parentJoint, geoms[j].parentJoint)]
        source = f"sampled ({sampling.samples} configurations, seed {sampling.seed})"
    names = [str(model.frames[g.parentFrame].name) for g in geoms]
    link_pairs = list(dict.fromkeys((names[i], names[j]) for i, j in candidates))
    screen = Screen([], [])
    if link_pairs:
        key = _cache_key(fingerprint, locked, kind, link_pairs, sampling)
        cached = _cached(key) if key is not None else None
        screen = cached if cached is not None else _screen(model, geoms, candidates, names, sampling)
        if key is not None and cached is None:
            _store(key, screen)
        _log.debug("self-pair screen %s", "from the cache" if cached is not None else "computed")
    dropped = {*screen.always, *screen.rigid}
    kept = [(i, j) for i, j in candidates if (names[i], names[j]) not in dropped]
    _log.info("self pairs: %d geometry pairs checked (%s)", len(kept), source)
    return _build(geoms, kept, names, kind, source, screen)


# ------------------------------------------------------------------------------------------ sources


def _disables_pairs(srdf: Path, shipped: bool, frames: set[str]) -> bool:
    """Whether the SRDF ``srdf`` disables some pair (and is a readable SRDF of this robot at all).

    Raises:
        RobotLoadError: a missing or malformed file, one that names none of the robot's links (another
            robot's), or a user's SRDF that disables no pair.
    """
    if not srdf.is_file():
        raise RobotLoadError(f"SRDF file {str(srdf)!r} does not exist")
    root = robot_root(srdf, "SRDF")
    for element in root.iter("disable_collisions"):
        if not element.get("link1") or not element.get("link2"):
            raise RobotLoadError(f"SRDF file {str(srdf)!r}: a <disable_collisions> lacks link1 or link2")
    named = {str(e.get(k)) for e in root.iter("disable_collisions") for k in ("link1", "link2")}
    if named and not named & frames:
        raise RobotLoadError(f"SRDF file {str(srdf)!r} names none of the robot's links (e.g. "
                             f"{sorted(named)[0]!r}): is it another robot's?")
    if named:
        return True
    if shipped:
        return False
    raise RobotLoadError(f"SRDF file {str(srdf)!r} disables no collision pair (no <disable_collisions>): every "
                         "pair of neighbouring links would count as a self-collision; list the pairs that never "
                         "collide, or leave srdf unset to sample them")


def _srdf_candidates(model: pin.Model, geoms: list[pin.GeometryObject], srdf: Path) -> list[tuple[int, int]]:
    """Pinocchio's own reading: every geometry pair on different joints, less the SRDF's disabled pairs.

    Raises:
        RobotLoadError: Pinocchio cannot read the file.
    """
    probe = pin.GeometryModel()
    for geom in geoms:
        probe.addGeometryObject(geom)
    probe.addAllCollisionPairs()
    try:
        pin.removeCollisionPairs(model, probe, str(srdf))
    except (ValueError, RuntimeError) as exc:
        raise RobotLoadError(f"SRDF file {str(srdf)!r} could not be read: {exc}") from exc
    return sorted((min(p.first, p.second), max(p.first, p.second)) for p in probe.collisionPairs)


def _adjacent(model: pin.Model, a: int, b: int) -> bool:
    """Whether geometry on joints ``a`` and ``b`` is on one rigid body or on two bodies one joint apart."""
    return a == b or int(model.parents[a]) == b or int(model.parents[b]) == a


def _build(geoms: list[pin.GeometryObject], pairs: list[tuple[int, int]], names: list[str], kind: str,
           source: str, screen: Screen) -> SelfPairs:
    """The :class:`SelfPairs` of the geometry ``pairs`` (indices into ``geoms``)."""
    used = sorted({g for pair in pairs for g in pair})
    slot = {g: k for k, g in enumerate(used)}
    model = pin.GeometryModel()
    for g in used:
        model.addGeometryObject(geoms[g])
    links = list(dict.fromkeys((names[i], names[j]) for i, j in pairs))
    pair_links = []
    for i, j in pairs:
        model.addCollisionPair(pin.CollisionPair(slot[i], slot[j]))
        pair_links.append(links.index((names[i], names[j])))
    return SelfPairs(tuple(links), model, np.array(pair_links, dtype=np.int64), kind, source, tuple(screen.always),
                     tuple(screen.rigid))


# ----------------------------------------------------------------------------------------- screening


@dataclass(frozen=True)
class Screen:
    """The link pairs a screen leaves out: in contact at nearly every sample, and at one distance at all."""

    always: list[LinkPair]
    rigid: list[LinkPair]


def _screen(model: pin.Model, geoms: list[pin.GeometryObject], pairs: list[tuple[int, int]], names: list[str],
            sampling: Sampling) -> Screen:
    """The link pairs in collision (some geometry pair of theirs) at ``>= sampling.always`` of the samples, and
    those whose every geometry pair keeps one positive distance (to ``rigid_tolerance``) over the first
    ``rigid_samples`` samples."""
    probe = pin.GeometryModel()
    for geom in geoms:
        probe.addGeometryObject(geom)
    for i, j in pairs:
        probe.addCollisionPair(pin.CollisionPair(i, j))
    probe_data, data = probe.createData(), model.createData()
    collisions, distances = list(probe_data.collisionResults), list(probe_data.distanceResults)
    links = list(dict.fromkeys((names[i], names[j]) for i, j in pairs))
    of_pair = np.array([links.index((names[i], names[j])) for i, j in pairs])
    counts = np.zeros(len(links))
    measured = []
    for k, q in enumerate(_uniform_configurations(model, sampling)):
        pin.updateGeometryPlacements(model, data, probe, probe_data, q)
        pin.computeCollisions(probe, probe_data, False)
        hit = np.zeros(len(links), dtype=bool)
        hit[of_pair[[r.isCollision() for r in collisions]]] = True
        counts += hit
        if k < sampling.rigid_samples:
            pin.computeDistances(probe, probe_data)
            measured.append([r.min_distance for r in distances])
    always = [links[k] for k in np.flatnonzero(counts >= sampling.always * sampling.samples)]
    spread = np.ptp(measured, axis=0) < sampling.rigid_tolerance
    fixed = spread & (np.min(measured, axis=0) > 0.0)
    rigid = [links[k] for k in range(len(links))
             if counts[k] == 0 and len(measured) > 1 and fixed[of_pair == k].all()]
    return Screen(always, rigid)


def _uniform_configurations(model: pin.Model, sampling: Sampling) -> list[np.ndarray]:
    """``sampling.samples`` configurations uniform within the limits (``+-pi`` where a joint has none)."""
    facts = JointFacts.of(model)
    lower = np.where(np.isfinite(facts.lower), facts.lower, -np.pi)
    upper = np.where(np.isfinite(facts.upper), facts.upper, np.pi)
    angles = np.random.default_rng(sampling.seed).uniform(lower, upper, size=(sampling.samples, model.nv))
    if facts.vector_space:
        return list(angles)
    neutral = pin.neutral(model)
    return [np.asarray(pin.integrate(model, neutral, a)) for a in angles]


# ------------------------------------------------------------------------------------------- caches

_MEMORY: dict[str, Screen] = {}
"""This process's screens, by cache key."""


def cache_dir() -> Path:
    """The folder of the disk cache: ``$XDG_CACHE_HOME/previewctl`` (default ``~/.cache/previewctl``)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "previewctl"


def _cache_key(fingerprint: str | None, locked: Sequence[str], kind: str, pairs: list[LinkPair],
               sampling: Sampling) -> str | None:
    """A hash of everything a screen depends on (``None`` without a fingerprint: nothing is cached)."""
    if fingerprint is None:
        return None
    payload = json.dumps([CACHE_VERSION, fingerprint, sorted(locked), kind, pairs,
                          [sampling.samples, sampling.always, sampling.seed, sampling.rigid_samples,
                           sampling.rigid_tolerance]])
    return hashlib.sha256(payload.encode("utf-8")).hexdigest()


def _cache_file(key: str) -> Path:
    return cache_dir() / f"self-pairs-{key[:40]}.json"


def _cached(key: str) -> Screen | None:
    """The screen under ``key`` from memory, else from disk (``None`` if absent or unreadable)."""
    if key in _MEMORY:
        return _MEMORY[key]
    try:
        stored = json.loads(_cache_file(key).read_text(encoding="utf-8"))
        if stored.get("key") != key:
            return None
        screen = Screen(*([(str(a), str(b)) for a, b in stored[part]] for part in ("always", "rigid")))
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None
    _MEMORY[key] = screen
    return screen


def _store(key: str, screen: Screen) -> None:
    """Keep the screen in memory and, if the cache folder can be written, on disk."""
    _MEMORY[key] = screen
    text = json.dumps({"key": key, "always": [list(p) for p in screen.always],
                       "rigid": [list(p) for p in screen.rigid]}, indent=1) + "\n"
    try:
        cache_dir().mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(_cache_file(key), text.encode("utf-8"))
    except OSError as exc:  # a read-only home or a full disk: the pairs are computed again next time
        _log.info("self-pair cache not written to %s: %s", cache_dir(), exc)
