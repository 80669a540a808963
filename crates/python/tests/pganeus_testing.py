"""Helpers shared by the Python package's tests and the workflow's (`workflow/tests` puts this folder on its
path; they run in a venv without the package, so nothing here imports `pganeus`): the small fit settings,
the `pganeus` command, a folder's contents without wall-clock times, and a first-pose guess from a truth."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[3]
TINY_SCENE = REPO / "scenes" / "synth_tiny_slide.toml"

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

# Keys whose values are wall-clock times: all two runs of the same stage may differ in.
TIME_KEYS = {"timings_s", "seconds"}


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
    raise FileNotFoundError("no pganeus command: build it (cargo build --profile test -p pganeus) or set PGANEUS_BIN")


def without_times(value):
    if isinstance(value, dict):
        return {k: without_times(v) for k, v in value.items() if k not in TIME_KEYS and not k.endswith("_s")}
    if isinstance(value, list):
        return [without_times(v) for v in value]
    return value


def contents(folder: Path, roots=(), skip=()) -> dict:
    """Every file under `folder` but `skip` (names, or first path parts): text files with each of `roots`
    (the folder as the commands were given it) written as ROOT, JSON without its times, the rest as bytes."""
    out = {}
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        rel = path.relative_to(folder)
        if rel.parts[0] in skip or path.name in skip:
            continue
        if path.suffix in (".json", ".jsonl", ".toml", ".csv"):
            text = path.read_text()
            for root in sorted(roots, key=len, reverse=True):
                text = text.replace(root, "ROOT")
            if path.suffix == ".json":
                out[str(rel)] = without_times(json.loads(text))
            elif path.suffix == ".jsonl":
                out[str(rel)] = [without_times(json.loads(line)) for line in text.splitlines() if line.strip()]
            else:
                out[str(rel)] = text
        else:
            out[str(rel)] = path.read_bytes()
    return out


def pose_matrix(t, q) -> np.ndarray:
    """The 4 × 4 body-to-world matrix of a translation and a quaternion [w, x, y, z]."""
    w, x, y, z = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    m = np.eye(4)
    m[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                 [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                 [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
    m[:3, 3] = t
    return m


def quaternion(r: np.ndarray) -> np.ndarray:
    """The unit quaternion [w, x, y, z] of a rotation matrix (w >= 0)."""
    w = np.sqrt(max(0.0, 1 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    x = np.copysign(np.sqrt(max(0.0, 1 + r[0, 0] - r[1, 1] - r[2, 2])) / 2, r[2, 1] - r[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1 - r[0, 0] + r[1, 1] - r[2, 2])) / 2, r[0, 2] - r[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1 - r[0, 0] - r[1, 1] + r[2, 2])) / 2, r[1, 0] - r[0, 1])
    q = np.array([w, x, y, z])
    return q / np.linalg.norm(q)


def first_pose_guess(truth_file: Path, video: str, body: str, capture: str) -> dict:
    """An init.json entry from the truth: where the body's frame in `capture` sits in the video's frame 0."""
    truth = json.loads(Path(truth_file).read_text())
    in_capture = next(c["pose"] for b in truth["bodies"] if b["name"] == body for c in b["static_captures"]
                      if c["capture"] == capture)
    v = next(v for v in truth["videos"] if v["capture"] == video)
    at_start = next(b["initial"] for b in v["bodies"] if b["name"] == body)
    m = pose_matrix(at_start["t"], at_start["q"]) @ np.linalg.inv(pose_matrix(in_capture["t"], in_capture["q"]))
    return {"capture": capture, "t": list(m[:3, 3]), "q": list(quaternion(m[:3, :3]))}
