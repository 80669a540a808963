"""The stages of the method, each the same as the ``pganeus`` command of the same name.

A call turns its keywords into the command's flags (``iterations=1000`` is ``--iterations 1000``,
``no_preview=True`` is ``--no-preview``, a list repeats the flag) and runs the stage in this process through
the command's own parser, so the defaults, the checks and the files written are the command's. Each page of
docs/commands/ lists a stage's flags; every flag is a keyword here.

The stages release the GIL while they run. ``progress`` receives each event as a dict (``event`` is one of
``started``, ``progress``, ``status``, ``finished``, ``note``; ``task``, ``what``, ``steps``, ``done``,
``text`` as they apply); ``print_progress`` prints them. Ctrl-C, or an exception raised by ``progress``,
stops the stage (its outputs are written whole or not at all) and is raised here. Failures raise
``PganeusError`` or one of its kinds (``InputError``, ``SettingsError``, ``OutputTakenError``,
``StageError``) with the command's message.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any, Callable, Mapping, Optional

from ._pganeus import run_command

Progress = Optional[Callable[[dict], Any]]
PathLike = "str | os.PathLike[str]"


def _flag_words(options: Mapping[str, Any]) -> list[str]:
    words: list[str] = []
    for key, value in options.items():
        if value is None or value is False:
            continue
        flag = "--" + key.rstrip("_").replace("_", "-")
        if value is True:
            words.append(flag)
        elif isinstance(value, (list, tuple)):
            for item in value:
                words += [flag, _word(item)]
        else:
            words += [flag, _word(value)]
    return words


def _word(value: Any) -> str:
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _run(name: str, positional: list[Any], options: Mapping[str, Any], progress: Progress) -> Optional[str]:
    argv = [name] + [_word(p) for p in positional] + _flag_words(options)
    return run_command(argv, progress)


def print_progress(event: dict) -> None:
    """A ``progress`` callback that prints notes, and each task's start and end, to standard error."""
    kind = event["event"]
    if kind == "note":
        print(event["text"], file=sys.stderr)
    elif kind == "started":
        print(f"[{event['task']}] {event['what']} ({event['steps']} steps)", file=sys.stderr)
    elif kind == "finished":
        print(f"[{event['task']}] done", file=sys.stderr)


def train(capture: PathLike, out: PathLike, *, progress: Progress = None, **options: Any) -> Path:
    """Trains a NeuS field on ``capture`` (NeuS layout) into the run folder ``out``; returns ``out``.

    Options as ``pganeus train``: ``kind`` ("object" or "scene"), ``preset``, ``iterations``, ``config``,
    ``resume``, ``force``, ``no_preview``, ``preview_res``.
    """
    _run("train", [capture], {"out": out, **options}, progress)
    return Path(out)


def merge(a: PathLike, b: PathLike, out: PathLike, *, progress: Progress = None, **options: Any) -> Path:
    """Merges an object's two training runs (two resting poses) into one closed mesh in ``out``; returns ``out``.

    Options as ``pganeus merge``: ``capture_a``, ``capture_b``, ``res``, ``field_res``, ``faces``, ``start``, ...
    """
    _run("merge", [a, b], {"out": out, **options}, progress)
    return Path(out)


def bake(source: PathLike, out: PathLike, *, progress: Progress = None, **options: Any) -> Path:
    """Bakes a scene run (or a mesh) into the SDF grid the simulator collides with; returns ``out``.

    Options as ``pganeus bake``: ``res``, ``bounds`` (a list of six), ``floor``, ``no_floor``, ``smooth``, ...
    """
    _run("bake", [source], {"out": out, **options}, progress)
    return Path(out)


def mesh(run: PathLike, out: PathLike, *, progress: Progress = None, **options: Any) -> Path:
    """The zero level of a training run as a mesh file ``out``; returns ``out``. Options as ``pganeus mesh``."""
    _run("mesh", [run], {"out": out, **options}, progress)
    return Path(out)


