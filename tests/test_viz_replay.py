"""Tests of :mod:`previewctl.viz.replay` and ``previewctl view``: what a replay records, and how it shows in Chromium.

The recorded scene is read back from the HTML file (viser's embed format: base64 of a zstd frame holding
a msgpack document of timed messages), so the checks name the nodes a person sees. The browser tests
open the file from disk in headless Chromium (Debian's package, WebGL by SwiftShader) through
Playwright; they skip, saying why, only when one of the two is missing (``.ci/run`` installs both).
"""

from __future__ import annotations

import base64
import dataclasses
import io
import re
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import msgspec
import numpy as np
import pytest
import zstandard
from helpers import planar_doc

from previewctl.cli.main import main
from previewctl.errors import PreviewctlError
from previewctl.sim.log import RunResult, save_run
from previewctl.sim.loop import simulate
from previewctl.sim.scenario import Scenario, load_scenario, scenario_from_dict
from previewctl.viz.drawing import COLLISION_COLOUR
from previewctl.viz.replay import HOLD, REPLAY_NAME, frame_steps, live_replay, write_replay
from previewctl.viz.replay_scene import GHOST_RGBA, ORACLE_RGBA, find_contact

BALL = {"name": "ball", "shape": "sphere", "radius": 0.1,
        "motion": {"type": "constant_velocity", "position": [0.33, -0.4], "velocity": [0.0, 0.4]}}
WALL = {"name": "wall", "shape": "box", "size": [0.2, 0.6, 0.2], "position": [2.4, 0.6]}
RED = tuple(int(COLLISION_COLOUR[i:i + 2], 16) for i in (1, 3, 5))


@pytest.fixture(scope="module")
def crossing() -> tuple[Scenario, RunResult]:
    """planar4 tracking (controller none, the paper's eq. 19) while a ball crosses link 1: hit at t = 1.2 s."""
    scenario = scenario_from_dict(planar_doc(obstacles=[BALL, WALL], timing={"duration": 3.0},
                                             controller={"execution": "pseudoinverse"}))
    return scenario, simulate(scenario, "none")


def recorded(html: str) -> dict[str, Any]:
    """The scene document embedded in a replay: ``durationSeconds`` and ``messages`` ``[(t, message), ...]``."""
    match = re.search(r'window\.__VISER_EMBED_DATA__="([^"]+)"', html)
    assert match is not None
    payload = base64.b64decode(match.group(1))
    inner = zstandard.ZstdDecompressor().decompress(payload[8:], max_output_size=int.from_bytes(payload[:8], "little"))
    size = int.from_bytes(inner[:8], "little")
    document: dict[str, Any] = msgspec.msgpack.decode(inner[8:8 + size])
    return document


def messages(document: dict[str, Any], kind: str, name: str = "") -> list[tuple[float, dict[str, Any]]]:
    return [(t, m) for t, m in document["messages"] if m["type"] == kind and m.get("name", "").startswith(name)]


# ------------------------------------------------------------------------------------- recording


def test_frame_steps_sample_the_run_and_keep_the_last_and_extra_steps() -> None:
    t = np.arange(121) * 0.01
    np.testing.assert_array_equal(frame_steps(t, 10.0), np.arange(0, 121, 10))
    np.testing.assert_array_equal(frame_steps(t, 10.0, extra=55), np.sort(np.append(np.arange(0, 121, 10), 55)))
    np.testing.assert_array_equal(frame_steps(t[:96], 10.0), [*range(0, 91, 10), 95])


def test_contact_is_the_logged_link_against_the_nearest_obstacle(crossing: tuple[Scenario, RunResult]) -> None:
    scenario, result = crossing
    contact = find_contact(result, scenario)
    assert contact is not None and contact.links == (result.summary()["collision_link"],) == ("link1",)
    assert contact.step == result.steps - 1 and scenario.scene.obstacles[contact.obstacle].name == "ball"
    centre = scenario.scene.obstacles[0].placement(float(result.t[contact.step])).translation
    assert abs(np.linalg.norm(contact.point - centre) - 0.1) < 0.005  # on the ball's surface, at the contact
    free = scenario_from_dict(planar_doc(timing={"duration": 0.2}))
    assert find_contact(simulate(free, "none"), free) is None


