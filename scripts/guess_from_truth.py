#!/usr/bin/env python3
"""A first-pose guess (`init.json` for `pganeus fit --init`) made from a synth truth, a set distance and angle
off: the benchmark's "guess" start (issue 68's table: 2 cm and 15° off), as two marker detections would give.

    python scripts/guess_from_truth.py TRUTH.json VIDEO --offset-mm 20 --offset-deg 15 [--seed 1] [--frame K] > init.json

`--frame K` offsets frame K's true pose instead (a start for a video cut to begin at frame K; with zero
offsets, the truth itself: a diagnostic of the fit's loss at the true pose).

For every body of the video: its true pose in frame 0, turned by `--offset-deg` about an axis and moved by
`--offset-mm` along a direction (both drawn from `--seed`; the turn about the body's centre), then written as
`init.json` wants it: the rigid motion taking the object from where it stood in its reference capture (the
truth's last static capture of that body, e.g. `toy_b`, the one `merge` keeps) to frame 0,
`p_frame0 = R(q) p_capture + t` (docs/formats.md). Needs only Python's standard library.
"""
import argparse
import json
import math
import random
import sys


def qmul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return [
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ]


def qconj(q):
    return [q[0], -q[1], -q[2], -q[3]]


def rotate(q, v):
    return qmul(qmul(q, [0.0, *v]), qconj(q))[1:]


def unit(rng):
    while True:
        v = [rng.uniform(-1, 1) for _ in range(3)]
        n = math.sqrt(sum(c * c for c in v))
        if 0.1 < n <= 1.0:
            return [c / n for c in v]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("truth")
    ap.add_argument("video", help="the video's capture name in truth.json (e.g. drop)")
    ap.add_argument("--offset-mm", type=float, default=20.0)
    ap.add_argument("--offset-deg", type=float, default=15.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--frame", type=int, default=0, help="the frame whose true pose is offset (default 0)")
    a = ap.parse_args()
    with open(a.truth) as f:
        truth = json.load(f)
    videos = [v for v in truth["videos"] if v["capture"] == a.video]
    if not videos:
        sys.exit(f"{a.truth}: no video named {a.video!r} (it has {[v['capture'] for v in truth['videos']]})")
    statics = {b["name"]: b.get("static_captures", []) for b in truth["bodies"]}
    rng = random.Random(a.seed)
    init = {}
    for body in videos[0]["bodies"]:
        captures = statics.get(body["name"]) or []
        if not captures:
            sys.exit(f"{a.truth}: body {body['name']!r} has no static capture to refer the guess to")
        reference = captures[-1]
        pb_t, pb_q = reference["pose"]["t"], reference["pose"]["q"]
        if not 0 <= a.frame < len(body["poses"]):
            sys.exit(f"{a.truth}: video {a.video!r} has {len(body['poses'])} frames, not frame {a.frame}")
        p0_t, p0_q = body["poses"][a.frame]["t"], body["poses"][a.frame]["q"]
        axis, direction = unit(rng), unit(rng)
        half = math.radians(a.offset_deg) / 2
        turn = [math.cos(half)] + [math.sin(half) * c for c in axis]
        q = qmul(turn, p0_q)
        t = [p0_t[i] + a.offset_mm * 1e-3 * direction[i] for i in range(3)]
        # frame 0 = P0' ∘ Pb⁻¹: p_frame0 = R(q Pb.q⁻¹) (p_capture − Pb.t) + t
        m_q = qmul(q, qconj(pb_q))
        shifted = rotate(m_q, pb_t)
        m_t = [t[i] - shifted[i] for i in range(3)]
        init[body["name"]] = {"capture": reference["capture"], "t": m_t, "q": m_q}
    json.dump(init, sys.stdout, indent=2)
    print()


if __name__ == "__main__":
    main()
