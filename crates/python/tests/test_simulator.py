"""The simulator from Python: free flight, a slide's stop, the exact gradients against finite differences,
a scene file, and the errors it raises."""

from __future__ import annotations

import json

import numpy as np
import pytest

import pganeus

G = 9.81


def sliding_box(frames: int = 12, substeps: int = 10, model: str = "mean_point") -> pganeus.World:
    sim = json.dumps({"fps": 30.0, "frames": frames, "substeps": substeps, "contact_model": model})
    world = pganeus.World.on_plane(sim=sim)
    world.add_body(
        "box", box=[0.03, 0.02, 0.015], mass=0.08, t=[0.0, 0.0, 0.015], v=[0.8, 0.1, 0.0], omega=[0, 0, 1.0],
        restitution=0.4, friction=0.3, contact_points=200, seed=1,
    )
    return world


def test_free_flight_is_a_parabola():
    world = pganeus.World.on_plane(sim=json.dumps({"fps": 30.0, "frames": 8}))
    world.add_body("ball", sphere=0.02, mass=0.05, t=[0.0, 0.0, 1.0], v=[0.3, 0.0, 1.0])
    states = world.simulate()
    assert states.shape == (8, 1, 13)
    time = np.arange(8) / 30.0
    np.testing.assert_allclose(states[:, 0, 0], 0.3 * time, atol=1e-12)
    np.testing.assert_allclose(states[:, 0, 2], 1.0 + time - 0.5 * G * time**2, atol=1e-12)
    np.testing.assert_allclose(states[:, 0, 3:7], np.tile([1.0, 0, 0, 0], (8, 1)), atol=1e-12)


def test_a_slide_stops_where_coulomb_friction_says():
    world = sliding_box(frames=30)
    world.set_params(np.where(np.array(world.param_names) == "box.omega.z", 0.0, world.params))
    states = world.simulate()
    v0 = np.hypot(0.8, 0.1)
    travelled = np.hypot(*(states[-1, 0, :2] - states[0, 0, :2]))
    assert travelled == pytest.approx(v0**2 / (2 * 0.3 * G), rel=0.03)
    assert np.abs(states[-1, 0, 7:10]).max() < 0.005, "at rest (to the pull of gravity within a substep)"


def corner_drop(model: str) -> pganeus.World:
    """A tilted, spinning box dropped onto a corner while sliding: restitution above its threshold and
    friction in the sliding branch both act. 12 frames at 60 fps: before it comes to lie on a face, where the
    mean-point model holds the derivatives of its tilt rate at zero on purpose (docs/contact-model.md)."""
    sim = json.dumps({"fps": 60.0, "frames": 12, "substeps": 10, "contact_model": model})
    world = pganeus.World.on_plane(sim=sim)
    q = np.array([0.93, 0.25, 0.2, 0.18])
    world.add_body(
        "box", box=[0.03, 0.02, 0.015], mass=0.2, t=[0.0, 0.0, 0.06], q=q / np.linalg.norm(q),
        v=[0.8, 0.2, -1.0], omega=[1.0, -2.0, 0.5], restitution=0.4, friction=0.3, contact_points=300, seed=3,
    )
    return world


@pytest.mark.parametrize("model", ["mean_point", "multi_point"])
def test_gradients_match_central_differences(model):
    world = corner_drop(model)
    params = world.params
    names = world.param_names
    states, jac, columns = world.simulate_with_gradients()
    assert jac.shape == states.shape + (len(names),)
    assert list(columns) == list(range(len(names)))
    np.testing.assert_allclose(states, world.simulate(), rtol=0, atol=1e-12)
    # Both contact values shape the path: the corner hits the board.
    assert np.abs(jac[..., names.index("box.restitution")]).max() > 1e-3
    assert np.abs(jac[..., names.index("box.friction")]).max() > 1e-3
    h = 1e-7  # small enough that no perturbation moves a contact point across the contact threshold
    for k, name in enumerate(names):
        up, down = params.copy(), params.copy()
        up[k] += h
        down[k] -= h
        numeric = (world.simulate(up) - world.simulate(down)) / (2 * h)
        error = np.abs(jac[..., k] - numeric).max()
        assert error < 1e-3 * np.abs(numeric).max() + 1e-6, (name, error, np.abs(numeric).max())


def test_all_gradients_by_default_and_params_given_or_held():
    world = sliding_box(frames=4)
    states, jac, columns = world.simulate_with_gradients()
    assert list(columns) == list(range(len(world.param_names)))
    assert jac.shape == (4, 1, 13, 14)
    # d t / d t0 is the identity in frame 0.
    np.testing.assert_allclose(jac[0, 0, :3, :3], np.eye(3), atol=1e-12)
    moved = world.params.copy()
    moved[0] += 0.01
    assert world.simulate(moved)[0, 0, 0] == pytest.approx(0.01)
    assert world.simulate()[0, 0, 0] == 0.0  # the world itself is unchanged


