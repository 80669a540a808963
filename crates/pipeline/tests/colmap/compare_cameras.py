"""An imported capture's cameras (import.json, cameras_sphere.npz) against a synth raw session's truth
capture: camera centres (mm) and rotations (degrees), median and worst. numpy only.

    python compare_cameras.py SESSION_DIR CAPTURE_DIR TRUTH_CAPTURE_NAME [--each]

SESSION_DIR is `synth --raw`'s output (camera_truth.json, the truth captures); CAPTURE_DIR is
`import-colmap`'s or `import-transforms`'s.
"""

import json
import sys

import numpy as np


def decompose(p):
    """world_mat = K [R | t] -> (K, R, camera centre)."""
    q, r = np.linalg.qr(np.flipud(p[:3, :3]).T)
    rot = np.flipud(q.T)
    k = np.fliplr(np.flipud(r.T))
    d = np.diag(np.sign(np.diag(k)))
    k, rot = k @ d, d @ rot
    t = np.linalg.solve(k, p[:3, 3])
    return k, rot, -rot.T @ t


def main() -> None:
    session, capture, name = sys.argv[1], sys.argv[2], sys.argv[3]
    imported = json.load(open(f"{capture}/import.json"))
    truth = json.load(open(f"{session}/camera_truth.json"))
    files = next(c for c in truth["captures"] if c["name"] == name)["files"]
    truth_mats = np.load(f"{session}/{name}/cameras_sphere.npz")
    mats = np.load(f"{capture}/cameras_sphere.npz")
    centres, angles = [], []
    for k, image in enumerate(imported["images"]):
        i = files.index(image["name"])
        _, rt, ct = decompose(truth_mats[f"world_mat_{i}"])
        _, rc, cc = decompose(mats[f"world_mat_{k}"])
        centres.append(1000 * np.linalg.norm(ct - cc))
        angles.append(np.degrees(np.arccos(np.clip((np.trace(rt @ rc.T) - 1) / 2, -1, 1))))
        if "--each" in sys.argv:
            print(f"{image['name']}: {centres[-1]:.2f} mm, {angles[-1]:.3f} deg")
    print(
        f"{len(centres)} cameras: centres median {np.median(centres):.2f} mm, worst {max(centres):.2f} mm; "
        f"rotations median {np.median(angles):.3f} deg, worst {max(angles):.3f} deg"
    )


if __name__ == "__main__":
    main()