def test_a_self_collision_marks_both_links(crossing: tuple[Scenario, RunResult], tmp_path: Path) -> None:
    """A run that hit itself before any obstacle: its first contact is the logged self pair, and the replay turns
    both links red (and no obstacle) from that step on, with a label naming both."""
    scenario, result = crossing
    hit = np.zeros(result.steps, dtype=bool)
    hit[5:] = True
    folded = dataclasses.replace(result, self_collision=hit, self_pair=np.where(hit, 0, -1),
                                 self_pairs=(("link1", "link3"),))
    contact = find_contact(folded, scenario)
    assert contact is not None and contact.step == 5 and contact.links == ("link1", "link3")
    assert contact.obstacle is None and contact.text == f"self-collision at t = {result.t[5]:.2f} s: link1 hits link3"
    document = recorded(write_replay(folded, tmp_path / "r.html", scenario=scenario, fps=10.0).read_text())
    red = {m["name"]: t for t, m in messages(document, "SceneNodeUpdateMessage")
           if tuple(m["updates"].get("color", ())) == RED}
    at = pytest.approx(float(result.t[5]))  # the contact's step is one of the recorded frames
    assert red == {"/arm/link1_0/0": at, "/arm/link3_0/0": at}
    (label,) = [m for _, m in messages(document, "LabelMessage")]
    assert label["props"]["text"] == contact.text


def test_replay_records_arm_ghosts_oracle_obstacles_and_collision(
    crossing: tuple[Scenario, RunResult], tmp_path: Path
) -> None:
    scenario, result = crossing
    offsets = np.array([[0.2, -0.2, 0.1, 0.0], [0.4, -0.3, 0.2, 0.1]])
    targets = result.q[:, None, :] + offsets[None]
    targets[:20] = np.nan  # no imaginary arm computed yet
    previewing = dataclasses.replace(result, targets=targets, target_S=np.ones((result.steps, 2)))
    oracle = dataclasses.replace(result, controller="oracle", q=result.q + 0.05)
    path = write_replay(previewing, tmp_path / "r.html", scenario=scenario, oracle=oracle, fps=10.0)
    document = recorded(path.read_text())
    assert document["durationSeconds"] == pytest.approx(1.2 + HOLD)
    meshes = {m["name"]: m["props"] for _, m in messages(document, "MeshMessage")}
    assert {n for n in meshes if n.startswith("/arm/")} == {f"/arm/link{i}_0/0" for i in range(1, 5)}
    for root, rgba in (("/ghost0/", GHOST_RGBA[0]), ("/ghost1/", GHOST_RGBA[1]), ("/oracle/", ORACLE_RGBA)):
        ghost = [props for name, props in meshes.items() if name.startswith(root)]
        assert len(ghost) == 4 and all(props["opacity"] == pytest.approx(rgba[3]) for props in ghost)
    assert {"/obstacles/ball/0", "/obstacles/wall/0"} <= set(meshes)
    # ghosts hidden while no target exists, shown from t = 0.2 s on
    shown = [(t, m["visible"]) for t, m in messages(document, "SetSceneNodeVisibilityMessage", "/ghost0/link1_0")
             if not m["name"].endswith("/0")]
    assert shown[0] == (0.0, True) and (0.0, False) in shown and shown[-1][1] is True
    assert min(t for t, visible in shown if visible and t > 0) == pytest.approx(0.2)
    # the ball moves, the last frame at its collision place
    ball = messages(document, "SetPositionMessage", "/obstacles/ball")
    np.testing.assert_allclose(ball[-1][1]["position"], [0.33, 0.08, 0.0], atol=1e-9)
    assert ball[-1][0] == pytest.approx(1.2)
    # at t = 1.2 s, and not before: link 1 and the ball turn red, the marker shows, the label names both
    red = {m["name"]: t for t, m in messages(document, "SceneNodeUpdateMessage")
           if tuple(m["updates"].get("color", ())) == RED}
    assert red == {"/arm/link1_0/0": pytest.approx(1.2), "/obstacles/ball/0": pytest.approx(1.2)}
    marker = messages(document, "SetSceneNodeVisibilityMessage", "/collision/marker")
    assert [(t, m["visible"]) for t, m in marker] == [(0.0, False), (pytest.approx(1.2), True)]
    (label,) = [m for _, m in messages(document, "LabelMessage")]
    assert label["props"]["text"] == "collision at t = 1.20 s: link1 hits ball"
    trace = messages(document, "LineSegmentsMessage", "/path/trace/")
    assert len(trace) == 12 and trace[-1][0] == pytest.approx(1.2)


