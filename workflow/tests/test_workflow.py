"""The workflow end to end on two tiny synthetic sessions, one calibrated and one raw (imported, its masks
computed): every stage through Snakemake with two cores, the outputs byte for byte those of the commands
run by hand, a second run with nothing to do, a changed setting of one session rerunning that session's
rules alone, a broken session failing alone and named in the summary, the lint, and the Slurm profile's
dry run."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

WORKFLOW = Path(__file__).resolve().parents[1]
REPO = WORKFLOW.parent
SNAKEFILE = WORKFLOW / "Snakefile"
# The helpers the Python package's tests use too (they import nothing of the package).
sys.path.insert(0, str(REPO / "crates" / "python" / "tests"))
from pganeus_testing import SMALL_FIT, TINY_SCENE, cli_binary, contents, first_pose_guess  # noqa: E402

SETTINGS = {"scene_iterations": 20, "object_iterations": 20, "bake_res": 64, "merge_res": 48,
            "merge_field_res": 64, "frames": 3}
# The workflow's own records, which running the commands by hand does not write (report.html records times).
RECORDS = ("logs", "benchmarks", ".snakemake", "report.html")


def run(argv, cwd=None):
    out = subprocess.run([str(a) for a in argv], capture_output=True, text=True, cwd=cwd)
    assert out.returncode == 0, f"{argv}\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}"
    return out


def snakemake(d: Path, *args):
    return run([sys.executable, "-m", "snakemake", "-s", SNAKEFILE, "--configfile", d / "config.yaml",
                "--directory", d, *args])


def init_file(data: Path, path: Path) -> Path:
    """The box's first pose from the truth, as init.json (so that no fit spends its time searching)."""
    path.write_text(json.dumps({"box": first_pose_guess(data / "truth.json", "slide", "box", "box_a")}))
    return path


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    d = tmp_path_factory.mktemp("workflow")
    scene = TINY_SCENE.read_text()
    # The second session: the box launched faster and turning.
    other = scene.replace("v = [0.6, 0.0, 0.0]", "v = [0.8, 0.1, 0.0]").replace("omega = [0.0, 0.0, 0.0]", "omega = [0.0, 0.0, 2.0]")
    assert other != scene
    (d / "two.toml").write_text(other)
    pganeus = str(cli_binary())
    run([pganeus, "synth", "--scene", TINY_SCENE, "--out", d / "data" / "one"])
    # Session two is raw: photos and videos of a printed ChArUco board through a distorting lens, imported by
    # the workflow (its captures at 64 px wide), its masks computed.
    run([pganeus, "synth", "--scene", d / "two.toml", "--out", d / "data" / "two", "--raw", "charuco",
         "--raw-size", "384x288"])
    (d / "small_fit.toml").write_text(SMALL_FIT)
    config = {
        "pganeus": pganeus,
        "out": "results",
        "defaults": {**SETTINGS, "fit_config": str(d / "small_fit.toml")},
        "sessions": {
            "one": {"data": str(d / "data" / "one"), "init": str(init_file(d / "data" / "one", d / "init_one.json"))},
            "two": {"raw": str(d / "data" / "two" / "raw"), "import_width": 64,
                    "truth": str(d / "data" / "two" / "truth.json"),
                    "init": str(init_file(d / "data" / "two", d / "init_two.json"))},
        },
    }
    (d / "config.yaml").write_text(json.dumps(config))  # JSON is YAML
    snakemake(d, "--cores", "2", "--keep-going")
    return {"dir": d, "config": config, "pganeus": pganeus}


def test_every_stage_runs_and_the_summary_has_both_sessions(sessions):
    out = sessions["dir"] / "results"
    for s in ("one", "two"):
        for f in ("runs/scene/checkpoint.safetensors", "runs/box_a/checkpoint.safetensors", "merged/box/merged.ply",
                  "scene.sdf", "fits/slide/trajectory.json", "fits/slide/eval.json", "report.html",
                  "logs/fit_slide.log", "benchmarks/fit_slide.tsv"):
            assert (out / s / f).exists(), f"{s}/{f}"
    # The raw session was imported, and its video's masks computed.
    assert (out / "two" / "data" / "session.json").exists()
    assert len(list((out / "two" / "data" / "slide" / "mask_box").glob("*.png"))) == 4
    summary = (out / "summary.csv").read_text().splitlines()
    assert len(summary) == 3 and all(",scored," in row for row in summary[1:]), summary


