"""Fixtures of the Python package's tests: a tiny synthetic capture, its scene and object trained for a few
steps (the stages' plumbing is under test here, not their accuracy), and the `pganeus` command to compare
with (helpers shared with the workflow's tests: `pganeus_testing.py`)."""

from __future__ import annotations

import json

import pytest

import pganeus
from pganeus_testing import SMALL_FIT, TINY_SCENE, cli_binary, first_pose_guess  # noqa: F401 (cli_binary: tests)


@pytest.fixture(scope="session")
def tiny(tmp_path_factory) -> dict:
    """A tiny dataset (`scenes/synth_tiny_slide.toml`), its scene and its box trained 20 steps each, the scene
    baked, the small fit's settings file and a first-pose guess from the truth."""
    d = tmp_path_factory.mktemp("tiny")
    data = pganeus.synth(d / "data", preset=None, scene=TINY_SCENE)
    scene = pganeus.train(data / "background", d / "runs" / "scene", kind="scene", iterations=20, no_preview=True)
    box = pganeus.train(data / "box_a", d / "runs" / "box", iterations=20, preview_res=32)
    grid = pganeus.bake(scene, d / "scene.sdf", res=64)
    config = d / "small_fit.toml"
    config.write_text(SMALL_FIT)
    init = d / "init.json"
    init.write_text(json.dumps({"box": first_pose_guess(data / "truth.json", "slide", "box", "box_a")}))
    return {"dir": d, "data": data, "scene": scene, "grid": grid, "box": box, "config": config, "init": init}
