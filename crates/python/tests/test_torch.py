"""`pganeus.torch`: the simulator as an autograd function, its gradient the exact Jacobian's product.
Needs PyTorch; skipped where it is not installed (CI: PyPI's wheel brings 2.5 GB of CUDA libraries)."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import pganeus  # noqa: E402
import pganeus.torch  # noqa: E402


def world() -> pganeus.World:
    w = pganeus.World.on_plane(sim=json.dumps({"fps": 30.0, "frames": 12}))
    w.add_body("box", box=[0.03, 0.02, 0.015], mass=0.1, t=[0.0, 0.0, 0.1], q=[0.98, 0.1, 0.15, 0.0],
               restitution=0.4, friction=0.3, contact_points=300)
    return w


WRT = ["box.v.x", "box.v.z", "box.restitution"]


def test_forward_is_the_simulation_and_backward_the_jacobian():
    w = world()
    values = torch.tensor([0.4, 0.3, 0.5], dtype=torch.float64, requires_grad=True)
    states = pganeus.torch.simulate(w, values, WRT)
    params = w.params.copy()
    for name, v in zip(WRT, values.detach().numpy()):
        params[w.param_names.index(name)] = v
    np.testing.assert_allclose(states.detach().numpy(), w.simulate(params), rtol=0, atol=1e-12)
    weights = torch.from_numpy(np.random.default_rng(1).normal(size=tuple(states.shape)))
    (states * weights).sum().backward()
    _, jac, _ = w.simulate_with_gradients(params, wrt=WRT)
    expected = np.einsum("tbsw,tbs->w", jac, weights.numpy())
    np.testing.assert_allclose(values.grad.numpy(), expected, rtol=1e-12, atol=1e-12)


def test_gradcheck_against_finite_differences():
    w = world()
    values = torch.tensor([0.4, 0.3, 0.5], dtype=torch.float64, requires_grad=True)
    # Positions only, where the landing leaves them smooth in these values at this step.
    assert torch.autograd.gradcheck(lambda v: pganeus.torch.simulate(w, v, WRT)[:, :, :3], (values,), eps=1e-7, atol=1e-5)


def test_float32_tensors_and_no_grad():
    w = world()
    values = torch.tensor([0.4, 0.3, 0.5], dtype=torch.float32)
    states = pganeus.torch.simulate(w, values, WRT)
    assert states.dtype == torch.float32 and states.shape == (12, 1, 13) and not states.requires_grad
    with pytest.raises(ValueError, match="3 values for 2"):
        pganeus.torch.simulate(w, values, WRT[:2])