def test_two_bodies_and_their_pair_values():
    world = pganeus.World.on_plane(sim=json.dumps({"fps": 30.0, "frames": 15}))
    world.add_body("a", box=[0.02, 0.02, 0.02], mass=0.1, t=[-0.1, 0, 0.02], v=[1.2, 0, 0], friction=0.2)
    world.add_body("b", box=[0.02, 0.02, 0.02], mass=0.1, t=[0.05, 0, 0.02], friction=0.2,
                   pair_restitution=0.8, pair_friction=0.1)
    assert world.bodies == ["a", "b"]
    assert world.param_names[-2:] == ["a-b.restitution", "a-b.friction"]
    assert world.params[-2:] == pytest.approx([0.8, 0.1])
    states = world.simulate()
    assert states[-1, 1, 0] > 0.06, "a strikes b and b moves along"


def test_a_scene_file(tmp_path):
    scene = tmp_path / "drop.toml"
    scene.write_text(
        """
name = "drop"
[sim]
fps = 30
frames = 20
[contact]
restitution = 0.5
friction = 0.3
[[scene]]
shape = "plane"
[[body]]
name = "box"
shape = { shape = "box", half = [0.03, 0.02, 0.015] }
mass = 0.1
t = [0.0, 0.0, 0.2]
"""
    )
    world = pganeus.World.from_scene_file(scene)
    assert world.bodies == ["box"] and world.frames == 20 and world.fps == 30.0
    states = world.simulate()
    assert states[-1, 0, 2] == pytest.approx(0.015, abs=2e-3), "it lands and rests on its face"


def test_settings_and_their_checks():
    world = sliding_box()
    world.substeps = 20
    world.contact_model = "multi_point"
    assert (world.substeps, world.contact_model) == (20, "multi_point")
    with pytest.raises(pganeus.SettingsError, match="contact_model"):
        world.contact_model = "springs"
    with pytest.raises(pganeus.SettingsError, match="fps"):
        world.fps = -1.0
    assert world.fps == 30.0
    with pytest.raises(pganeus.SettingsError, match="3 values for a world of 14"):
        world.simulate(np.zeros(3))
    with pytest.raises(pganeus.SettingsError, match="no parameter \"box.mass\""):
        world.simulate_with_gradients(wrt=["box.mass"])
    with pytest.raises(pganeus.SettingsError, match="sim"):
        pganeus.World.on_plane(sim='{"substepz": 3}')
    with pytest.raises(pganeus.PganeusError, match="no bodies"):
        pganeus.World.on_plane().simulate()
    with pytest.raises(pganeus.SettingsError, match="box or as sphere"):
        pganeus.World.on_plane().add_body("x", box=[0.1, 0.1, 0.1], sphere=0.1)


def test_missing_files_name_themselves(tmp_path):
    missing = tmp_path / "nowhere.sdf"
    with pytest.raises(pganeus.InputError, match="nowhere.sdf"):
        pganeus.World.from_sdf_file(missing)
    with pytest.raises(pganeus.InputError, match="nowhere.ply"):
        pganeus.read_mesh(tmp_path / "nowhere.ply")
    bad = tmp_path / "bad.toml"
    bad.write_text("[sim]\nfps = -3\n")
    with pytest.raises(pganeus.InputError, match="bad.toml"):
        pganeus.World.from_scene_file(bad)


def test_a_world_on_a_grid_matches_the_same_plane():
    # The board z = 0 as a grid: values = z at each node.
    h = 0.01
    x = np.arange(-20, 21) * h
    z = np.arange(-5, 16) * h
    values = np.broadcast_to(z[None, None, :], (len(x), len(x), len(z))).astype(np.float32)
    sim = json.dumps({"fps": 30.0, "frames": 12})
    on_grid = pganeus.World.on_grid(values, origin=[x[0], x[0], z[0]], spacing=h, sim=sim)
    on_plane = pganeus.World.on_plane(sim=sim)
    for w in (on_grid, on_plane):
        w.add_body("ball", sphere=0.02, mass=0.05, t=[0.0, 0.0, 0.1], v=[0.2, 0.0, 0.0], restitution=0.5)
    np.testing.assert_allclose(on_grid.simulate(), on_plane.simulate(), atol=1e-6)


def test_the_launch_example_recovers_the_launch():
    import subprocess
    import sys
    from pathlib import Path

    example = Path(__file__).resolve().parents[3] / "examples" / "python" / "fit_launch.py"
    out = subprocess.run([sys.executable, str(example)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    off = float(out.stdout.strip().splitlines()[-1].split(": ")[-1].split(" %")[0])
    assert off < 2.0, out.stdout
