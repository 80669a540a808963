"""A markdown table of fits scored by `eval`: one row per fit and body.

    python3 scripts/fit_table.py LABEL=FIT_DIR [LABEL=FIT_DIR ...]

Each FIT_DIR is a `fit` folder with its `eval.json` (and `trajectory.json`). Columns: the reported poses'
position error mean / worst (mm) and rotation mean / worst (degrees, up to the shape's symmetries), the
frames reported from the simulation of the fitted physics, the simulation's own error from the truth
(mean / worst mm), v0's error (% of the true speed, or m/s where the truth starts at rest), restitution and
friction against the scene with their ranges (a star where the truth falls outside), the predictable
frames (`horizon`) and the fit's time.
"""

import json
import sys
from pathlib import Path


def value(p, name):
    """`fitted [lo–hi]` of a contact value in eval's parameters, starred when the truth is outside."""
    fitted = p.get(name)
    rng = p.get(f"{name}_range")
    true = p.get(f"{name}_true")
    if fitted is None:
        return "–"
    text = f"{fitted:.3f}"
    if isinstance(rng, list) and len(rng) == 2:
        inside = true is None or rng[0] <= true <= rng[1]
        text += f" [{rng[0]:.2f}–{rng[1]:.2f}]{'' if inside else '*'}"
    if true is not None:
        text += f" ({true:.2f})"
    return text


def rows(label, fit):
    e = json.loads((fit / "eval.json").read_text())
    t = json.loads((fit / "trajectory.json").read_text())
    seconds = sum(v for k, v in t.get("timings_s", {}).items() if isinstance(v, (int, float)) and k != "pga_rounds")
    horizon = e.get("horizon", {})
    h = f"{horizon.get('predictable_frames', '–')} / {horizon.get('frames', '–')}" if horizon else "–"
    for body, s in e["summary"].items():
        p = e["parameters"].get(body, {})
        v0 = p.get("v0_error_percent")
        v0 = f"{v0:.1f} %" if v0 is not None else f"{p.get('v0_error_m_s', float('nan')):.3f} m/s"
        sim = s.get("sim_position_mm", {})
        yield (
            f"| {label} | {body} | {s['position_mm']['mean']:.2f} / {s['position_mm']['worst']:.2f} "
            f"| {s['rotation_sym_deg']['mean']:.2f} / {s['rotation_sym_deg']['worst']:.2f} "
            f"| {s.get('simulated_frames', '–')} / {s['frames']} "
            f"| {sim.get('mean', float('nan')):.2f} / {sim.get('worst', float('nan')):.2f} "
            f"| {v0} | {value(p, 'restitution')} | {value(p, 'friction')} | {h} | {seconds:.0f} s |"
        )


def main():
    print(
        "| fit | body | position mm | rotation ° | from the simulation | simulation mm | v0 | restitution "
        "| friction | predictable | time |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for arg in sys.argv[1:]:
        label, _, path = arg.partition("=")
        for row in rows(label, Path(path)):
            print(row)


if __name__ == "__main__":
    main()
