"""Tests of :mod:`previewctl.robot.self_pairs`: which pairs of an arm's own links are checked, from an SRDF (as
Pinocchio reads it) or sampled (as MoveIt's setup assistant does), cached, and the errors of a bad SRDF."""

from __future__ import annotations

import os
from pathlib import Path

import pinocchio as pin
import pytest

from previewctl import load_robot
from previewctl.errors import RobotLoadError
from previewctl.index.load import shipped_robots_dir
from previewctl.robot import self_pairs
from previewctl.robot.geometry import prepare_geometry
from previewctl.robot.model import Geometry, Robot


def panda_files() -> tuple[Path, Path]:
    """The Panda's URDF and SRDF as example-robot-data ships them."""
    from example_robot_data import robots_loader

    root = Path(robots_loader.getModelPath("panda_description/urdf/panda.urdf"))
    return root / "panda_description/urdf/panda.urdf", root / "panda_description/srdf/panda.srdf"


def pinocchio_pairs(geometry: Geometry) -> set[frozenset[str]]:
    """Pinocchio's own reading of the Panda's SRDF on the same geometry: the fingers locked (as the loader locks
    them), every pair on different joints added, the SRDF's pairs removed; as pairs of geometry names."""
    urdf, srdf = panda_files()
    model = pin.buildModelFromUrdf(str(urdf))
    collision = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.COLLISION, package_dirs=[str(urdf.parents[4])])
    fingers = [model.getJointId(n) for n in ("panda_finger_joint1", "panda_finger_joint2")]
    model, collision = pin.buildReducedModel(model, collision, fingers, pin.neutral(model))
    collision = prepare_geometry(collision, geometry)
    collision.addAllCollisionPairs()
    pin.removeCollisionPairs(model, collision, str(srdf))
    names = [g.name for g in collision.geometryObjects]
    return {frozenset((names[p.first], names[p.second])) for p in collision.collisionPairs}


def our_pairs(robot: Robot) -> set[frozenset[str]]:
    names = [g.name for g in robot.self_pairs.geometry.geometryObjects]
    return {frozenset((names[p.first], names[p.second])) for p in robot.self_pairs.geometry.collisionPairs}


@pytest.mark.parametrize("geometry", ["convex", "mesh"])
def test_srdf_pairs_of_the_panda_equal_pinocchios_own_reading(geometry: Geometry) -> None:
    robot = load_robot("panda", geometry=geometry)
    expected = pinocchio_pairs(geometry)
    assert len(expected) == 44  # the design note's count, fingers included
    assert our_pairs(robot) == expected
    assert robot.self_pairs.source == f"SRDF {panda_files()[1]}" and robot.self_pairs.kind == geometry
    assert robot.self_pairs.always == () and robot.self_pairs.rigid == ()


def test_self_geometry_is_every_link_the_base_and_fingers_included_and_the_hand_is_one_body(panda: Robot) -> None:
    links = {link for pair in panda.self_pairs.links for link in pair}
    assert {"panda_link0", "panda_leftfinger", "panda_rightfinger", "panda_hand"} <= links
    assert "panda_link0" not in panda.guarded_links  # the clearance's links leave the fixed base out
    # the fingers are locked: hand, fingers and link 7 hang on one joint, one rigid body, no pair inside it
    hand = {"panda_link7", "panda_hand", "panda_leftfinger", "panda_rightfinger"}
    assert not [pair for pair in panda.self_pairs.links if set(pair) <= hand]
    # link a is the one nearer the base, and the pair indices name the links
    geometry = panda.self_pairs.geometry.geometryObjects
    joint_of = {panda.model.frames[g.parentFrame].name: g.parentJoint for g in geometry}
    assert all(joint_of[a] <= joint_of[b] for a, b in panda.self_pairs.links)
    assert panda.self_pairs.pair_names(0) == panda.self_pairs.links[panda.self_pairs.pair_links[0]]


def test_planar4_ships_an_srdf_that_disables_every_pair(planar4: Robot) -> None:
    assert (shipped_robots_dir() / "planar4.srdf").is_file()
    assert len(planar4.self_pairs) == 0 and planar4.self_pairs.links == ()
    assert planar4.self_pairs.source.startswith("SRDF ")