def test_the_outputs_are_the_commands_run_by_hand(sessions):
    d, pganeus = sessions["dir"], sessions["pganeus"]
    data, hand = d / "data" / "one", d / "by_hand" / "one"
    s = {**sessions["config"]["defaults"], **sessions["config"]["sessions"]["one"]}
    for capture, kind, iterations in (("background", "scene", s["scene_iterations"]),
                                      ("box_a", "object", s["object_iterations"]),
                                      ("box_b", "object", s["object_iterations"])):
        out = hand / "runs" / ("scene" if kind == "scene" else capture)
        run([pganeus, "train", data / capture, "--out", out, "--kind", kind, "--iterations", iterations, "--force"])
    run([pganeus, "merge", hand / "runs" / "box_a", hand / "runs" / "box_b", "--out", hand / "merged" / "box",
         "--capture-a", data / "box_a", "--capture-b", data / "box_b", "--res", s["merge_res"], "--field-res",
         s["merge_field_res"]])
    run([pganeus, "bake", hand / "runs" / "scene", "--out", hand / "scene.sdf", "--res", s["bake_res"]])
    run([pganeus, "fit", data / "slide", "--scene", hand / "runs" / "scene", "--scene-grid", hand / "scene.sdf",
         "--object", f"box={hand / 'merged' / 'box'}", "--init", s["init"], "--config", s["fit_config"],
         "--frames", s["frames"], "--out", hand / "fits" / "slide", "--force"])
    run([pganeus, "eval", hand / "fits" / "slide", "--truth", data / "truth.json", "--video", "slide"])
    run([pganeus, "report", hand])
    by_hand = contents(hand, roots=[str(hand)], skip=RECORDS)
    by_workflow = contents(d / "results" / "one", roots=[str(d / "results" / "one"), "results/one"], skip=RECORDS)
    assert sorted(by_hand) == sorted(by_workflow)
    for name in by_hand:
        assert by_hand[name] == by_workflow[name], f"{name} differs between the workflow and the commands"


def test_a_second_run_has_nothing_to_do(sessions):
    out = snakemake(sessions["dir"], "--cores", "2", "-n")
    assert "Nothing to be done" in out.stdout + out.stderr, out.stdout


def test_a_changed_setting_reruns_that_session_alone(sessions):
    d = sessions["dir"]
    config = json.loads((d / "config.yaml").read_text())
    config["sessions"]["two"]["bake_res"] = 48
    changed = d / "changed.yaml"
    changed.write_text(json.dumps(config))
    jobs = planned_rules(d, changed)
    assert {r for r, _ in jobs} == {"bake", "fit", "eval", "report"}, jobs
    # Which outputs: session two's alone.
    assert any(o.endswith("results/two/scene.sdf") for _, o in jobs), jobs
    assert all("results/two/" in o for _, o in jobs), jobs


def planned_rules(d: Path, configfile: Path, printed: list[str] | None = None) -> list[tuple[str, str]]:
    """Each job a dry run plans: its rule and its first output (and the whole plan into `printed`)."""
    out = run([sys.executable, "-m", "snakemake", "-s", SNAKEFILE, "--configfile", configfile, "--directory", d,
               "-n", "-p"]).stdout
    if printed is not None:
        printed.append(out)
    jobs, rule = [], None
    for line in out.splitlines():
        if line.startswith(("rule ", "localrule ")):  # a dry run prints "rule", a local run "localrule"
            rule = line.split()[1].rstrip(":")
        elif line.strip().startswith("output:") and rule:
            jobs.append((rule, line.split(":", 1)[1].split(",")[0].strip()))
            rule = None
    return jobs


def test_a_sessions_own_settings_file_reruns_that_session_alone(sessions):
    d = sessions["dir"]
    own = d / "data" / "two" / "raw" / "pganeus.yaml"
    try:
        # The session's folder holds its settings: a changed value reruns what it reaches, in that session only.
        own.write_text("bake_res: 48\n")
        jobs = planned_rules(d, d / "config.yaml")
        assert {r for r, _ in jobs} == {"bake", "fit", "eval", "report"}, jobs
        assert all("results/two/" in o for _, o in jobs), jobs
        # Touching the file without changing a value reruns nothing (Snakemake compares the settings).
        own.write_text("bake_res: 64  # as the defaults say\n")
        out = snakemake(d, "--cores", "2", "-n")
        assert "Nothing to be done" in out.stdout + out.stderr, out.stdout
        # A fit settings file named relative to the session's file (found there: a wrong path would be a missing
        # input): the session's fits, evals and report are planned again, with the new settings.
        fit_settings = own.parent / "fit.toml"
        fit_settings.write_text((d / "small_fit.toml").read_text())
        own.write_text("fit_config: fit.toml\n")
        jobs = planned_rules(d, d / "config.yaml")
        assert {r for r, _ in jobs} == {"fit", "eval", "report"} and all("results/two/" in o for _, o in jobs), jobs
        # A typo is refused by name, not ignored.
        own.write_text("bake_resolution: 48\n")
        out = subprocess.run([sys.executable, "-m", "snakemake", "-s", SNAKEFILE, "--configfile", d / "config.yaml",
                              "--directory", d, "-n"], capture_output=True, text=True)
        assert out.returncode != 0
        assert "pganeus.yaml: unknown setting(s) bake_resolution" in out.stdout + out.stderr, out.stdout + out.stderr
    finally:
        own.unlink(missing_ok=True)
        (own.parent / "fit.toml").unlink(missing_ok=True)


