"""Tests of :mod:`previewctl.robot` (model, load, geometry) and of scene files
(:mod:`previewctl.scene.file`): defaults, options, typed errors, the shipped robots' folder
(the wheel that ships it: ``tests/test_packaging.py``)."""

from __future__ import annotations

import contextlib
import re
import signal
from collections.abc import Iterator
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest
from helpers import rot_z

import previewctl
import previewctl.scene.motion
from previewctl import (
    ConfigurationError,
    PreviewctlError,
    RobotLoadError,
    SceneError,
    UnknownNameError,
    avoidance,
    evaluate,
    load_robot,
    load_scene,
)
from previewctl.index.evaluator import Evaluator
from previewctl.index.load import shipped_robot_names, shipped_robots_dir
from previewctl.robot.model import Robot, Task
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Obstacle, Scene, Sphere

REPO = Path(__file__).resolve().parent.parent


# ------------------------------------------------------------------------------ defaults


def test_planar4_defaults(planar4: Robot) -> None:
    assert planar4.nq == planar4.nv == 4
    assert planar4.joint_names == ("joint1", "joint2", "joint3", "joint4")
    assert planar4.control_points == ("joint2", "joint3", "joint4")
    assert planar4.guarded_links == ("link1", "link2", "link3", "link4")
    assert planar4.hand_links == ("link4",)
    assert planar4.task == "planar"
    assert planar4.tip_frame == "tip"
    assert planar4.planar is not None
    assert tuple(planar4.structural_ranks) == (1, 2, 1)
    assert all(isinstance(g.geometry, coal.Capsule) for g in planar4.collision_model.geometryObjects)
    assert [g.geometry.radius for g in planar4.collision_model.geometryObjects] == pytest.approx([0.03] * 4)
    np.testing.assert_allclose(planar4.lower_limits, -2 * np.pi)
    np.testing.assert_allclose(planar4.upper_limits, 2 * np.pi)
    data = planar4.model.createData()
    pin.framesForwardKinematics(planar4.model, data, np.zeros(4))
    np.testing.assert_allclose(data.oMf[planar4.tip_frame_id].translation, [3.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(evaluate(planar4, None, np.zeros(4)).tip_position, [[3.0, 0.0, 0.0]], atol=1e-12)
    # control points are the tips of links 1-3
    for name, x in zip(planar4.control_points, (0.75, 1.5, 2.25), strict=True):
        np.testing.assert_allclose(data.oMf[planar4.model.getFrameId(name)].translation, [x, 0.0, 0.0], atol=1e-12)
    assert avoidance(planar4, np.zeros(4)).J_task.shape == (2, 4)


def test_panda_defaults(panda: Robot) -> None:
    assert panda.nq == panda.nv == 7
    assert panda.joint_names == tuple(f"panda_joint{i}" for i in range(1, 8))
    assert not any("finger" in name for name in panda.joint_names)
    assert panda.tip_frame == "panda_hand_tcp"
    assert panda.task == "position"
    assert panda.planar is None
    assert len(panda.structural_ranks) == len(panda.control_points) > 0
    assert set(panda.control_points) <= set(panda.joint_names)
    hand = ("panda_link7", "panda_hand", "panda_leftfinger", "panda_rightfinger")
    assert panda.guarded_links[-4:] == panda.hand_links == hand  # every link guarded, the hand's included
    # meshes become convex hulls; the fingers' boxes stay boxes
    assert all(isinstance(g.geometry, coal.Box if "finger" in g.name else coal.Convex)
               for g in panda.collision_model.geometryObjects)
    assert avoidance(panda, panda.neutral()).J_task.shape == (3, 7)


def test_ur5_defaults(ur5: Robot) -> None:
    assert ur5.nq == ur5.nv == 6
    assert ur5.tip_frame == "tool0"
    assert ur5.task == "position"
    assert len(ur5.structural_ranks) == len(ur5.control_points)


def test_kinova_continuous_joints(kinova: Robot) -> None:
    assert (kinova.nq, kinova.nv) == (9, 6)
    Q = kinova.random_configurations(np.random.default_rng(0), 5)
    assert Q.shape == (5, 9)
    # each continuous joint is a unit (cos, sin) pair
    for j in range(1, kinova.model.njoints):
        joint = kinova.model.joints[j]
        if joint.nq == 2:
            np.testing.assert_allclose(np.hypot(Q[:, joint.idx_q], Q[:, joint.idx_q + 1]), 1.0)


def test_guarded_links_intermediate_leaves_out_the_hand_link() -> None:
    robot = load_robot("planar4", guarded_links="intermediate")
    assert robot.guarded_links == ("link1", "link2", "link3")
    assert len(robot.collision_model.geometryObjects) == 3
    assert evaluate(robot, None, np.zeros(4)).link_distances.shape == (1, 3)


def test_custom_control_points_and_links() -> None:
    robot = load_robot("planar4", control_points=["joint3"], guarded_links=["link2"])
    assert robot.control_points == ("joint3",)
    assert robot.guarded_links == ("link2",)
    assert tuple(robot.structural_ranks) == (2,)
    assert avoidance(robot, np.array([0.3, 0.4, 0.5, 0.6])).M.shape == (1, 2, 4)


def test_geometry_choice(planar4: Robot, panda: Robot, panda_mesh: Robot) -> None:
    assert all(isinstance(g.geometry, coal.Box if "finger" in g.name else coal.BVHModelBase)
               for g in panda_mesh.collision_model.geometryObjects)
    assert all(isinstance(g.geometry, coal.Box if "finger" in g.name else coal.Convex)
               for g in panda.collision_model.geometryObjects)
    assert panda_mesh.guarded_links == panda.guarded_links
    # the hull covers the mesh: from any outside point it is at most as far away
    rng = np.random.default_rng(0)
    probe = coal.Sphere(0.01)
    for hull, mesh in zip(
        panda.collision_model.geometryObjects, panda_mesh.collision_model.geometryObjects, strict=True
    ):
        assert hull.parentFrame == mesh.parentFrame
        for _ in range(5):
            direction = rng.normal(size=3)
            at = coal.Transform3s(np.eye(3), 0.4 * direction / np.linalg.norm(direction))
            identity = coal.Transform3s()
            d_hull = coal.distance(hull.geometry, identity, probe, at, coal.DistanceRequest(), coal.DistanceResult())
            d_mesh = coal.distance(mesh.geometry, identity, probe, at, coal.DistanceRequest(), coal.DistanceResult())
            assert d_hull <= d_mesh + 1e-6
    cylinders = load_robot("planar4", geometry="mesh")
    assert all(isinstance(g.geometry, coal.Cylinder) for g in cylinders.collision_model.geometryObjects)
    assert cylinders.planar is None  # the closed form needs capsules
    assert all(isinstance(g.geometry, coal.Capsule) for g in planar4.collision_model.geometryObjects)


@pytest.mark.parametrize("shape", [(0.05, 0.02, 0.3), (0.1, 0.1, 0.1), (0.2, 0.01, 0.01)])
def test_enclosing_capsule_contains_the_points_tightly(shape: tuple[float, float, float]) -> None:
    """Long, round and flat point clouds: every point inside, one on the surface, a proper rotation."""
    from previewctl.robot.geometry import enclosing_capsule

    rng = np.random.default_rng(7)
    rotation = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    points = (rng.normal(size=(400, 3)) * shape) @ rotation.T + [0.3, -0.1, 0.5]
    radius, half_length, placement = enclosing_capsule(points)
    R = placement.rotation
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    local = (points - placement.translation) @ R
    on_axis = np.clip(local[:, 2], -half_length, half_length)
    distance = np.sqrt(local[:, 0] ** 2 + local[:, 1] ** 2 + (local[:, 2] - on_axis) ** 2)
    assert distance.max() <= radius + 1e-12
    assert distance.max() == pytest.approx(radius, rel=1e-9)


def test_capsule_geometry_covers_the_meshes(panda_mesh: Robot) -> None:
    """geometry="capsules": one Coal capsule per mesh, on the same frame, containing every mesh vertex."""
    capsules = load_robot("panda", geometry="capsules")
    assert capsules.guarded_links == panda_mesh.guarded_links
    for capsule, mesh in zip(
        capsules.collision_model.geometryObjects, panda_mesh.collision_model.geometryObjects, strict=True
    ):
        if isinstance(mesh.geometry, coal.Box):  # the fingers' boxes are kept
            assert isinstance(capsule.geometry, coal.Box)
            continue
        assert isinstance(capsule.geometry, coal.Capsule)
        assert capsule.parentFrame == mesh.parentFrame
        M, C = mesh.placement, capsule.placement  # both in the parent joint frame
        vertices = np.asarray(mesh.geometry.vertices()) @ M.rotation.T + M.translation
        local = (vertices - C.translation) @ C.rotation
        half = capsule.geometry.halfLength
        gap = local - np.column_stack([np.zeros((len(local), 2)), np.clip(local[:, 2], -half, half)])
        assert np.linalg.norm(gap, axis=1).max() <= capsule.geometry.radius + 1e-9


def test_task_choices(ur5: Robot) -> None:
    pose = load_robot("ur5", task="pose")
    assert pose.task == "pose" and ur5.task == "position"
    q = np.array([0.1, -1.2, 1.5, -0.8, 1.1, 0.3])
    J_pose = avoidance(pose, q).J_task
    assert J_pose.shape == (6, 6)
    np.testing.assert_allclose(J_pose[:3], avoidance(ur5, q).J_task, atol=1e-12)  # same position rows


@pytest.mark.parametrize(("task", "rows", "rank"), [("pose", 6, 3), ("position", 3, 2)])
def test_task_the_hand_cannot_follow_is_refused(task: Task, rows: int, rank: int) -> None:
    """A planar arm moves its hand in x, y and turns it about z: z and the tilts are out of reach."""
    with pytest.raises(RobotLoadError, match=rf"robot 'planar4' cannot follow task '{task}': its hand moves along "
                       rf"only {rank} of the task's {rows} directions; valid tasks for it: \['planar'\]"):
        load_robot("planar4", task=task)


# ------------------------------------------------------------------------------ robot errors


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nowhere.urdf"
    with pytest.raises(RobotLoadError, match=re.escape(str(path))) as info:
        load_robot(path)
    assert isinstance(info.value, PreviewctlError)
    with pytest.raises(RobotLoadError, match="does not exist"):
        load_robot(str(tmp_path / "sub" / "robot"))


def test_malformed_xml(tmp_path: Path) -> None:
    path = write(tmp_path, "broken.urdf", '<robot name="b"><link name="a"></robot>')
    with pytest.raises(RobotLoadError, match=r"not valid XML") as info:
        load_robot(path)
    assert str(path) in str(info.value)
    not_robot = write(tmp_path, "other.urdf", "<model/>")
    with pytest.raises(RobotLoadError, match=r"<model>"):
        load_robot(not_robot)


def test_no_movable_joint(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        "fixed.urdf",
        """<?xml version="1.0"?>
<robot name="statue">
  <link name="base"/>
  <joint name="weld" type="fixed"><parent link="base"/><child link="top"/><origin xyz="0 0 1"/></joint>
  <link name="top"/>
</robot>
""",
    )
    with pytest.raises(RobotLoadError, match="no movable joint") as info:
        load_robot(path)
    assert isinstance(info.value, PreviewctlError)


def test_unknown_robot_name() -> None:
    with pytest.raises(UnknownNameError, match="unknown robot 'no_such_arm'") as info:
        load_robot("no_such_arm")
    message = str(info.value)
    assert "planar4" in message
    assert "panda" in message
    assert isinstance(info.value, PreviewctlError)
    assert isinstance(info.value, KeyError)


def test_unknown_tip_frame() -> None:
    with pytest.raises(UnknownNameError, match="frame 'hand'") as info:
        load_robot("planar4", tip="hand")
    for valid in ("tip", "link4", "joint2"):
        assert re.search(rf"\b{valid}\b", str(info.value))


def test_unknown_lock_joint() -> None:
    with pytest.raises(UnknownNameError, match="joint 'joint9'") as info:
        load_robot("planar4", lock=["joint9"])
    assert "joint1" in str(info.value)
    assert "joint4" in str(info.value)


@contextlib.contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    """Raise TimeoutError in the main thread after ``seconds`` (interrupts a Python-level loop)."""

    def on_alarm(signum: int, frame: object) -> None:
        raise TimeoutError(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def test_lock_with_explicit_tip() -> None:
    with time_limit(5):
        robot = load_robot("planar4", lock=["joint4"], tip="tip")
    assert robot.joint_names == ("joint1", "joint2", "joint3")
    assert robot.nq == 3
    assert robot.control_points == ("joint2", "joint3")
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, np.zeros(3))
    np.testing.assert_allclose(data.oMf[robot.tip_frame_id].translation, [3.0, 0.0, 0.0], atol=1e-12)
    with pytest.raises(RobotLoadError, match="no joint is left to move once the joints joint1, joint2, joint3, joint4"):
        load_robot("planar4", lock=["joint1", "joint2", "joint3", "joint4"])


def test_lock_last_joint_default_tip() -> None:
    """Locking the last chain joint without naming the tip: the tip is still found ("tip")."""
    with time_limit(3):
        robot = load_robot("planar4", lock=["joint4"])
    assert robot.joint_names == ("joint1", "joint2", "joint3")
    assert robot.tip_frame == "tip"


def test_unknown_task() -> None:
    with pytest.raises(UnknownNameError, match="task 'orientation'") as info:
        load_robot("planar4", task="orientation")  # type: ignore[arg-type]
    for valid in ("planar", "position", "pose"):
        assert valid in str(info.value)


def test_unknown_geometry_choice() -> None:
    with pytest.raises(UnknownNameError, match="geometry choice 'hull'") as info:
        load_robot("planar4", geometry="hull")  # type: ignore[arg-type]
    assert "convex" in str(info.value)
    assert "mesh" in str(info.value)


def test_unknown_control_point_and_link() -> None:
    with pytest.raises(UnknownNameError, match=r"'elbow'.*joint1"):
        load_robot("planar4", control_points=["elbow"])
    with pytest.raises(UnknownNameError, match=r"'link9'.*link1"):
        load_robot("planar4", guarded_links=["link9"])
    with pytest.raises(UnknownNameError, match=r"'some'.*intermediate"):
        load_robot("planar4", guarded_links="some")


def test_missing_mesh(tmp_path: Path) -> None:
    for filename in ("meshes/missing_link.stl", "package://nopkg/meshes/missing_link.stl"):
        path = write(
            tmp_path,
            "meshy.urdf",
            f"""<?xml version="1.0"?>
<robot name="meshy">
  <link name="base"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <link name="arm">
    <collision><geometry><mesh filename="{filename}"/></geometry></collision>
  </link>
</robot>
""",
        )
        with pytest.raises(RobotLoadError, match=re.escape(filename)) as info:
            load_robot(path)
        assert isinstance(info.value, PreviewctlError)


def test_bad_configurations(planar4: Robot) -> None:
    with pytest.raises(ConfigurationError, match=r"shape \(3,\).*\(4,\)") as info:
        avoidance(planar4, np.zeros(3))
    assert isinstance(info.value, PreviewctlError)
    with pytest.raises(ConfigurationError, match=r"shape \(5, 3\)"):
        evaluate(planar4, None, np.zeros((5, 3)))
    with pytest.raises(ConfigurationError, match=r"shape \(2, 2, 4\)"):
        avoidance(planar4, np.zeros((2, 2, 4)))
    with pytest.raises(ConfigurationError, match=r"nan.*'joint2'"):
        avoidance(planar4, [0.0, float("nan"), 0.0, 0.0])
    Q = np.zeros((3, 4))
    Q[2, 3] = np.inf
    with pytest.raises(ConfigurationError, match=r"q\[2, 3\] = inf.*'joint4'"):
        evaluate(planar4, None, Q)
    with pytest.raises(ConfigurationError, match="numbers"):
        avoidance(planar4, ["a", "b", "c", "d"])
    # the caller's array is not touched
    assert np.isinf(Q[2, 3])


def test_bad_configuration_names_continuous_joint(kinova: Robot) -> None:
    """kinova: q has 9 entries for 6 joints; the NaN is reported with the joint it belongs to."""
    q = kinova.neutral()
    for index in range(kinova.nq):
        owner = next(
            kinova.model.names[j]
            for j in range(1, kinova.model.njoints)
            if kinova.model.joints[j].idx_q <= index < kinova.model.joints[j].idx_q + kinova.model.joints[j].nq
        )
        bad = q.copy()
        bad[index] = np.nan
        with pytest.raises(ConfigurationError, match=re.escape(f"'{owner}'")):
            avoidance(kinova, bad)
    with pytest.raises(ConfigurationError, match=r"\(9,\)"):
        avoidance(kinova, np.zeros(6))


# ------------------------------------------------------------------------------ scenes


SCENE = """
[[obstacles]]
name = "ball"
shape = "sphere"
radius = 0.2
position = [1.0, 0.5]

[[obstacles]]
name = "crate"
shape = "box"
size = [0.2, 0.3, 0.4]
position = [0.5, -0.5, 0.0]
rpy = [0.0, 0.0, 0.5]

[[obstacles]]
name = "runner"
shape = "sphere"
radius = 0.1

[obstacles.motion]
type = "constant_velocity"
position = [0.0, 1.0, 0.0]
velocity = [0.5, 0.0, 0.0]
"""


def test_load_valid_scene(tmp_path: Path, planar4: Robot) -> None:
    scene = load_scene(write(tmp_path, "scene.toml", SCENE))
    assert scene.names == ("ball", "crate", "runner")
    ball, crate, runner = scene.obstacles
    assert ball.shape == previewctl.Sphere(0.2)
    assert crate.shape == previewctl.Box((0.2, 0.3, 0.4))
    assert runner.shape == previewctl.Sphere(0.1)
    np.testing.assert_allclose(ball.placement(0.0).translation, [1.0, 0.5, 0.0])
    np.testing.assert_allclose(ball.placement(3.0).translation, [1.0, 0.5, 0.0])
    np.testing.assert_allclose(crate.placement(0.0).rotation, rot_z(0.5), atol=1e-12)
    np.testing.assert_allclose(runner.placement(0.0).translation, [0.0, 1.0, 0.0])
    np.testing.assert_allclose(runner.placement(2.0).translation, [1.0, 1.0, 0.0])
    # the moving obstacle moves in the evaluation too
    q = np.array([np.pi / 2, 0.0, 0.0, 0.0])  # arm along +y: x = 0, the runner starts on it
    at0 = evaluate(planar4, scene, q, 0.0)
    at2 = evaluate(planar4, scene, q, 2.0)
    assert at0.collision[0]
    assert not at2.collision[0]
    assert at2.S[0] > 0 > at0.S[0]


@pytest.mark.parametrize(
    ("body", "match"),
    [
        ('[[obstacles]]\nname = "c"\nshape = "cone"\nradius = 0.1\n', r"'cone'.*sphere"),
        ('[[obstacles]]\nname = "c"\nshape = "sphere"\nradius = 0.1\ncolour = "red"\n',
         r"unknown key 'obstacles\[0\]\.colour'; valid keys in obstacles\[0\] \(shape = 'sphere'\): "
         r"name, work_surface, shape, radius, position"),
        ('[[obstacles]]\nname = "c"\nshape = "sphere"\nradius = -0.1\n', r"radius.*-0\.1"),
        ('[[obstacles]]\nname = "c"\nshape = "box"\nsize = [0.1, 0.0, 0.1]\n', r"size.*0\.0"),
        ('[[obstacles]]\nname = "c"\nshape = "mesh"\npath = "nope.stl"\n', r"nope\.stl"),
        ('[[obstacles]\nname = "c"\n', r"not valid TOML"),
        ('title = "x"\n[[obstacles]]\nname = "c"\nshape = "sphere"\nradius = 0.1\n', r"'title'"),
        (
            '[[obstacles]]\nname = "c"\nshape = "sphere"\nradius = 0.1\n'
            '[[obstacles]]\nname = "c"\nshape = "sphere"\nradius = 0.2\n',
            r"repeated: c",
        ),
        (
            '[[obstacles]]\nname = "c"\nshape = "sphere"\nradius = 0.1\n[obstacles.motion]\ntype = "teleport"\n',
            r"'teleport'",
        ),
    ],
)
def test_scene_errors(tmp_path: Path, body: str, match: str) -> None:
    with pytest.raises(SceneError, match=match) as info:
        load_scene(write(tmp_path, "bad.toml", body))
    assert isinstance(info.value, PreviewctlError)


def test_a_scene_file_that_is_not_utf8_is_named_not_a_traceback(tmp_path: Path) -> None:
    path = tmp_path / "latin1.toml"
    path.write_bytes('[[obstacles]]\nname = "côte"\n'.encode("latin-1"))
    with pytest.raises(SceneError, match=r"scene file '.*latin1\.toml' cannot be read: 'utf-8' codec"):
        load_scene(path)


CUBE_OBJ = "\n".join(
    [f"v {x} {y} {z}" for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    + [
        f"f {a} {b} {c}\nf {a} {c} {d}"
        for a, b, c, d in ((1, 3, 4, 2), (5, 6, 8, 7), (1, 2, 6, 5), (3, 7, 8, 4), (1, 5, 7, 3), (2, 4, 8, 6))
    ]
)


def test_mesh_obstacles_match_boxes(tmp_path: Path, planar4: Robot) -> None:
    """A cube mesh (relative path, per-axis or scalar scale, exact or convex) == the same Box."""
    write(tmp_path, "cube.obj", CUBE_OBJ + "\n")
    scene = load_scene(
        write(
            tmp_path,
            "scene.toml",
            """
[[obstacles]]
name = "block"
shape = "mesh"
path = "cube.obj"
scale = [0.1, 0.2, 0.3]
position = [1.0, 0.6, 0.0]
rpy = [0.0, 0.0, 0.3]

[[obstacles]]
name = "hull"
shape = "mesh"
path = "cube.obj"
scale = 0.15
convex = true
position = [-1.0, 0.6, 0.0]
""",
        )
    )
    block, hull = scene.obstacles
    assert block.shape == previewctl.Mesh(str(tmp_path / "cube.obj"), (0.1, 0.2, 0.3), False)
    assert hull.shape == previewctl.Mesh(str(tmp_path / "cube.obj"), (0.15, 0.15, 0.15), True)
    boxes = previewctl.Scene(
        (
            previewctl.Obstacle(
                "b",
                previewctl.Box((0.2, 0.4, 0.6)),
                previewctl.scene.motion.Static(np.array([1.0, 0.6, 0.0]), rot_z(0.3)),
            ),
            previewctl.Obstacle(
                "h", previewctl.Box((0.3, 0.3, 0.3)), previewctl.scene.motion.Static(np.array([-1.0, 0.6, 0.0]))
            ),
        )
    )
    Q = np.random.default_rng(0).uniform(-np.pi, np.pi, size=(100, 4))
    meshes, reference = evaluate(planar4, scene, Q), evaluate(planar4, boxes, Q, method="general")
    np.testing.assert_array_equal(meshes.collision, reference.collision)
    positive = reference.link_distances > 0
    assert positive.mean() > 0.5
    np.testing.assert_allclose(meshes.link_distances[positive], reference.link_distances[positive], atol=1e-6)


def test_scene_file_missing(tmp_path: Path) -> None:
    with pytest.raises(SceneError, match=r"absent\.toml"):
        load_scene(tmp_path / "absent.toml")


# ------------------------------------------------------------------------------ packaging


def test_shipped_robots_dir() -> None:
    assert (shipped_robots_dir() / "planar4.urdf").is_file()
    assert "planar4" in shipped_robot_names()


# ---------------------------------------------------------------------------- no collision geometry

VISUAL_ONLY_ARM = """<?xml version="1.0"?>
<robot name="visual_only">
  <link name="base"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="upper"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <link name="upper"><visual><origin xyz="0.25 0 0" rpy="0 1.5707963267948966 0"/>
    <geometry><cylinder radius="0.03" length="0.5"/></geometry></visual></link>
  <joint name="j2" type="revolute"><parent link="upper"/><child link="fore"/>
    <origin xyz="0.5 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <link name="fore"><visual><origin xyz="0.25 0 0" rpy="0 1.5707963267948966 0"/>
    <geometry><cylinder radius="0.03" length="0.5"/></geometry></visual></link>
  <joint name="j3" type="revolute"><parent link="fore"/><child link="hand"/>
    <origin xyz="0.5 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <link name="hand"><visual><geometry><sphere radius="0.02"/></geometry></visual></link>
  <joint name="tip_joint" type="fixed"><parent link="hand"/><child link="tip"/><origin xyz="0.1 0 0"/></joint>
  <link name="tip"/>
</robot>
"""


def test_an_arm_without_collision_geometry_is_refused(tmp_path: Path) -> None:
    urdf = tmp_path / "visual_only.urdf"
    urdf.write_text(VISUAL_ONLY_ARM)
    with pytest.raises(RobotLoadError, match=r"robot 'visual_only' has no collision geometry on its moving links "
                       r"\(no <collision> elements\).*collision_from_visual=True"):
        load_robot(urdf)
    # the explicit opt-in guards the visual cylinders: a ball through the forearm collides
    robot = load_robot(urdf, collision_from_visual=True)
    assert robot.guarded_links == ("upper", "fore", "hand")
    q = np.zeros(robot.nq)
    ball = Scene((Obstacle("ball", Sphere(0.05), Static(np.array([0.75, 0.0, 0.0]))),))
    check = Evaluator(robot, ball)(q[None, :])
    assert check.collision[0] and check.link_distances[0].tolist()[1] < 0 < check.link_distances[0].tolist()[0]