def test_sampled_pairs_are_stable_for_a_seed_come_back_from_the_disk_cache_and_skip_adjacent_links(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(self_pairs, "_MEMORY", {})
    first = load_robot("ur10")  # example-robot-data ships no SRDF for it
    assert first.self_pairs.source.startswith("sampled")
    cached = list((tmp_path / "previewctl").glob("self-pairs-*.json"))
    assert len(cached) == 1
    again = load_robot("ur10")
    assert again.self_pairs.links == first.self_pairs.links
    # a fresh process: nothing in memory, the screen must come from the disk
    monkeypatch.setattr(self_pairs, "_MEMORY", {})

    def no_screen(*args: object) -> None:
        raise AssertionError("the screen ran again instead of reading the disk cache")

    monkeypatch.setattr(self_pairs, "_screen", no_screen)
    from_disk = load_robot("ur10")
    assert from_disk.self_pairs.links == first.self_pairs.links
    # no adjacent links: not on one joint, not on a joint and its parent
    model = first.model
    joint_of = {model.frames[g.parentFrame].name: int(g.parentJoint)
                for g in first.self_pairs.geometry.geometryObjects}
    for a, b in first.self_pairs.links:
        ja, jb = joint_of[a], joint_of[b]
        assert ja != jb and model.parents[jb] != ja and model.parents[ja] != jb, (a, b)
    assert ("base_link", "upper_arm_link") in first.self_pairs.links  # two joints apart: kept
    assert not any({"shoulder_link", "upper_arm_link"} == set(pair) for pair in first.self_pairs.links)


def test_the_screen_draws_the_same_configurations_for_a_seed_without_any_cache() -> None:
    """No fingerprint, so no cache: two screens with one seed draw the same configurations and agree."""
    robot = load_robot("z1")  # its SRDF disables nothing: sampled; its hulls keep two neighbour pairs in contact
    geometry = pin.GeometryModel()
    for g in robot.self_pairs.geometry.geometryObjects:
        geometry.addGeometryObject(g)
    settings = self_pairs.Sampling(samples=200, seed=3)
    one, two = (self_pairs.find_self_pairs(robot.model, geometry, "convex", srdf=None, fingerprint=None,
                                           sampling=settings) for _ in range(2))
    assert one.links == two.links and one.always == two.always and one.rigid == two.rigid
    assert robot.self_pairs.always == (("link00", "link02"), ("link04", "link06"))


def test_a_cache_that_cannot_be_written_does_not_fail_the_load(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocked = tmp_path / "a-file"
    blocked.write_text("not a folder")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocked))
    monkeypatch.setattr(self_pairs, "_MEMORY", {})
    robot = load_robot("ur10")
    assert len(robot.self_pairs) == 20
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file"]


def test_a_corrupt_cache_file_is_recomputed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(self_pairs, "_MEMORY", {})
    expected = load_robot("ur10").self_pairs.links
    (cached,) = (tmp_path / "previewctl").glob("self-pairs-*.json")
    cached.write_text("{ torn")
    monkeypatch.setattr(self_pairs, "_MEMORY", {})
    assert load_robot("ur10").self_pairs.links == expected


def write_srdf(path: Path, pairs: list[tuple[str, str]], name: str = "panda") -> Path:
    lines = [f'<disable_collisions link1="{a}" link2="{b}" reason="test"/>' for a, b in pairs]
    path.write_text(f'<?xml version="1.0"?>\n<robot name="{name}">\n' + "\n".join(lines) + "\n</robot>\n")
    return path


def test_bad_srdf_is_refused_naming_the_file(tmp_path: Path) -> None:
    missing = tmp_path / "missing.srdf"
    with pytest.raises(RobotLoadError, match=r"SRDF file '.*missing\.srdf' does not exist"):
        load_robot("panda", srdf=missing)
    broken = tmp_path / "broken.srdf"
    broken.write_text("<robot><disable_collisions link1='a'")
    with pytest.raises(RobotLoadError, match=r"SRDF file '.*broken\.srdf' is not valid XML"):
        load_robot("panda", srdf=broken)
    empty = write_srdf(tmp_path / "empty.srdf", [])
    with pytest.raises(RobotLoadError, match=r"empty\.srdf' disables no collision pair"):
        load_robot("panda", srdf=empty)
    other = write_srdf(tmp_path / "other.srdf", [("wheel", "chassis")])
    with pytest.raises(RobotLoadError, match=r"other\.srdf' names none of the robot's links"):
        load_robot("panda", srdf=other)
    half = tmp_path / "half.srdf"
    half.write_text('<robot><disable_collisions link1="panda_link0"/></robot>')
    with pytest.raises(RobotLoadError, match=r"half\.srdf': a <disable_collisions> lacks link1 or link2"):
        load_robot("panda", srdf=half)


def test_a_user_srdf_replaces_the_shipped_one(tmp_path: Path, panda: Robot) -> None:
    links = sorted({link for pair in panda.self_pairs.links for link in pair} | {"panda_link3", "panda_link4"})
    every = [(a, b) for i, a in enumerate(links) for b in links[i + 1:]]
    none_left = load_robot("panda", srdf=write_srdf(tmp_path / "all.srdf", every))
    assert len(none_left.self_pairs) == 0 and none_left.self_pairs.source == f"SRDF {tmp_path / 'all.srdf'}"
    one_left = load_robot("panda", srdf=write_srdf(tmp_path / "one.srdf", [p for p in every
                                                                          if p != ("panda_hand", "panda_link0")]))
    assert one_left.self_pairs.links == (("panda_link0", "panda_hand"),)


def test_shipped_srdf_without_disabled_pairs_is_passed_over_for_sampling() -> None:
    """Kinova's SRDF holds a reference posture only: the pairs are sampled (its neighbours would touch)."""
    kinova = load_robot("kinova")
    assert kinova.self_pairs.source.startswith("sampled")
    assert ("j2s6s200_link_1", "j2s6s200_link_2") not in kinova.self_pairs.links


def test_coarse_cover_leaves_out_a_pair_it_always_has_in_contact_and_a_rigid_pair() -> None:
    capsules, mesh = load_robot("ur5", geometry="capsules"), load_robot("ur5", geometry="mesh")
    assert capsules.self_pairs.always == (("wrist_2_link", "ee_link"),)
    assert ("wrist_2_link", "ee_link") not in capsules.self_pairs.links
    # on the meshes that pair keeps 2 cm at every sample: the flange box turns about its own axis
    assert mesh.self_pairs.rigid == (("wrist_2_link", "ee_link"),) and mesh.self_pairs.always == ()
    assert os.path.basename(mesh.self_pairs.source.split()[-1]) == "ur5.srdf"
