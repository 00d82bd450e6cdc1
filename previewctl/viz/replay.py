"""A run as a 3-D replay in the browser: one self-contained HTML file (viser's offline player), or live.

:func:`write_replay` records the run's scene (:class:`~previewctl.viz.replay_scene.ReplayScene`: the arm's
meshes, the obstacles moving, the desired path and the hand's trace, the imaginary arms as ghosts, the
oracle's motion, the collision in red) frame after frame and saves it as ``replay.html``: it opens from
disk with no server and no network, with play/pause, a time slider and an orbit camera.
:func:`serve_replay` shows the same scene live, from a local server on 127.0.0.1 with a time slider.

Size: a replay holds every mesh once (viser stores identical buffers once, so ghosts cost no mesh
data) plus the poses of each frame. Frames are taken at ``fps`` (default 15 per second of the run).
"""

from __future__ import annotations

import contextlib
import io
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from previewctl.errors import PreviewctlError
from previewctl.extras import require
from previewctl.files import atomic_write_bytes
from previewctl.sim.log import RunResult, load_run
from previewctl.sim.paper import shipped_scenarios_dir
from previewctl.sim.scenario import Scenario, load_scenario
from previewctl.types import Array
from previewctl.viz.replay_scene import ReplayScene

REPLAY_NAME = "replay.html"
DEFAULT_FPS = 15.0
"""Replay frames per second of run time (the log has 100 per second at dt = 0.01 s)."""
HOLD = 1.0
"""Time [s] the last frame stays on screen (the end of a colliding run is its collision)."""


def frame_steps(t: Array, fps: float, extra: int | None = None) -> Array:
    """Log step indices of the replay frames: the step nearest each ``1/fps`` [s] of run time, the last step and
    ``extra``."""
    times = np.arange(t[0], t[-1], 1.0 / fps)
    after = np.clip(np.searchsorted(t, times), 1, max(t.size - 1, 1))
    nearest = np.where(times - t[after - 1] < t[np.minimum(after, t.size - 1)] - times, after - 1, after)
    steps = np.append(np.minimum(nearest, t.size - 1), t.size - 1)
    if extra is not None:
        steps = np.append(steps, extra)
    return np.unique(steps)


@contextlib.contextmanager
def _server(port: int, quiet: bool) -> Iterator[Any]:
    """A viser server on 127.0.0.1 (port 0: any free port), stopped on exit; ``quiet`` silences its messages."""
    viser = require("viser", "viz", "the browser replay")
    with contextlib.redirect_stdout(io.StringIO()) if quiet else contextlib.nullcontext():
        server = viser.ViserServer(host="127.0.0.1", port=port, verbose=not quiet)
    try:
        yield server
    finally:
        with contextlib.redirect_stdout(io.StringIO()) if quiet else contextlib.nullcontext():
            server.stop()


def replay_html(
    result: RunResult, scenario: Scenario, *, oracle: RunResult | None = None, fps: float = DEFAULT_FPS
) -> str:
    """The replay of ``result`` (in ``scenario``) as one self-contained HTML document.

    Args:
        result: the run.
        scenario: its scenario (robot source, obstacles).
        oracle: the oracle's run of the same scenario, drawn as a translucent green arm.
        fps: replay frames per second of run time.

    Raises:
        PreviewctlError: ``fps`` is not positive, or the run's joints do not match the scenario's robot.
    """
    if not fps > 0:
        raise PreviewctlError(f"fps must be > 0, got {fps}")
    with _server(0, quiet=True) as server:
        replay = ReplayScene(server, result, scenario, oracle)
        steps = frame_steps(result.t, fps, replay.contact.step if replay.contact else None)
        serializer = server.get_scene_serializer()
        for frame, k in enumerate(steps):
            replay.show(int(k))
            replay.add_trace(str(frame), int(steps[max(frame - 1, 0)]), int(k))
            serializer.insert_sleep(float(result.t[steps[frame + 1]] - result.t[k]) if frame + 1 < steps.size else HOLD)
        return serializer.as_html()


@dataclass(frozen=True, eq=False)
class LiveReplay:
    """A run shown live: its scene and the GUI handles that drive it."""

    scene: ReplayScene
    slider: Any
    playing: Any