def test_a_session_without_its_folder_is_refused_by_name(sessions):
    d = sessions["dir"]
    config = json.loads((d / "config.yaml").read_text())
    config["sessions"]["lost"] = {"settings": str(d / "nowhere.yaml")}
    (d / "lost.yaml").write_text(json.dumps(config))
    out = subprocess.run([sys.executable, "-m", "snakemake", "-s", SNAKEFILE, "--configfile", d / "lost.yaml",
                          "--directory", d, "-n"], capture_output=True, text=True)
    assert out.returncode != 0
    assert "session lost: give its folder as `data:`" in out.stdout + out.stderr, out.stdout + out.stderr


def test_an_edited_fit_settings_file_reruns_the_fits(sessions):
    d = sessions["dir"]
    fit_settings = d / "small_fit.toml"
    before, stamp = fit_settings.read_text(), fit_settings.stat()
    try:
        fit_settings.write_text(before + "\n# edited\n")
        jobs = planned_rules(d, d / "config.yaml")
        assert {r for r, _ in jobs} == {"fit", "eval", "report"}, jobs
        assert {o.split("/")[1] for _, o in jobs} == {"one", "two"}, jobs
    finally:
        # As it was, its time too: the tests after this one expect nothing to do.
        fit_settings.write_text(before)
        os.utime(fit_settings, ns=(stamp.st_atime_ns, stamp.st_mtime_ns))


def test_a_raw_video_of_several_bodies_is_left_to_the_fit_to_split(sessions):
    # Only the folders' names matter to the plan: a raw session of two objects and one video showing both.
    d = sessions["dir"]
    raw = d / "data" / "pair_raw"
    for folder in ("background", "cup_a", "cup_b", "box_a", "box_b", "push"):
        (raw / folder).mkdir(parents=True, exist_ok=True)
        (raw / folder / "000.png").write_bytes(b"")
    (raw / "board.toml").write_text("")
    config = json.loads((d / "config.yaml").read_text())
    config["sessions"]["pair"] = {"raw": str(raw)}
    (d / "pair.yaml").write_text(json.dumps(config))
    printed: list[str] = []
    jobs = planned_rules(d, d / "pair.yaml", printed)
    assert all("results/pair/" in o for _, o in jobs), jobs
    rules = [r for r, _ in jobs]
    # `masks` tells whatever moves from the scene: with two bodies that is neither's mask, so no masks job.
    assert sorted(rules) == sorted(["import_session", "train_scene", "bake", "fit", "report", "merge", "merge"]
                                   + ["train_object"] * 4), jobs
    fit = next(line for line in printed[0].splitlines() if " fit " in line and "--object" in line)
    assert "--object box=" in fit and "--object cup=" in fit, fit


def test_the_workflow_lints_clean_and_the_slurm_profile_plans(sessions):
    d = sessions["dir"]
    lint = run([sys.executable, "-m", "snakemake", "-s", SNAKEFILE, "--configfile", d / "config.yaml",
                "--directory", d, "--lint"])
    assert "Lints for" not in lint.stdout + lint.stderr
    config = json.loads((d / "config.yaml").read_text())
    config["sessions"]["two"]["scene_iterations"] = 30
    (d / "slurm.yaml").write_text(json.dumps(config))
    plan = run([sys.executable, "-m", "snakemake", "-s", SNAKEFILE, "--configfile", d / "slurm.yaml",
                "--directory", d, "--profile", WORKFLOW / "profiles" / "slurm", "-n"])
    assert "train_scene" in plan.stdout and "results/two/" in plan.stdout, plan.stdout


def test_a_failed_session_keeps_the_others_and_is_in_the_summary(sessions):
    d = sessions["dir"]
    broken = d / "data" / "broken"
    shutil.copytree(d / "data" / "one", broken)
    for image in (broken / "background" / "image").iterdir():
        image.write_bytes(b"not a PNG")
    config = json.loads((d / "config.yaml").read_text())
    config["sessions"]["broken"] = {"data": str(broken), "init": config["sessions"]["one"]["init"]}
    (d / "with_broken.yaml").write_text(json.dumps(config))
    out = subprocess.run([sys.executable, "-m", "snakemake", "-s", SNAKEFILE, "--configfile", d / "with_broken.yaml",
                          "--directory", d, "--cores", "2", "--keep-going"], capture_output=True, text=True)
    assert out.returncode != 0, "a failed job fails the workflow"
    # The broken session's object still trained (keep-going), the others' outputs untouched.
    assert (d / "results" / "broken" / "merged" / "box" / "merged.ply").exists()
    rows = {(r.split(",")[0], r.split(",")[2]) for r in (d / "results" / "summary.csv").read_text().splitlines()[1:]}
    assert ("one", "scored") in rows and ("two", "scored") in rows, rows
    assert ("broken", "failed in train_scene") in rows, rows
    summary = (d / "results" / "summary.md").read_text()
    assert "background" in summary and "broken" in summary, summary
