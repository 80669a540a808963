"""Fit the launch velocity of a dropped box from its poses with the simulator's exact gradients.

The "measured" poses are a simulation with a launch the fit does not know, plus 1 mm of noise; the fit
starts from rest and takes Gauss-Newton steps on the poses' squared error, the Jacobian from
``World.simulate_with_gradients``. With ``--torch`` the same fit runs as a PyTorch loss through
``pganeus.torch.simulate`` (needs torch).

    python examples/python/fit_launch.py [--torch]
"""

from __future__ import annotations

import argparse
import json

import numpy as np

import pganeus

TRUE_V0 = np.array([0.45, -0.2, 0.8])
WRT = ["box.v.x", "box.v.y", "box.v.z"]


def dropped_box() -> pganeus.World:
    world = pganeus.World.on_plane(sim=json.dumps({"fps": 30.0, "frames": 24, "substeps": 10}))
    q = [0.9659, 0.0, 0.2588, 0.0]  # tilted 30 degrees: it lands on an edge
    world.add_body("box", box=[0.03, 0.02, 0.015], mass=0.1, t=[0.0, 0.0, 0.15], q=q,
                   restitution=0.4, friction=0.3)
    return world


def measured_positions(world: pganeus.World, rng: np.random.Generator) -> np.ndarray:
    params = world.params.copy()
    for name, v in zip(WRT, TRUE_V0):
        params[world.param_names.index(name)] = v
    positions = world.simulate(params)[:, 0, :3]
    return positions + rng.normal(scale=0.001, size=positions.shape)


def fit_numpy(world: pganeus.World, target: np.ndarray) -> np.ndarray:
    names = world.param_names
    columns = [names.index(n) for n in WRT]
    params = world.params.copy()
    for step in range(10):
        states, jac, _ = world.simulate_with_gradients(params, wrt=WRT)
        r = (states[:, 0, :3] - target).reshape(-1)
        J = jac[:, 0, :3, :].reshape(-1, len(WRT))
        delta = np.linalg.lstsq(J, -r, rcond=None)[0]
        params[columns] += delta
        print(f"step {step}: rms {np.sqrt(np.mean(r**2)) * 1000:.2f} mm, v0 = {np.round(params[columns], 4)}")
        if np.abs(delta).max() < 1e-6:
            break
    return params[columns]


def fit_torch(world: pganeus.World, target: np.ndarray) -> np.ndarray:
    import torch

    import pganeus.torch

    v0 = torch.zeros(3, dtype=torch.float64, requires_grad=True)
    goal = torch.from_numpy(target)
    optimiser = torch.optim.Adam([v0], lr=0.05)
    for step in range(300):
        optimiser.zero_grad()
        states = pganeus.torch.simulate(world, v0, WRT)
        loss = ((states[:, 0, :3] - goal) ** 2).mean()
        loss.backward()
        optimiser.step()
        if step % 50 == 0:
            print(f"step {step}: rms {loss.item() ** 0.5 * 1000:.2f} mm, v0 = {v0.detach().numpy().round(4)}")
    return v0.detach().numpy()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--torch", action="store_true", help="fit through pganeus.torch (PyTorch's Adam)")
    args = parser.parse_args()
    world = dropped_box()
    target = measured_positions(world, np.random.default_rng(0))
    v0 = fit_torch(world, target) if args.torch else fit_numpy(world, target)
    error = np.linalg.norm(v0 - TRUE_V0) / np.linalg.norm(TRUE_V0)
    print(f"fitted v0 {np.round(v0, 4)} m/s, true {TRUE_V0}: {100 * error:.2f} % off")


if __name__ == "__main__":
    main()