def test_view_command_finds_the_scenario_and_the_oracle_beside_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``run --view`` writes the replay; ``view`` rewrites it from the folder, the oracle's run beside it."""
    scenario = load_scenario(Path(__file__).parents[1] / "scenarios" / "planar_free.toml")
    out = tmp_path / "planar_free"
    assert main(["run", str(scenario.source), "--out", str(out / "none"), "--no-gif", "--view"]) == 0
    first = recorded((out / "none" / REPLAY_NAME).read_text())
    assert not messages(first, "MeshMessage", "/oracle/")
    save_run(dataclasses.replace(simulate(scenario, "none"), controller="oracle"), out / "oracle")
    capsys.readouterr()
    assert main(["view", str(out / "none"), "--fps", "5"]) == 0
    assert re.fullmatch(rf"written {re.escape(str(out / 'none' / REPLAY_NAME))} \(\d+\.\d MB\): open it in a browser\n",
                        capsys.readouterr().out)
    again = recorded((out / "none" / REPLAY_NAME).read_text())
    assert len(messages(again, "MeshMessage", "/oracle/")) == 4
    assert sorted(p.name for p in (out / "none").iterdir() if p.name.startswith(".")) == []  # no temporary left


def test_bad_inputs_are_named(crossing: tuple[Scenario, RunResult], tmp_path: Path,
                              capsys: pytest.CaptureFixture[str]) -> None:
    scenario, result = crossing
    with pytest.raises(PreviewctlError, match=r"a RunResult needs the path of the HTML file"):
        write_replay(result)
    with pytest.raises(PreviewctlError, match=r"fps must be > 0, got 0"):
        write_replay(result, tmp_path / "r.html", scenario=scenario, fps=0.0)
    panda = load_scenario(Path(__file__).parents[1] / "scenarios" / "panda_crossing.toml")
    with pytest.raises(PreviewctlError, match=r"run 'planar_test' has 4 joints; scenario 'panda_crossing'.* has 7"):
        write_replay(result, tmp_path / "r.html", scenario=panda)
    save_run(result, tmp_path / "run")
    with pytest.raises(PreviewctlError, match=r"scenario 'planar_test': no shipped scenario has that name "
                                              r"\(panda_crossing, paper_fitted.*\); pass its scenario file"):
        write_replay(tmp_path / "run")
    assert main(["view", str(tmp_path / "nothing")]) == 2
    missing = str(tmp_path / "nothing")
    assert capsys.readouterr().err == f"previewctl: error: no run in {missing!r}: run.npz is missing\n"
    assert not (tmp_path / "run" / REPLAY_NAME).exists()


def test_live_replay_follows_the_slider_back_and_forth(crossing: tuple[Scenario, RunResult]) -> None:
    """The live viewer's slider shows any time: the arm where the log has it, the collision only from 1.2 s on."""
    import viser

    scenario, result = crossing
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        live = live_replay(server, result, scenario)
        meshes = live.scene.arm.meshes
        link1 = live.scene.arm.parts["link1"][0][0]
        for t, k, collided in ((1.2, 120, True), (0.3, 30, False), (0.9, 90, False)):
            live.slider.value = t
            for frame, placement in zip(live.scene.arm.frames, meshes.placements(result.q[k]), strict=True):
                np.testing.assert_allclose(frame.position, placement.translation, atol=1e-12)
            assert live.scene.marker.visible is collided and live.scene.label.visible is collided
            assert tuple(link1.color) == (RED if collided else (89, 140, 217))  # ARM_RGBA in 0-255
            ball = live.scene.obstacles[0].frame.position
            np.testing.assert_allclose(ball, [0.33, -0.4 + 0.4 * t, 0.0], atol=1e-12)
        assert server.get_host() == "127.0.0.1"
    finally:
        server.stop()


