"""Run folders read back: a training run, a merge, a fit and a demo, as numpy arrays and dicts.

``load_run(path)`` tells the kind by the files in the folder (docs/formats.md lists them):

========== =========================================== =========
kind       files                                       class
========== =========================================== =========
demo       ``demo.json``                               DemoRun
fit        ``trajectory.json`` (or ``ga.json``, ...)   FitRun
merge      ``merged.ply``                              MergeRun
training   ``checkpoint.safetensors``                  TrainRun
========== =========================================== =========
"""

from __future__ import annotations

import csv
import json
import os
from functools import cached_property
from pathlib import Path
from typing import Any, Optional

import numpy as np

from ._pganeus import InputError, World, read_cameras, read_mesh, read_sdf_grid
from .transforms import pose_matrices

try:  # Python 3.11+
    import tomllib as _toml
except ImportError:  # pragma: no cover - Python 3.10
    _toml = None


def _read_json(path: Path) -> Any:
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except json.JSONDecodeError as e:
        raise InputError(f"{path}: not valid JSON: {e}") from None


def _read_jsonl(path: Path) -> list[dict]:
    if not path.exists():
        return []
    with open(path, encoding="utf-8") as f:
        return [json.loads(line) for line in f if line.strip()]


def _pose_rows(poses: list[dict]) -> np.ndarray:
    return np.array([list(p["t"]) + list(p["q"]) for p in poses], dtype=np.float64).reshape(-1, 7)


class Run:
    """A run folder: its path and its log."""

    kind = "run"

    def __init__(self, path: "str | os.PathLike[str]"):
        self.path = Path(path)
        if not self.path.is_dir():
            raise InputError(f"{self.path}: not a folder")

    @property
    def log(self) -> list[dict]:
        """The run's ``log.jsonl``, one dict a line (empty when there is none)."""
        return _read_jsonl(self.path / "log.jsonl")

    def __repr__(self) -> str:
        return f"{type(self).__name__}({str(self.path)!r})"


