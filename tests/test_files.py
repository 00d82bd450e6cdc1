"""Tests of :mod:`previewctl.files`: result files are written completely or not at all."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import pytest

from previewctl.files import atomic_write, save_figure


def test_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "summary.json"
    target.write_bytes(b"old")

    def fail_halfway(handle: object) -> None:
        handle.write(b"partial")  # type: ignore[attr-defined]
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        atomic_write(target, fail_halfway)
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]


def test_save_figure_follows_the_suffix_and_fails_cleanly(tmp_path: Path) -> None:
    fig, ax = plt.subplots()
    try:
        ax.plot([0, 1], [0, 1])
        png = save_figure(fig, tmp_path / "plot.png", dpi=50)
        svg = save_figure(fig, tmp_path / "plot.svg")
        plain = save_figure(fig, tmp_path / "plot", dpi=50)
        with pytest.raises(ValueError, match="xyz"):
            save_figure(fig, tmp_path / "plot.xyz")
    finally:
        plt.close(fig)
    assert png.read_bytes().startswith(b"\x89PNG") and plain.read_bytes().startswith(b"\x89PNG")
    assert b"<svg" in svg.read_bytes()[:500]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plot", "plot.png", "plot.svg"]
