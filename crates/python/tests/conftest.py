"""Fixtures of the Python package's tests: a tiny synthetic capture, its scene and object trained for a few
steps (the stages' plumbing is under test here, not their accuracy), and the `pganeus` command to compare
with."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

import pganeus

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[2]

# A fit small enough for a test (the settings of crates/pipeline/tests/fits.rs's CI-sized fits).
SMALL_FIT = """
launch_frames = 2
rounds = 1
pga_multi_start = false
[first_pose]
iterations = 30
rays_per_step = 128
[pa]
iterations = 20
rays_per_frame = 64
window_steps = 5
[ga]
contact_points = 8
[ga.pose]
iterations = 10
rays_per_step = 128
[ga.end_search]
screened = 2
screen_iterations = 5
refined = 1
twin_iterations = 5
[ga.end_search.refine]
iterations = 10
rays_per_step = 128
[pga]
iterations = 10
[auto_init]
screened = 2
screen_iterations = 5
refined = 1
twin_iterations = 5
[auto_init.refine]
iterations = 10
rays_per_step = 128
"""


def cli_binary() -> Path:
    """The `pganeus` command: $PGANEUS_BIN, else the workspace's test or release build, else on PATH."""
    given = os.environ.get("PGANEUS_BIN")
    if given:
        return Path(given)
    for candidate in (REPO / "target" / "debug" / "pganeus", REPO / "target" / "release" / "pganeus"):
        if candidate.exists():
            return candidate
    found = shutil.which("pganeus")
    if found:
        return Path(found)
    pytest.fail("no pganeus command: build it (cargo build --profile test -p pganeus) or set PGANEUS_BIN")


@pytest.fixture(scope="session")
def tiny(tmp_path_factory) -> dict:
    """A tiny dataset (`scenes/synth_tiny_slide.toml`), its scene and its box trained 20 steps each, and the
    small fit's settings file."""
    d = tmp_path_factory.mktemp("tiny")
    data = pganeus.synth(d / "data", preset=None, scene=REPO / "scenes" / "synth_tiny_slide.toml")
    scene = pganeus.train(data / "background", d / "runs" / "scene", kind="scene", iterations=20, no_preview=True)
    box = pganeus.train(data / "box_a", d / "runs" / "box", iterations=20, preview_res=32)
    grid = pganeus.bake(scene, d / "scene.sdf", res=64)
    config = d / "small_fit.toml"
    config.write_text(SMALL_FIT)
    init = d / "init.json"
    init.write_text(json.dumps({"box": first_pose_guess(data / "truth.json", "slide", "box", "box_a")}))
    return {"dir": d, "data": data, "scene": scene, "grid": grid, "box": box, "config": config, "init": init}


def first_pose_guess(truth_file: Path, video: str, body: str, capture: str) -> dict:
    """An init.json entry from the truth: where the body's frame in `capture` sits in the video's frame 0."""
    truth = json.loads(truth_file.read_text())
    in_capture = next(c["pose"] for b in truth["bodies"] if b["name"] == body for c in b["static_captures"]
                      if c["capture"] == capture)
    v = next(v for v in truth["videos"] if v["capture"] == video)
    at_start = next(b["initial"] for b in v["bodies"] if b["name"] == body)
    to_world = pganeus.pose_matrices(np.array(at_start["t"] + at_start["q"]))
    to_capture = pganeus.pose_matrices(np.array(in_capture["t"] + in_capture["q"]))
    m = to_world @ np.linalg.inv(to_capture)
    return {"capture": capture, "t": list(m[:3, 3]), "q": list(quaternion(m[:3, :3]))}


def quaternion(r: np.ndarray) -> np.ndarray:
    """The unit quaternion [w, x, y, z] of a rotation matrix (w >= 0)."""
    w = np.sqrt(max(0.0, 1 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    x = np.copysign(np.sqrt(max(0.0, 1 + r[0, 0] - r[1, 1] - r[2, 2])) / 2, r[2, 1] - r[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1 - r[0, 0] + r[1, 1] - r[2, 2])) / 2, r[0, 2] - r[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1 - r[0, 0] - r[1, 1] + r[2, 2])) / 2, r[1, 0] - r[0, 1])
    q = np.array([w, x, y, z])
    return q / np.linalg.norm(q)
