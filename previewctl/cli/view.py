"""``previewctl view``: write a run's 3-D replay, one HTML file that opens from disk in a browser."""

from __future__ import annotations

import argparse
from pathlib import Path

from previewctl.cli.common import Commands, add_json_option, print_json
from previewctl.errors import PreviewctlError
from previewctl.sim.log import load_run
from previewctl.sim.scenario import load_scenario
from previewctl.viz.replay import DEFAULT_FPS, REPLAY_NAME, scenario_of, serve_replay, sibling_oracle, write_replay


def add_parser(commands: Commands) -> None:
    """The ``view`` subcommand and its options."""
    view = commands.add_parser(
        "view",
        help="write a run's 3-D replay (RUN_DIR/replay.html, opens from disk in a browser)",
        description="Write the 3-D replay of a saved run (the folder of run.npz, from 'previewctl run' or "
        "'previewctl paper'): one self-contained HTML file with the arm's meshes, the obstacles, the desired "
        "path and the hand's trace, the imaginary arms as ghosts, the oracle's motion (a sibling 'oracle' "
        "run), the collision highlighted, play/pause and a time slider. No server and no network needed.",
    )
    view.add_argument("run_dir", help="run folder (holds run.npz)")
    view.add_argument("--scenario", help="the run's scenario file (default: the shipped scenario of its name)")
    view.add_argument("--out", help=f"HTML file (default RUN_DIR/{REPLAY_NAME})")
    view.add_argument("--fps", type=float, default=DEFAULT_FPS,
                      help=f"replay frames per second of run time (default {DEFAULT_FPS:g})")
    view.add_argument("--serve", action="store_true",
                      help="instead of the file, show the run live on http://127.0.0.1:PORT (this machine only) "
                      "with a time slider, until Ctrl-C")
    view.add_argument("--port", type=int, default=8080, help="port of --serve (default 8080; the next free one)")
    add_json_option(view, "the file written and its size")
    view.set_defaults(func=cmd_view)


def cmd_view(args: argparse.Namespace) -> int:
    """Write the replay of RUN_DIR and print its path and size (or serve it live with --serve)."""
    if args.serve and args.json:
        raise PreviewctlError("--json reports the file written; --serve writes none: give one of them")
    scenario = load_scenario(args.scenario) if args.scenario else None
    if args.serve:
        folder = Path(args.run_dir)
        result = load_run(folder)
        serve_replay(result, scenario or scenario_of(result), oracle=sibling_oracle(folder, result), port=args.port)
        return 0
    out = write_replay(Path(args.run_dir), args.out, scenario=scenario, fps=args.fps)
    size = out.stat().st_size
    if args.json:
        print_json({"replay": str(out), "bytes": size})
    else:
        print(f"written {out} ({size / 1e6:.1f} MB): open it in a browser")
    return 0
