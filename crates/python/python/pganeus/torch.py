"""The simulator in a PyTorch loss: ``simulate(world, values, wrt)`` is differentiable in ``values``.

Imported only when PyTorch is installed (``pip install torch``); the package itself needs numpy alone.
The gradient is exact (the simulator's dual numbers give the Jacobian of every state; backward multiplies
it by the incoming gradient), computed on the CPU in float64 whatever the tensors' device and dtype.

    import torch, pganeus, pganeus.torch
    world = pganeus.World.on_plane(sim='{"fps": 30, "frames": 20}')
    world.add_body("box", box=[0.03, 0.02, 0.015], mass=0.1, t=[0, 0, 0.2])
    v0 = torch.tensor([0.5, 0.0, 0.0], requires_grad=True)
    states = pganeus.torch.simulate(world, v0, wrt=["box.v.x", "box.v.y", "box.v.z"])
    loss = ((states[:, 0, :3] - target) ** 2).sum()
    loss.backward()  # v0.grad
"""

from __future__ import annotations

from typing import Sequence, Union

import numpy as np
import torch as _torch

from ._pganeus import World

Names = Sequence[Union[str, int]]


class _Simulate(_torch.autograd.Function):
    @staticmethod
    def forward(ctx, values: _torch.Tensor, world: World, wrt: Names) -> _torch.Tensor:  # type: ignore[override]
        names = world.param_names
        columns = [names.index(w) if isinstance(w, str) else int(w) for w in wrt]
        params = np.array(world.params, dtype=np.float64)
        params[columns] = values.detach().to("cpu", _torch.float64).numpy().reshape(-1)
        if ctx.needs_input_grad[0]:
            states, jac, _ = world.simulate_with_gradients(params, wrt=columns)
            ctx.save_for_backward(_torch.from_numpy(jac))
        else:
            states = world.simulate(params)
        ctx.like = values
        return _torch.from_numpy(states).to(values.device, values.dtype)

    @staticmethod
    def backward(ctx, grad_states: _torch.Tensor):  # type: ignore[override]
        (jac,) = ctx.saved_tensors
        g = grad_states.detach().to("cpu", _torch.float64)
        grad = _torch.einsum("tbsw,tbs->w", jac, g)
        like = ctx.like
        return grad.to(like.device, like.dtype).reshape(like.shape), None, None


def simulate(world: World, values: _torch.Tensor, wrt: Names) -> _torch.Tensor:
    """Every body's state in every frame, ``[frames, bodies, 13]``, with the parameters ``wrt`` (names of
    ``world.param_names`` or indices) set to ``values`` and the others as ``world`` holds them;
    differentiable in ``values``."""
    if values.numel() != len(wrt):
        raise ValueError(f"{values.numel()} values for {len(wrt)} parameters in wrt")
    return _Simulate.apply(values, world, list(wrt))
