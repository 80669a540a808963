"""Poses as arrays: ``[..., 7]`` rows ``[t(3), q(4) as w, x, y, z]`` and their ``[..., 4, 4]`` matrices."""

from __future__ import annotations

import numpy as np


def poses_from_states(states: np.ndarray) -> np.ndarray:
    """The poses ``[..., 7]`` of simulated states ``[..., 13]`` (``t``, ``q``, ``v``, ``omega``)."""
    return np.asarray(states)[..., :7]


def pose_matrices(poses: np.ndarray) -> np.ndarray:
    """Body-to-world matrices ``[..., 4, 4]`` of poses ``[..., 7]`` (``p_world = R p_body + t``)."""
    poses = np.asarray(poses, dtype=np.float64)
    t = poses[..., :3]
    q = poses[..., 3:7] / np.linalg.norm(poses[..., 3:7], axis=-1, keepdims=True)
    w, x, y, z = (q[..., i] for i in range(4))
    m = np.zeros(poses.shape[:-1] + (4, 4))
    m[..., 0, 0] = 1 - 2 * (y * y + z * z)
    m[..., 0, 1] = 2 * (x * y - w * z)
    m[..., 0, 2] = 2 * (x * z + w * y)
    m[..., 1, 0] = 2 * (x * y + w * z)
    m[..., 1, 1] = 1 - 2 * (x * x + z * z)
    m[..., 1, 2] = 2 * (y * z - w * x)
    m[..., 2, 0] = 2 * (x * z - w * y)
    m[..., 2, 1] = 2 * (y * z + w * x)
    m[..., 2, 2] = 1 - 2 * (x * x + y * y)
    m[..., :3, 3] = t
    m[..., 3, 3] = 1.0
    return m
