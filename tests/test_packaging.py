"""The distribution: ``hatchling build`` gives a wheel and an sdist; the wheel, installed on its own, runs.

The wheel is installed with ``pip install --no-deps --target`` into a folder outside the repository, and a
fresh interpreter (``-I``: no ``PYTHONPATH``, no working directory on the path) imports previewctl from that
folder, the dependencies coming from this environment. It never skips: without hatchling (the ``test`` extra)
it fails. It takes a few seconds.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
TIMEOUT = 600.0
"""[s] for the build, the install and the import: seconds are typical, a loaded shared host is slow."""

INSTALLED_CHECK = """
import sys
sys.path.insert(0, sys.argv[1])
import importlib.metadata, json
from pathlib import Path
import numpy as np
import previewctl as pc

package = Path(pc.__file__).parent
robot = pc.load_robot(package / "robots" / "planar4.urdf")  # a URDF path, no robot name
path = pc.HandPath([[1.9069, 1.0417], [1.7, 1.2]], duration=2.0)
ctrl = pc.make_controller("qp", robot=robot, path=path)
qdot = ctrl.step(np.array([0.6, 1.0, -1.2, -1.0]), 0.0)
dist = importlib.metadata.distribution("previewctl")
(script,) = [e for e in dist.entry_points if e.group == "console_scripts"]
print(json.dumps({
    "package": str(package), "dist": str(dist.locate_file("")), "version": dist.version,
    "files": sorted(str(p.relative_to(package)) for p in package.rglob("*") if p.suffix in (".typed", ".urdf",
                                                                                               ".srdf", ".toml")),
    "script": [script.name, script.value], "qdot": qdot.tolist(),
    "by_name": pc.load_robot("planar4").self_pairs.source,
}))
"""


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    done = subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=TIMEOUT)
    assert done.returncode == 0, done.stderr
    return done


@pytest.fixture(scope="module")
def dist(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The folder of the wheel and the sdist built from this tree."""
    if importlib.util.find_spec("hatchling") is None:
        pytest.fail("the packaging test needs hatchling: install the test extra (pip install '.[test]')")
    out = tmp_path_factory.mktemp("dist")
    _run([sys.executable, "-m", "hatchling", "build", "-d", str(out)], REPO)
    return out


def test_the_installed_wheel_imports_ships_its_data_and_steps_a_controller_on_a_urdf_path(
    dist: Path, tmp_path: Path
) -> None:
    (wheel,) = dist.glob("*.whl")
    target = tmp_path / "site"
    _run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-index", "--target", str(target),
          str(wheel)], tmp_path)
    assert (target / "bin" / "previewctl").is_file()  # the console script
    found = json.loads(_run([sys.executable, "-I", "-c", INSTALLED_CHECK, str(target)], tmp_path).stdout)
    assert Path(found["package"]) == target / "previewctl"  # the wheel's copy, not the source tree
    assert Path(found["dist"]) == target and found["version"] == "0.1.0"
    assert {"py.typed", "robots/planar4.urdf", "robots/planar4.srdf", "scenarios/paper_planar.toml",
            "scenarios/planar_free.toml"} <= set(found["files"])
    assert found["script"] == ["previewctl", "previewctl.cli.main:main"]
    assert found["by_name"] == f"SRDF {target / 'previewctl' / 'robots' / 'planar4.srdf'}"  # shipped beside it
    qdot = found["qdot"]
    assert len(qdot) == 4 and all(abs(v) < 100 for v in qdot) and any(v != 0 for v in qdot)


def test_the_sdist_holds_the_sources_the_tests_and_the_documents(dist: Path) -> None:
    (sdist,) = dist.glob("*.tar.gz")
    with tarfile.open(sdist) as archive:
        names = {n.split("/", 1)[1] for n in archive.getnames() if "/" in n}
    assert {"pyproject.toml", "README.md", "LICENSE", "CHANGELOG.md", "CITATION.cff", "previewctl/py.typed",
            "robots/planar4.urdf", "scenarios/paper_planar.toml", "tests/conftest.py",
            "tests/test_packaging.py"} <= names
    assert not any(n.startswith((".venv/", "site/", "dist/")) or "__pycache__" in n for n in names)


def test_the_wheel_declares_a_lean_core_and_the_extras(dist: Path) -> None:
    """The core a robot computer installs, and the extras for the rest (read from the built metadata)."""
    (wheel,) = dist.glob("*.whl")
    with zipfile.ZipFile(wheel) as archive:
        metadata = archive.read("previewctl-0.1.0.dist-info/METADATA").decode()
    requires = [line.split(": ", 1)[1] for line in metadata.splitlines() if line.startswith("Requires-Dist: ")]
    core = sorted(r.split(">")[0].split(";")[0].strip() for r in requires if "extra ==" not in r)
    assert core == ["coal", "daqp", "numba", "numpy", "pin", "pydantic", "qpsolvers", "tomli", "tqdm"]
    extras = [line.split(": ", 1)[1] for line in metadata.splitlines() if line.startswith("Provides-Extra: ")]
    assert {"viz", "bench", "robots", "all", "test", "dev"} <= set(extras)
