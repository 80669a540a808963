"""The stages from Python: the same files as the command, errors as exceptions, progress to a callback."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import pganeus

from pganeus_testing import TINY_SCENE, cli_binary, contents


@pytest.fixture(scope="module")
def fitted(tiny):
    """The tiny slide fitted by `pganeus.fit` (3 frames, the small settings), with the events it reported."""
    events = []
    summary = pganeus.fit(
        tiny["data"] / "slide",
        scene=tiny["scene"],
        objects={"box": tiny["box"]},
        out=tiny["dir"] / "fit_py",
        init=tiny["init"],
        scene_grid=tiny["grid"],
        config=tiny["config"],
        frames=3,
        progress=events.append,
    )
    return {"dir": tiny["dir"] / "fit_py", "summary": summary, "events": events}


def test_fit_writes_what_the_command_writes(tiny, fitted):
    d = tiny["dir"]
    summary, events = fitted["summary"], fitted["events"]
    assert summary and "trajectory.json" in summary
    cli = subprocess.run(
        [str(cli_binary()), "fit", str(tiny["data"] / "slide"), "--scene", str(tiny["scene"]),
         "--object", f"box={tiny['box']}", "--init", str(tiny["init"]), "--scene-grid", str(tiny["grid"]), "--out", str(d / "fit_cli"),
         "--config", str(tiny["config"]), "--frames", "3"],
        capture_output=True, text=True,
    )
    assert cli.returncode == 0, cli.stderr
    # Each run's own folder named as ROOT where a file records it; everything else, settings included, alike.
    py, sh = contents(d / "fit_py", roots=[str(d / "fit_py")]), contents(d / "fit_cli", roots=[str(d / "fit_cli")])
    assert sorted(py) == sorted(sh)
    assert "trajectory.json" in py and "config.toml" in py
    for name in py:
        assert py[name] == sh[name], f"{name} differs between pganeus.fit and the command"
    # The progress went to the callback: tasks started and finished, and their steps counted.
    kinds = {e["event"] for e in events}
    assert {"started", "progress", "finished"} <= kinds
    assert all(isinstance(e["task"], int) for e in events if e["event"] != "note")


def test_a_fit_read_back(fitted):
    run = pganeus.load_run(fitted["dir"])
    assert isinstance(run, pganeus.FitRun) and run.bodies == ["box"]
    final = run.poses()
    assert final.shape == (3, 7)
    np.testing.assert_allclose(np.linalg.norm(final[:, 3:], axis=1), 1.0, atol=1e-9)
    assert set(run.stages()) >= {"final", "first", "ga", "pga", "simulated"}
    for stage in run.stages():
        assert run.poses("box", stage).shape == ((1, 7) if stage == "first" else (3, 7)), stage
    m = run.pose_matrices()
    assert m.shape == (3, 4, 4)
    np.testing.assert_allclose(m[:, :3, :3] @ m[:, :3, :3].transpose(0, 2, 1), np.tile(np.eye(3), (3, 1, 1)), atol=1e-9)
    physics = run.physics()
    box = physics["bodies"]["box"]
    assert box["mass"] > 0 and box["initial"]["v"].shape == (3,)
    assert 0 < physics["contact"]["restitution"] < 1 and 0 < physics["contact"]["friction"] < 1
    v, f = run.mesh()
    assert v.shape[1] == 3 and f.shape[1] == 3 and f.max() < len(v)
    grid = run.scene_grid()
    assert grid["values"].ndim == 3 and grid["spacing"] > 0
    camera = run.camera()
    assert camera["K"].shape == (3, 3) and camera["W2C"].shape == (4, 4)
    # The fitted world, simulated here, draws the fit's own simulated poses.
    world = run.world()
    simulated = pganeus.poses_from_states(world.simulate())[:, 0]
    np.testing.assert_allclose(simulated[:, :3], run.poses(stage="simulated")[:, :3], atol=1e-6)


def test_eval_and_its_frames(tiny, fitted, tmp_path):
    # A copy: eval writes into the fit folder, which the other tests compare with the command's.
    fit_dir = Path(shutil.copytree(fitted["dir"], tmp_path / "fit"))
    report = pganeus.eval(fit_dir, tiny["data"] / "truth.json", video="slide")
    assert report == fit_dir / "eval.json" and report.exists()
    frames = pganeus.load_run(fit_dir).eval_frames()["box"]
    assert frames["position_mm"].shape == (3,) and np.all(np.isfinite(frames["position_mm"]))


def test_training_runs_and_captures_read_back(tiny):
    scene = pganeus.load_run(tiny["scene"])
    assert isinstance(scene, pganeus.TrainRun)
    assert scene.config["iterations"] == 20
    losses = pganeus.load_run(tiny["box"]).losses()
    assert "loss.rgb" in losses and len(losses["loss.rgb"]) == len(losses["step"]) > 0
    v, f = pganeus.load_run(tiny["box"]).mesh()
    assert len(v) > 0 and len(f) > 0
    cams = pganeus.read_cameras(tiny["data"] / "box_a")
    n = len(cams["names"])
    assert n == 8 and cams["K"].shape == (n, 3, 3) and cams["W2C"].shape == (n, 4, 4)
    # The world frame's origin seen by each camera: in front of it (OpenCV: z forward).
    assert np.all(cams["W2C"][:, 2, 3] > 0)
    truth = json.loads((tiny["data"] / "truth.json").read_text())
    assert truth["bodies"][0]["name"] == "box"


def test_errors_carry_the_commands_messages(tiny, tmp_path):
    with pytest.raises(pganeus.InputError, match="nowhere"):
        pganeus.train(tmp_path / "nowhere", tmp_path / "run")
    with pytest.raises(pganeus.SettingsError, match="--iterationz"):
        pganeus.train(tiny["data"] / "box_a", tmp_path / "run", iterationz=3)
    with pytest.raises(pganeus.PganeusError):
        pganeus.fit(tiny["data"] / "slide", scene=tmp_path / "no_scene", objects={"box": tiny["box"]},
                    out=tmp_path / "fit")
    assert not (tmp_path / "fit" / "trajectory.json").exists()
    with pytest.raises(pganeus.InputError, match="not a run folder"):
        pganeus.load_run(tmp_path)


def test_a_raising_callback_stops_the_stage(tiny, tmp_path):
    class Enough(Exception):
        pass

    def stop(event):
        if event["event"] == "progress":
            raise Enough()

    with pytest.raises(Enough):
        pganeus.train(tiny["data"] / "box_a", tmp_path / "stopped", iterations=50, progress=stop)
    assert not (tmp_path / "stopped" / "preview.ply").exists()


def test_a_demo_folder_read_back(tiny, fitted, tmp_path):
    # A demo's layout, its parts the tiny run's: data/, runs/, fits/, scene.sdf, demo.json.
    demo = tmp_path / "demo"
    (demo / "runs").mkdir(parents=True)
    (demo / "fits").mkdir()
    (demo / "data").symlink_to(tiny["data"])
    (demo / "runs" / "scene").symlink_to(tiny["scene"])
    (demo / "fits" / "slide").symlink_to(fitted["dir"])
    (demo / "scene.sdf").symlink_to(tiny["grid"])
    (demo / "demo.json").write_text(json.dumps({"done": {"fit slide": {"argv": ["fit"], "seconds": 1.0}}}))
    run = pganeus.load_run(demo)
    assert isinstance(run, pganeus.DemoRun)
    assert list(run.fits) == ["slide"] and list(run.runs) == ["scene"] and run.objects == {}
    truth = run.true_poses("slide", "box")
    written = json.loads((tiny["data"] / "truth.json").read_text())["videos"][0]["bodies"][0]["poses"]
    np.testing.assert_array_equal(truth, [p["t"] + p["q"] for p in written])
    np.testing.assert_array_equal(run.fits["slide"].poses("box"), pganeus.load_run(fitted["dir"]).poses("box"))
    assert run.scene_grid()["values"].shape == tuple(pganeus.read_sdf_grid(tiny["grid"])["values"].shape)
    with pytest.raises(ValueError, match="no video"):
        run.true_poses("drop")


def test_merge_mesh_and_report(tiny, fitted, tmp_path):
    box_b = pganeus.train(tiny["data"] / "box_b", tmp_path / "box_b", iterations=20, no_preview=True)
    merged = pganeus.merge(tiny["box"], box_b, tmp_path / "merged", capture_a=tiny["data"] / "box_a",
                           capture_b=tiny["data"] / "box_b", res=48, field_res=64)
    run = pganeus.load_run(merged)
    assert isinstance(run, pganeus.MergeRun)
    v, f = run.mesh()
    assert len(v) > 0 and f.max() < len(v)
    # The merged mesh is in the second capture's frame: its centre of mass where the box lay there (5 mm: the
    # fields had 20 steps).
    tri = v[f]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    volume = np.einsum("ij,ij->i", tri[:, 0], cross) / 6
    centre = (volume[:, None] * tri.sum(axis=1) / 4).sum(axis=0) / volume.sum()
    truth = json.loads((tiny["data"] / "truth.json").read_text())
    lay = next(c["pose"]["t"] for c in truth["bodies"][0]["static_captures"] if c["capture"] == "box_b")
    assert np.linalg.norm(centre - lay) < 0.005, (centre, lay)
    out = pganeus.mesh(tiny["box"], tmp_path / "box.ply", res=32)
    assert pganeus.read_mesh(out)[1].shape[1] == 3
    page = pganeus.report(fitted["dir"], out=tmp_path / "report.html")
    assert page.exists() and "<html" in page.read_text()[:1000].lower()


def test_calibrate_a_raw_session(tmp_path):
    # The tiny scene with raw footage of a printed ChArUco board through a distorting lens, at 384 x 288.
    data = pganeus.synth(tmp_path / "data", preset=None, scene=TINY_SCENE,
                         raw="charuco", raw_size="384x288")
    raw = data / "raw"
    out = pganeus.calibrate([raw / "box_a"], board=raw / "board.toml", out=tmp_path / "captures",
                            scene=[raw / "background"], video=[raw / "slide"], lens_only=[raw / "calibration"],
                            width=64)
    calibrated = pganeus.read_cameras(out / "background")
    truth = pganeus.read_cameras(data / "background")
    assert calibrated["names"] and len(calibrated["names"]) == len(truth["names"])
    centres = lambda w2c: np.einsum("nij,nj->ni", -w2c[:, :3, :3].transpose(0, 2, 1), w2c[:, :3, 3])
    error = np.linalg.norm(centres(calibrated["W2C"]) - centres(truth["W2C"]), axis=1)
    assert error.max() < 0.01, error  # metres: the board's world is the truth's
    assert (out / "slide").is_dir() and (out / "calibration.json").exists()


def test_masks_of_a_video_and_of_an_object_capture(tiny, tmp_path):
    video = pganeus.masks(tiny["data"] / "slide", scene=tiny["scene"], body="box", out=tmp_path / "video_masks")
    frames = sorted(video.iterdir())
    assert video == tmp_path / "video_masks" and len(frames) == 4, frames
    capture = tmp_path / "box_a"
    shutil.copytree(tiny["data"] / "box_a", capture, ignore=shutil.ignore_patterns("mask"))
    photos = pganeus.masks(capture, out=tmp_path / "object_masks")
    assert len(list(photos.iterdir())) == len(list((capture / "image").iterdir()))