def fit(
    video: PathLike,
    *,
    scene: PathLike,
    objects: Mapping[str, PathLike],
    out: PathLike,
    init: PathLike = "auto",
    progress: Progress = None,
    **options: Any,
) -> Optional[str]:
    """Fits each body's pose in every frame of ``video`` and the physics that explains it (first pose, PA, GA,
    PGA) into the fit folder ``out``; returns the fit's summary line.

    ``objects`` maps each body's name (the video's ``mask_<NAME>/``) to its ``merge`` output. Options as
    ``pganeus fit``: ``scene_grid``, ``stages`` (a list of "first", "pa", "ga", "pga"), ``config``,
    ``frames``, ``fps``, ``shutter``, ``density``, ``no_pa``, ``no_ga``, ``force``.
    """
    if not objects:
        raise ValueError("fit: give at least one body in objects={name: merge folder}")
    words = {"scene": scene, "object": [f"{n}={os.fspath(p)}" for n, p in objects.items()], "init": init, "out": out}
    if "stages" in options and options["stages"] is not None and not isinstance(options["stages"], str):
        options = {**options, "stages": ",".join(options["stages"])}
    return _run("fit", [video], {**words, **options}, progress)


def eval(fit: PathLike, truth: PathLike, *, progress: Progress = None, **options: Any) -> Path:  # noqa: A001
    """Scores the fit folder ``fit`` against a scene's ``truth.json`` (writes ``eval.json`` and ``eval.csv``
    in it unless ``out``/``csv`` say otherwise); returns the path of the JSON report.

    Options as ``pganeus eval``: ``video`` (the video's name in the truth), ``samples``, ``out``, ``csv``.
    """
    _run("eval", [fit], {"truth": truth, **options}, progress)
    return Path(options.get("out") or Path(fit) / "eval.json")


def report(dir: PathLike, *, progress: Progress = None, **options: Any) -> Path:  # noqa: A002
    """One self-contained HTML page for a run folder; returns its path. Options as ``pganeus report``."""
    _run("report", [dir], options, progress)
    return Path(options.get("out") or Path(dir) / "report.html")


def calibrate(
    dirs: "list[PathLike]", *, board: PathLike, out: PathLike, progress: Progress = None, **options: Any
) -> Path:
    """Cameras and lens from photos and videos of a printed board, written as NeuS captures in ``out``;
    returns ``out``. Options as ``pganeus calibrate``: ``scene`` (list), ``video`` (list), ``lens_only``,
    ``width``, ``intrinsics``, ``region``, ``fps``, ...
    """
    if isinstance(dirs, (str, os.PathLike)):
        dirs = [dirs]
    _run("calibrate", list(dirs), {"board": board, "out": out, **options}, progress)
    return Path(out)


def masks(
    capture: PathLike,
    *,
    scene: Optional[PathLike] = None,
    body: str = "body",
    progress: Progress = None,
    **options: Any,
) -> Path:
    """Masks computed without a network; returns their folder. For a video (``scene``: the scene's run),
    the moving ``body`` against the scene rendered through the video's camera (``mask_<body>/``); for a
    static object capture (no ``scene``), the object against the board from its photos alone (``mask/``).
    Options as ``pganeus masks``: ``out``.
    """
    if scene is None:
        _run("masks", [capture], options, progress)
        return Path(options.get("out") or Path(capture) / "mask")
    _run("masks", [capture], {"scene": scene, "body": body, **options}, progress)
    return Path(options.get("out") or Path(capture) / f"mask_{body}")


def synth(out: PathLike, *, preset: Optional[str] = "tabletop", progress: Progress = None, **options: Any) -> Path:
    """A synthetic dataset with its truth (captures, videos, ``truth.json``); returns ``out``.

    Options as ``pganeus synth``: ``scene`` (a scene file instead of ``preset``), ``scale`` ("small",
    "large"), ``physics`` ("pganeus", "rapier"), ``camera_like``, ``raw``, ``contact_sheet``, ``force``.
    """
    if options.get("scene") is not None:
        preset = None
    _run("synth", [], {"preset": preset, "out": out, **options}, progress)
    return Path(out)


def demo(out: Optional[PathLike] = None, *, progress: Progress = None, **options: Any) -> Path:
    """The whole method on a synthetic scene (synth, train, merge, bake, fit, eval, report); returns the path
    of ``report.md``. Options as ``pganeus demo``: ``quick``, ``preset``, ``physics``, ``scale``,
    ``camera_like``, ``force``.
    """
    report_path = _run("demo", [], {"out": out, **options}, progress)
    return Path(report_path) if report_path else Path(out or ".") / "report.md"
