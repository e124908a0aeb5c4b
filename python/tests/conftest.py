"""Shared fixtures: the repository's scenarios and the twincell command line, whose outputs the
package's functions must reproduce, and frames rendered by it with their ground truth."""

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = ROOT / "scenarios"
PAPER_50 = SCENARIOS / "paper_50.toml"


def _binary():
    """The twincell binary: $TWINCELL_BIN (scripts/test.sh sets it to the one cargo built),
    else `twincell` on PATH. Missing, the tests that need it fail: none is skipped."""
    path = os.environ.get("TWINCELL_BIN") or shutil.which("twincell")
    if not path or not Path(path).is_file():
        pytest.fail(
            "the twincell binary is needed to render frames and compare outputs: set "
            "TWINCELL_BIN or put twincell on PATH (bash scripts/test.sh does)"
        )
    return path


@pytest.fixture(scope="session")
def twincell_bin():
    return _binary()


def run_cli(binary, *args):
    """Runs `twincell ARGS...` and returns its stdout parsed as JSON."""
    done = subprocess.run(
        [binary, *map(str, args)], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, f"twincell {' '.join(map(str, args))}: {done.stderr}"
    return json.loads(done.stdout)


def load_png(path):
    """An 8-bit RGB PNG as a numpy uint8 H x W x 3 array."""
    from PIL import Image

    with Image.open(path) as image:
        return np.asarray(image.convert("RGB"), dtype=np.uint8).copy()


class Shot:
    """A rendered pick-station frame with its calibration and ground truth."""

    def __init__(self, directory):
        self.dir = Path(directory)
        self.png = self.dir / "shot.png"
        self.json_path = self.dir / "shot.json"
        self.meta = json.loads(self.json_path.read_text())
        self.image = load_png(self.png)

    @property
    def objects(self):
        return self.meta["objects"]

    def calibration(self, plane_height_m):
        return dict(self.meta["calibration"], plane_height_m=plane_height_m)


# Frames over the scenario's space: indices draw each frame's part type, pose, bottle and
# sensor realism from the scenario seed.
SHOT_INDICES = (0, 3, 7, 12)


@pytest.fixture(scope="session")
def shots(twincell_bin, tmp_path_factory):
    out = []
    for index in SHOT_INDICES:
        directory = tmp_path_factory.mktemp(f"shot{index}")
        done = subprocess.run(
            [twincell_bin, "render", str(PAPER_50), "--out", str(directory),
             "--index", str(index)],
            capture_output=True, text=True, check=False,
        )
        assert done.returncode == 0, done.stderr
        out.append(Shot(directory))
    return out