def live_replay(server: Any, result: RunResult, scenario: Scenario, oracle: RunResult | None = None) -> LiveReplay:
    """Fill ``server`` with the run's scene, a time slider and a play box (moving the slider shows that time)."""
    replay = ReplayScene(server, result, scenario, oracle)
    slider = server.gui.add_slider("t [s]", min=float(result.t[0]), max=float(result.t[-1]), step=float(result.dt),
                                   initial_value=float(result.t[0]))
    playing = server.gui.add_checkbox("play", initial_value=False)

    def show(_: object = None) -> None:
        k = min(int(np.searchsorted(result.t, slider.value - 0.5 * result.dt)), result.steps - 1)
        replay.show(k)
        replay.add_trace("live", 0, max(k, 1))  # one node, replaced: the slider may go back

    slider.on_update(show)
    show()
    return LiveReplay(replay, slider, playing)


def serve_replay(result: RunResult, scenario: Scenario, *, oracle: RunResult | None = None, port: int = 8080) -> None:
    """Show the run live at ``http://127.0.0.1:<port>`` (this machine only; the next free port if taken) with a
    time slider and a play box, until Ctrl-C."""
    with _server(port, quiet=False) as server:
        live = live_replay(server, result, scenario, oracle)
        period = 1.0 / DEFAULT_FPS
        with contextlib.suppress(KeyboardInterrupt):
            while True:
                time.sleep(period)
                if live.playing.value:  # at the end, start over
                    later = live.slider.value + period
                    live.slider.value = later if later <= result.t[-1] else float(result.t[0])


def scenario_of(result: RunResult) -> Scenario:
    """The shipped scenario a run was made with (``scenarios/<name>.toml``).

    Raises:
        PreviewctlError: no shipped scenario has the run's name (the message says how to pass one).
    """
    path = shipped_scenarios_dir() / f"{result.scenario}.toml"
    if not path.is_file():
        shipped = sorted(p.stem for p in shipped_scenarios_dir().glob("*.toml"))
        raise PreviewctlError(
            f"run of scenario {result.scenario!r}: no shipped scenario has that name ({', '.join(shipped)}); "
            "pass its scenario file (--scenario FILE)"
        )
    return load_scenario(path)


def sibling_oracle(run_dir: Path, result: RunResult) -> RunResult | None:
    """The oracle's run beside ``run_dir`` (``../oracle``, as ``previewctl paper`` writes), if there is one."""
    folder = run_dir.parent / "oracle"
    if result.controller == "oracle" or not (folder / "run.npz").is_file():
        return None
    oracle = load_run(folder)
    return oracle if oracle.scenario == result.scenario else None


def write_replay(
    run: RunResult | str | os.PathLike[str],
    path: str | os.PathLike[str] | None = None,
    *,
    scenario: Scenario | None = None,
    oracle: RunResult | None = None,
    fps: float = DEFAULT_FPS,
) -> Path:
    """Write the 3-D replay of a run as one self-contained HTML file (atomically).

    Args:
        run: the run, or its folder (``run.npz``, as :func:`~previewctl.sim.log.save_run` writes).
        path: the HTML file; default ``<run folder>/replay.html`` (required when ``run`` is a result).
        scenario: the run's scenario; default: the shipped scenario of the run's name.
        oracle: the oracle's run to draw beside it; default for a folder: ``../oracle`` if it holds a run
            of the same scenario.
        fps: replay frames per second of run time.

    Returns:
        The path written.

    Raises:
        PreviewctlError: no run in the folder, no scenario for it, or a file that cannot be written.
        MissingExtraError: viser or trimesh is not installed (``pip install 'previewctl[viz]'``).
    """
    if isinstance(run, RunResult):
        if path is None:
            raise PreviewctlError("write_replay(result, path): a RunResult needs the path of the HTML file")
        result = run
    else:
        folder = Path(run)
        result = load_run(folder)
        if oracle is None:
            oracle = sibling_oracle(folder, result)
        path = folder / REPLAY_NAME if path is None else path
    html = replay_html(result, scenario or scenario_of(result), oracle=oracle, fps=fps)
    out = Path(path)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(out, html.encode("utf-8"))
    except OSError as exc:
        raise PreviewctlError(f"cannot write the replay to {str(out)!r}: {exc}") from exc
    return out
