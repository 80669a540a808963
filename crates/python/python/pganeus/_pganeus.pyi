"""Type stubs of the Rust half of pganeus (crates/python/src)."""

from os import PathLike
from typing import Any, Callable, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str

class PganeusError(Exception): ...
class InputError(PganeusError): ...
class SettingsError(PganeusError): ...
class OutputTakenError(PganeusError): ...
class StageError(PganeusError): ...

_Path = Union[str, PathLike[str]]

def run_command(argv: list[str], progress: Optional[Callable[[dict], Any]] = None) -> Optional[str]:
    """Runs the stage `argv` names (the command's words after `pganeus`); what it says at its end."""

def read_mesh(path: _Path) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.uint32]]:
    """`(vertices float64[N,3], faces uint32[M,3])` of a `.ply` or `.obj` mesh."""

def read_sdf_grid(path: _Path) -> dict[str, Any]:
    """`{"values": float32[nx,ny,nz], "origin": (x,y,z), "spacing": h}` of a baked `.sdf` grid."""

def read_cameras(capture: _Path) -> dict[str, Any]:
    """`{"names", "K": float64[N,3,3], "W2C": float64[N,4,4], "width", "height"}` of a NeuS capture."""

class World:
    """A rigid-body world: a static scene, bodies, contact values; simulated with exact gradients."""

    @staticmethod
    def on_plane(normal: Sequence[float] = ..., offset: float = ..., sim: Optional[str] = None) -> World: ...
    @staticmethod
    def on_grid(values: npt.ArrayLike, origin: Sequence[float], spacing: float, sim: Optional[str] = None) -> World: ...
    @staticmethod
    def from_sdf_file(path: _Path, sim: Optional[str] = None) -> World: ...
    @staticmethod
    def from_scene_file(path: _Path) -> World: ...
    def add_body(
        self,
        name: str,
        *,
        vertices: Optional[npt.ArrayLike] = None,
        faces: Optional[npt.ArrayLike] = None,
        box: Optional[Sequence[float]] = None,
        sphere: Optional[float] = None,
        mass: Optional[float] = None,
        density: Optional[float] = None,
        t: Sequence[float] = ...,
        q: Sequence[float] = ...,
        v: Sequence[float] = ...,
        omega: Sequence[float] = ...,
        restitution: float = 0.5,
        friction: float = 0.3,
        pair_restitution: Optional[float] = None,
        pair_friction: Optional[float] = None,
        contact_points: int = 1000,
        seed: int = 0,
    ) -> int: ...
    @property
    def bodies(self) -> list[str]: ...
    @property
    def masses(self) -> list[float]: ...
    @property
    def param_names(self) -> list[str]: ...
    @property
    def params(self) -> npt.NDArray[np.float64]: ...
    def set_params(self, params: npt.NDArray[np.float64]) -> None: ...
    frames: int
    substeps: int
    fps: float
    contact_model: str
    def simulate(self, params: Optional[npt.NDArray[np.float64]] = None) -> npt.NDArray[np.float64]:
        """States `float64[frames, bodies, 13]`: `t(3), q(4) w,x,y,z, v(3), omega(3)`."""
    def simulate_with_gradients(
        self, params: Optional[npt.NDArray[np.float64]] = None, wrt: Optional[Sequence[Union[str, int]]] = None
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.int64]]:
        """`(states [T,B,13], jacobian [T,B,13,W], wrt [W])`."""
