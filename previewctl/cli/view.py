"""``previewctl view``: write a run's 3-D replay, one HTML file that opens from disk in a browser."""

from __future__ import annotations

import argparse
from pathlib import Path

from previewctl.cli.common import Commands
from previewctl.sim.scenario import load_scenario
from previewctl.viz.replay import DEFAULT_FPS, REPLAY_NAME, write_replay


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
    view.set_defaults(func=cmd_view)


def cmd_view(args: argparse.Namespace) -> int:
    """Write the replay of RUN_DIR and print its path and size."""
    scenario = load_scenario(args.scenario) if args.scenario else None
    out = write_replay(Path(args.run_dir), args.out, scenario=scenario, fps=args.fps)
    print(f"written {out} ({out.stat().st_size / 1e6:.1f} MB): open it in a browser")
    return 0