def test_ten_second_panda_replay_with_three_ghosts_stays_under_10_mb(tmp_path: Path) -> None:
    """The size budget: a Panda's meshes are stored once (the ghosts share them), poses at 15 frames/s."""
    scenario = load_scenario(Path(__file__).parents[1] / "scenarios" / "panda_crossing.toml")
    short = dataclasses.replace(scenario, timing=dataclasses.replace(scenario.timing, duration=0.05))
    head = simulate(short, "none")
    t = np.arange(1001) * 0.01
    q = scenario.q0 + 0.3 * np.sin(t)[:, None] * np.linspace(1.0, 0.4, 7)
    fields = {f.name: getattr(head, f.name) for f in dataclasses.fields(RunResult)}
    stretched = {name: np.repeat(value[:1], t.size, axis=0) for name, value in fields.items()
                 if isinstance(value, np.ndarray) and value.ndim and value.shape[0] == head.steps}
    result = RunResult(**{**fields, **stretched, "t": t, "q": q,
                          "targets": q[:, None, :] + np.array([0.2, 0.4, 0.6])[None, :, None],
                          "target_S": np.ones((t.size, 3))})
    path = write_replay(result, tmp_path / "panda.html", scenario=scenario)
    document = recorded(path.read_text())
    assert document["durationSeconds"] == pytest.approx(10.0 + HOLD)
    assert len(messages(document, "MeshMessage", "/ghost2/")) == len(messages(document, "MeshMessage", "/arm/")) > 20
    assert path.stat().st_size < 10e6


# ---------------------------------------------------------------------------------------- browser

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
SWIFTSHADER = ["--use-gl=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist", "--no-sandbox"]


@pytest.fixture(scope="module")
def page(crossing: tuple[Scenario, RunResult], tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """The colliding run's replay, opened from disk in headless Chromium and paused; console and requests logged."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("playwright is not installed (pip install '.[test]'; .ci/run installs it)")
    if CHROMIUM is None:
        pytest.skip("no chromium on PATH (Debian: apt-get install chromium; .ci/run installs it)")
    scenario, result = crossing
    html = write_replay(result, tmp_path_factory.mktemp("replay") / REPLAY_NAME, scenario=scenario)
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=SWIFTSHADER)
        tab = browser.new_page(viewport={"width": 480, "height": 360})
        tab.problems, tab.requests = [], []
        tab.on("console", lambda m: tab.problems.append(m.text) if m.type == "error" else None)
        tab.on("pageerror", lambda e: tab.problems.append(str(e)))
        tab.on("request", lambda r: tab.requests.append(r.url))
        tab.goto(html.as_uri())
        tab.wait_for_selector(".mantine-Slider-track", timeout=60_000)
        tab.evaluate("document.querySelector('.mantine-Slider-root').parentElement.querySelector('button').click()")
        tab.evaluate("document.querySelector('.mantine-Notification-closeButton')?.click()")
        yield tab
        browser.close()


def screenshot_at(page: Any, fraction: float) -> tuple[float, np.ndarray]:
    """Seek the slider to ``fraction`` of the replay; the time shown [s] and the 3-D view (RGB, player bar cut off)."""
    from PIL import Image

    track = page.locator(".mantine-Slider-track").bounding_box()
    page.mouse.click(track["x"] + fraction * track["width"], track["y"] + track["height"] / 2)
    page.evaluate("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
    page.wait_for_timeout(300)
    time = float(page.locator("[role=slider]").get_attribute("aria-valuenow"))
    image = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)
    return time, image[: int(track["y"]) - 20]


def red_pixels(image: np.ndarray) -> int:
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    return int(np.count_nonzero((r > 150) & (g < 90) & (b < 90)))


def test_replay_renders_in_chromium_moves_with_the_slider_and_shows_the_collision(page: Any) -> None:
    before_time, before = screenshot_at(page, 0.15)
    end_time, end = screenshot_at(page, 0.97)
    assert page.problems == []
    assert [url for url in page.requests if not url.startswith(("file:", "data:", "blob:"))] == []  # offline
    assert 0.2 < before_time < 0.5 and end_time > 1.2  # the slider moved the replay (the end holds 1 s)
    background = np.median(before.reshape(-1, 3), axis=0)
    drawn = np.abs(before - background).sum(axis=2) > 60
    assert drawn.mean() > 0.02  # the canvas is not blank: the arm, the obstacles, the grid
    changed = np.abs(end - before).sum(axis=2) > 60
    assert changed.sum() > 500  # the ball crossed, the arm moved
    assert red_pixels(before) == 0 and red_pixels(end) > 200  # the collision marker, link and ball in red
