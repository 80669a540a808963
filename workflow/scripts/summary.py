"""One table over every session a workflow ran: each fit's scores (when a truth scored it), its physics and
its time, and for a session that failed, the rule that failed and the last line of its log.

    python workflow/scripts/summary.py OUT SESSION [SESSION ...]

Writes OUT/summary.md and OUT/summary.csv (one row per session and video; a failed session's row says where
it stopped). The Snakefile runs it when the workflow ends, whether every job succeeded or not. It reads the
files `pganeus` wrote and computes nothing of the method.
"""

import csv
import json
import sys
from pathlib import Path

COLUMNS = [
    "session", "video", "status", "bodies", "position_mm_mean", "position_mm_worst", "rotation_deg_worst",
    "iou_worst", "frames_from_simulation", "restitution", "restitution_range", "friction", "friction_range",
    "fit_s", "session_s", "error",
]


def read_json(path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def seconds(tsv):
    """The wall-clock seconds of a Snakemake benchmark file (its first row's `s`)."""
    try:
        lines = tsv.read_text().splitlines()
        header, row = lines[0].split("\t"), lines[1].split("\t")
        return float(row[header.index("s")])
    except (OSError, IndexError, ValueError):
        return None


def last_error(log):
    """The last line of a job's log that names a failure (or its last line)."""
    try:
        lines = [l.strip() for l in log.read_text(errors="replace").splitlines() if l.strip()]
    except OSError:
        return None
    for line in reversed(lines):
        if line.lower().startswith(("error", "thread")) or "error:" in line.lower():
            return line
    return lines[-1] if lines else None


def range_text(contact, key):
    r = contact.get(f"{key}_range")
    return f"{r[0]:.3f}-{r[1]:.3f}" if isinstance(r, list) and len(r) == 2 else ""


def session_rows(out, session):
    root = out / session
    bench = sorted((root / "benchmarks").glob("*.tsv"))
    total = sum(s for s in (seconds(b) for b in bench) if s is not None) or None
    # A job whose log exists but whose output does not: where the session stopped.
    failures = []
    for log in sorted((root / "logs").glob("*.log")):
        rule = log.stem
        if not (root / "benchmarks" / f"{rule}.tsv").exists():
            failures.append((rule, last_error(log)))
    rows = []
    fits = sorted(p for p in (root / "fits").glob("*") if p.is_dir()) if (root / "fits").is_dir() else []
    for fit in fits:
        t = read_json(fit / "trajectory.json")
        row = {"session": session, "video": fit.name, "status": "fitted" if t else "failed"}
        if t:
            contact = t.get("contact", {})
            row.update(
                bodies=" ".join(b["name"] for b in t["bodies"]),
                restitution=f"{contact.get('restitution', float('nan')):.3f}",
                restitution_range=range_text(contact, "restitution"),
                friction=f"{contact.get('friction', float('nan')):.3f}",
                friction_range=range_text(contact, "friction"),
            )
        e = read_json(fit / "eval.json")
        if e:
            row["status"] = "scored"
            s = e.get("summary", {})
            worst = lambda key: max((b[key]["worst"] for b in s.values() if key in b), default=None)
            mean = lambda key: max((b[key]["mean"] for b in s.values() if key in b), default=None)
            row.update(
                position_mm_mean=mean("position_mm"),
                position_mm_worst=worst("position_mm"),
                rotation_deg_worst=worst("rotation_sym_deg"),
                iou_worst=min((b["silhouette_iou"]["worst"] for b in s.values() if "silhouette_iou" in b), default=None),
                frames_from_simulation=" ".join(f"{b.get('simulated_frames', '?')}/{b.get('frames', '?')}" for b in s.values()),
            )
        row["fit_s"] = seconds(root / "benchmarks" / f"fit_{fit.name}.tsv")
        rows.append(row)
    if failures or not rows:
        rule, error = failures[0] if failures else ("", "no fit ran")
        rows.append({"session": session, "video": "", "status": f"failed in {rule}" if rule else "not run", "error": error})
    for r in rows:
        r["session_s"] = total
    return rows


def markdown(rows):
    shown = ["session", "video", "status", "position_mm_mean", "position_mm_worst", "rotation_deg_worst",
             "frames_from_simulation", "restitution", "friction", "fit_s", "error"]
    fmt = lambda v: "" if v is None else (f"{v:.2f}" if isinstance(v, float) else str(v).replace("|", "\\|"))
    lines = ["| " + " | ".join(shown) + " |", "|" + " --- |" * len(shown)]
    lines += ["| " + " | ".join(fmt(r.get(c)) for c in shown) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def main():
    out = Path(sys.argv[1])
    rows = [r for session in sys.argv[2:] for r in session_rows(out, session)]
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "summary.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        for r in rows:
            w.writerow({c: r.get(c, "") for c in COLUMNS})
    failed = sum(1 for r in rows if r["status"].startswith(("failed", "not run")))
    (out / "summary.md").write_text(
        f"# {len(sys.argv) - 2} sessions, {len(rows) - failed} fits, {failed} failed\n\n" + markdown(rows)
    )
    print(f"wrote {out / 'summary.md'} and {out / 'summary.csv'}")


if __name__ == "__main__":
    main()
