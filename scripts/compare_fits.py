"""How far two fits of the same video place each body, frame by frame: the pose each gives the *true* body
(its own body frame carried into the truth's through the static capture it is expressed in, as `eval` does),
so two fits from different reconstructions of one object compare.

    python3 scripts/compare_fits.py FIT_A FIT_B TRUTH.json

FIT_A and FIT_B are `fit` folders (their trajectory.json); prints per body the worst and mean distance
between the two fits' positions of the true body's origin (mm) and between their orientations (degrees, up
to none of the shape's symmetries: both fits are of the same frames), and the worst frame.
"""

import json
import math
import sys

from guess_from_truth import qconj as conj, qmul, rotate


def compose(a, b):
    """a ∘ b for poses (q, t): x -> a(b(x))."""
    return qmul(a[0], b[0]), [x + y for x, y in zip(rotate(a[0], b[1]), a[1])]


def inverse(a):
    qi = conj(a[0])
    return qi, [-x for x in rotate(qi, a[1])]


def angle_deg(q):
    return math.degrees(2 * math.acos(min(1.0, abs(q[0]) / math.sqrt(sum(x * x for x in q)))))


def true_body_poses(fit_dir, truth):
    traj = json.load(open(f"{fit_dir}/trajectory.json"))
    out = {}
    for body in traj["bodies"]:
        ref = body.get("object", {}).get("reference")
        to_truth = ([1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
        if ref:
            stat = next(
                s
                for b in truth["bodies"]
                if b["name"] == body["name"]
                for s in b["static_captures"]
                if s["capture"] == ref["capture"]
            )
            to_truth = compose(inverse((stat["pose"]["q"], stat["pose"]["t"])), (ref["pose"]["q"], ref["pose"]["t"]))
        back = inverse(to_truth)
        out[body["name"]] = [compose((p["q"], p["t"]), back) for p in body["poses"]]
    return out


def main():
    a_dir, b_dir, truth_path = sys.argv[1:4]
    truth = json.load(open(truth_path))
    a, b = true_body_poses(a_dir, truth), true_body_poses(b_dir, truth)
    for name in a:
        rows = []
        for k, (pa, pb) in enumerate(zip(a[name], b[name])):
            d = math.dist(pa[1], pb[1]) * 1000
            r = angle_deg(qmul(conj(pa[0]), pb[0]))
            rows.append((k, d, r))
        worst_d = max(rows, key=lambda x: x[1])
        worst_r = max(rows, key=lambda x: x[2])
        print(
            f"{name}: position apart mean {sum(x[1] for x in rows) / len(rows):.2f} mm, worst {worst_d[1]:.2f} mm "
            f"(frame {worst_d[0]}); orientation apart mean {sum(x[2] for x in rows) / len(rows):.2f} deg, "
            f"worst {worst_r[2]:.2f} deg (frame {worst_r[0]})"
        )


if __name__ == "__main__":
    main()
