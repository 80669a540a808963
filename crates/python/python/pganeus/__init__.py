"""pganeus: neural surfaces and rigid-body physics from camera footage (PGA-NeuS), from Python.

- Runs read back as numpy arrays: ``load_run(path)`` for a training run, a merge, a fit or a demo folder.
- The differentiable simulator: ``World`` (a scene, bodies, contact values), ``World.simulate`` and
  ``World.simulate_with_gradients`` (exact derivatives by dual numbers); ``pganeus.torch`` wraps it as an
  autograd function when PyTorch is installed.
- Every stage of the method, the same as the command of the same name (the same files written):
  ``train``, ``merge``, ``bake``, ``mesh``, ``fit``, ``eval``, ``report``, ``calibrate``, ``masks``,
  ``synth``, ``demo``.

Conventions (docs/formats.md): metres, z up, OpenCV cameras, quaternions ``[w, x, y, z]``.
"""

from ._pganeus import (
    InputError,
    OutputTakenError,
    PganeusError,
    SettingsError,
    StageError,
    World,
    __version__,
    read_cameras,
    read_mesh,
    read_sdf_grid,
)
from .runs import DemoRun, FitRun, MergeRun, Run, TrainRun, load_run, world_from_fit
from .stages import (
    bake,
    calibrate,
    demo,
    eval,
    fit,
    masks,
    merge,
    mesh,
    print_progress,
    report,
    synth,
    train,
)
from .transforms import pose_matrices, poses_from_states

__all__ = [
    "DemoRun",
    "FitRun",
    "InputError",
    "MergeRun",
    "OutputTakenError",
    "PganeusError",
    "Run",
    "SettingsError",
    "StageError",
    "TrainRun",
    "World",
    "__version__",
    "bake",
    "calibrate",
    "demo",
    "eval",
    "fit",
    "load_run",
    "masks",
    "merge",
    "mesh",
    "pose_matrices",
    "poses_from_states",
    "print_progress",
    "read_cameras",
    "read_mesh",
    "read_sdf_grid",
    "report",
    "synth",
    "train",
    "world_from_fit",
]