class TrainRun(Run):
    """A ``train`` run: ``checkpoint.safetensors``, ``config.toml``, ``log.jsonl``, ``preview.ply``."""

    kind = "train"

    @property
    def config(self) -> dict:
        """The training settings (``config.toml``)."""
        path = self.path / "config.toml"
        if _toml is None:
            raise InputError(f"{path}: reading TOML needs Python 3.11 (tomllib)")
        with open(path, "rb") as f:
            return _toml.load(f)

    def mesh(self) -> "tuple[np.ndarray, np.ndarray]":
        """The preview mesh of the zero level, ``(vertices float64[N,3], faces uint32[M,3])``."""
        return read_mesh(self.path / "preview.ply")

    def losses(self) -> "dict[str, np.ndarray]":
        """Each logged quantity of the training steps over the logged steps: ``step``, ``psnr``, ``lr``, the
        loss terms as ``loss.rgb``, ``loss.eikonal``, ..."""
        rows = []
        for r in self.log:
            if "step" not in r:
                continue
            flat = {k: v for k, v in r.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
            for k, v in (r.get("loss") or {}).items() if isinstance(r.get("loss"), dict) else []:
                flat[f"loss.{k}"] = v
            rows.append(flat)
        keys = sorted({k for r in rows for k in r})
        return {k: np.array([r.get(k, np.nan) for r in rows], dtype=np.float64) for k in keys}


class MergeRun(Run):
    """A ``merge`` output: ``merged.ply`` (the closed mesh in the second capture's frame) and
    ``transform.json`` (the first capture's frame to the second's)."""

    kind = "merge"

    def mesh(self) -> "tuple[np.ndarray, np.ndarray]":
        """The merged closed mesh in the second capture's frame, ``(vertices float64[N,3], faces uint32[M,3])``."""
        return read_mesh(self.path / "merged.ply")

    @property
    def transform(self) -> dict:
        """``transform.json``: how the two captures' frames were aligned."""
        return _read_json(self.path / "transform.json")


class FitRun(Run):
    """A ``fit`` folder: each body's poses per stage, the fitted physics with its ranges, the scores of
    ``eval`` when it ran, the meshes and the scene grid the fitted world simulates in."""

    kind = "fit"

    #: The stages whose poses a fit folder keeps, and their files (``final``: what the fit reports).
    STAGE_FILES = {
        "final": "trajectory.json",
        "first": "first_pose.json",
        "pa": "pa.json",
        "ga": "ga.json",
        "ga_tracked": "ga_tracked.json",
        "pga": "pga.json",
        "pga_tracked": "pga_tracked.json",
    }

    @cached_property
    def trajectory(self) -> dict:
        """``trajectory.json`` as written (docs/formats.md), read once."""
        return _read_json(self.path / "trajectory.json")

    @property
    def bodies(self) -> "list[str]":
        """The bodies' names, in the fit's order."""
        return [b["name"] for b in self.trajectory["bodies"]]

    @property
    def fps(self) -> float:
        return float(self.trajectory["fps"])

    def stages(self) -> "list[str]":
        """The stages whose poses this folder holds."""
        return [s for s, f in self.STAGE_FILES.items() if (self.path / f).exists()] + (
            ["simulated"] if (self.path / "trajectory.json").exists() else []
        )

    def _body(self, doc: dict, body: Optional[str]) -> dict:
        entries = doc["bodies"]
        if body is None:
            if len(entries) != 1:
                raise ValueError(f"{self.path}: {len(entries)} bodies; name one of {[b['name'] for b in entries]}")
            return entries[0]
        for b in entries:
            if b["name"] == body:
                return b
        raise ValueError(f"{self.path}: no body {body!r} (bodies: {[b['name'] for b in entries]})")

    def poses(self, body: Optional[str] = None, stage: str = "final") -> np.ndarray:
        """``float64[T, 7]`` poses ``[t, q(w, x, y, z)]`` of ``body`` (the only one when None) in every frame,
        as ``stage`` left them: ``final`` (reported), ``simulated`` (the fitted physics simulated), or a
        stage's own file (``pa``, ``ga``, ``ga_tracked``, ``pga``, ``pga_tracked``); ``first`` is the first
        stage's pose of frame 0 alone, ``[1, 7]``."""
        if stage == "simulated":
            return _pose_rows([f["simulated"] for f in self._frames(body)])
        if stage not in self.STAGE_FILES:
            raise ValueError(f"stage {stage!r}: one of {sorted(self.STAGE_FILES) + ['simulated']}")
        doc = _read_json(self.path / self.STAGE_FILES[stage])
        if stage == "first":
            return self._first_pose(doc, body)
        return _pose_rows(self._body(doc, body)["poses"])

    def _first_pose(self, doc: dict, body: Optional[str]) -> np.ndarray:
        """The first stage's pose of frame 0 as ``[1, 7]`` (one body: the file is the pose; several: by name)."""
        if "bodies" not in doc:
            return _pose_rows([doc])
        names = sorted(doc["bodies"])
        if body is None:
            if len(names) != 1:
                raise ValueError(f"{self.path}: {len(names)} bodies; name one of {names}")
            body = names[0]
        if body not in doc["bodies"]:
            raise ValueError(f"{self.path}: no body {body!r} (bodies: {names})")
        return _pose_rows([doc["bodies"][body]])

    def pose_matrices(self, body: Optional[str] = None, stage: str = "final") -> np.ndarray:
        """``float64[T, 4, 4]`` body-to-world matrices of :meth:`poses`."""
        return pose_matrices(self.poses(body, stage))

    def _frames(self, body: Optional[str]) -> "list[dict]":
        """The per-frame rows of ``trajectory.json`` of a body (one body: the file's own ``frames``)."""
        t = self.trajectory
        b = self._body(t, body)
        return b["frames"] if "frames" in b else t["frames"]

    def reported_from(self, body: Optional[str] = None) -> "list[str]":
        """Per frame, which estimate the reported pose is (``simulated``, ``ga``, ...)."""
        return [f["pose"] for f in self._frames(body)]

    def physics(self) -> dict:
        """The fitted physics: per body its mass, initial state (``t``, ``q``, ``v``, ``omega``) and contact
        values with the scene; the scene's contact values and, per pair, the pair's; each value's range
        ``[lo, hi]`` where the fit profiled one (``restitution_range``, ``friction_range``)."""
        t = self.trajectory
        bodies = {}
        for b in t["bodies"]:
            entry = {"mass": b.get("mass"), "initial": {k: np.array(v) for k, v in b["initial"].items()}}
            entry.update(b.get("contact", {}))
            if "start" in b:
                entry["start"] = b["start"]
            bodies[b["name"]] = entry
        contact = {k: v for k, v in t.get("contact", {}).items() if k != "pairs"}
        pairs = {tuple(p["bodies"]): {k: v for k, v in p.items() if k not in ("bodies", "contact")} for p in t.get("contact", {}).get("pairs", [])}
        return {"bodies": bodies, "contact": contact, "pairs": pairs, "horizon": t.get("horizon"), "sim": t.get("sim")}

    @property
    def eval(self) -> Optional[dict]:
        """``eval.json`` when ``eval`` scored this fit, else None."""
        p = self.path / "eval.json"
        return _read_json(p) if p.exists() else None

    def eval_frames(self) -> "dict[str, dict[str, np.ndarray]]":
        """``eval.csv`` per body: each column (``position_mm``, ``rotation_deg``, ``silhouette_iou``,
        ``sim_position_mm``, ...) as an array over the frames (NaN where a frame has no value)."""
        p = self.path / "eval.csv"
        if not p.exists():
            raise InputError(f"{p}: no such file (run pganeus.eval on the fit first)")
        out: dict[str, dict[str, list]] = {}
        with open(p, newline="", encoding="utf-8") as f:
            for row in csv.DictReader(f):
                cols = out.setdefault(row["body"], {})
                for k, v in row.items():
                    if k != "body":
                        cols.setdefault(k, []).append(v)
        return {b: {k: _column(v) for k, v in cols.items()} for b, cols in out.items()}

    def mesh(self, body: Optional[str] = None) -> "tuple[np.ndarray, np.ndarray]":
        """A body's mesh as the fit simulated it (centre of mass at the origin)."""
        b = self._body(self.trajectory, body)
        return read_mesh(self.path / b["object"]["mesh"])

    def scene_grid(self) -> dict:
        """The scene grid the fitted world simulates in (:func:`read_sdf_grid`)."""
        return read_sdf_grid(self.path / "scene_carved.sdf")

    def camera(self) -> dict:
        """The video's fixed camera: ``{"K": [3,3], "W2C": [4,4], "width", "height"}``."""
        video = Path(self.trajectory["video"])
        if not video.is_absolute() and not video.exists():
            video = self.path / video
        cams = read_cameras(video)
        return {"K": cams["K"][0], "W2C": cams["W2C"][0], "width": cams["width"], "height": cams["height"]}

    def world(self) -> World:
        """The fitted world (:func:`world_from_fit`)."""
        return world_from_fit(self.path)


def _column(values: list) -> np.ndarray:
    try:
        return np.array([float(v) if v != "" else np.nan for v in values], dtype=np.float64)
    except ValueError:
        return np.array(values, dtype=object)


class DemoRun(Run):
    """A ``demo`` folder: its dataset (``data/``), training runs (``runs/``), merges (``merged/``), the
    scene grid, the fits (``fits/``) and the report."""

    kind = "demo"

    @property
    def record(self) -> dict:
        """``demo.json``: each stage's command and time."""
        return _read_json(self.path / "demo.json")

    @cached_property
    def truth(self) -> dict:
        """The synthetic dataset's ``truth.json``, read once."""
        return _read_json(self.path / "data" / "truth.json")

    @property
    def runs(self) -> "dict[str, TrainRun]":
        return {p.name: TrainRun(p) for p in sorted((self.path / "runs").glob("*")) if p.is_dir()}

    @property
    def objects(self) -> "dict[str, MergeRun]":
        return {p.name: MergeRun(p) for p in sorted((self.path / "merged").glob("*")) if p.is_dir()}

    @property
    def fits(self) -> "dict[str, FitRun]":
        return {p.name: FitRun(p) for p in sorted((self.path / "fits").glob("*")) if p.is_dir()}

    def scene_grid(self) -> dict:
        return read_sdf_grid(self.path / "scene.sdf")

    def true_poses(self, video: str, body: Optional[str] = None) -> np.ndarray:
        """``float64[T, 7]`` true poses of ``body`` in ``video`` from ``truth.json``."""
        videos = self.truth["videos"]
        v = next((x for x in videos if x["capture"] == video), None)
        if v is None:
            raise ValueError(f"no video {video!r} in the truth (videos: {[x['capture'] for x in videos]})")
        bodies = v["bodies"]
        if body is None:
            if len(bodies) != 1:
                raise ValueError(f"{video}: {len(bodies)} bodies; name one")
            b = bodies[0]
        else:
            b = next((x for x in bodies if x["name"] == body), None)
            if b is None:
                raise ValueError(f"{video}: no body {body!r}")
        return _pose_rows(b["poses"])


def load_run(path: "str | os.PathLike[str]") -> Run:
    """The run in folder ``path``: a :class:`DemoRun`, :class:`FitRun`, :class:`MergeRun` or
    :class:`TrainRun`, told by its files."""
    p = Path(path)
    if not p.is_dir():
        raise InputError(f"{p}: no such folder")
    if (p / "demo.json").exists():
        return DemoRun(p)
    if any((p / f).exists() for f in FitRun.STAGE_FILES.values()):
        return FitRun(p)
    if (p / "merged.ply").exists():
        return MergeRun(p)
    if (p / "checkpoint.safetensors").exists():
        return TrainRun(p)
    raise InputError(
        f"{p}: not a run folder (no demo.json, trajectory.json, merged.ply nor checkpoint.safetensors)"
    )


def world_from_fit(path: "str | os.PathLike[str]") -> World:
    """The world a fit ended with: its scene grid (``scene_carved.sdf``), each body's mesh, mass and fitted
    initial state, and the fitted contact values, with the fit's simulation settings. Simulated, it draws
    the poses of the fit's ``simulated`` stage."""
    fit = FitRun(path)
    t = fit.trajectory
    world = World.from_sdf_file(fit.path / "scene_carved.sdf", sim=json.dumps(t["sim"]))
    for b in t["bodies"]:
        v, f = read_mesh(fit.path / b["object"]["mesh"])
        s = b["initial"]
        c = b.get("contact") or t["contact"]
        world.add_body(
            b["name"], vertices=v, faces=f, mass=b["mass"], t=s["t"], q=s["q"], v=s["v"], omega=s["omega"],
            restitution=c["restitution"], friction=c["friction"],
        )
    pairs = t.get("contact", {}).get("pairs", [])
    if pairs:
        names = world.param_names
        params = world.params
        order = world.bodies
        for p in pairs:
            a, b = p["bodies"]
            if order.index(a) > order.index(b):
                a, b = b, a
            params[names.index(f"{a}-{b}.restitution")] = p["restitution"]
            params[names.index(f"{a}-{b}.friction")] = p["friction"]
        world.set_params(params)
    return world
