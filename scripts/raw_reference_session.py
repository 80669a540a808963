"""The same raw photos with the true cameras and the true masks: the reference a raw session's run is held to.

    python scripts/raw_reference_session.py SESSION IMPORTED OUT
    pganeus run OUT --out RUN --truth SESSION/truth.json

SESSION is `synth --raw`'s output (or `demo --preset raw`'s `data/`), IMPORTED is what `pganeus import`
made of SESSION/raw (`demo --preset raw`'s `imported/`). For every capture IMPORTED holds (the scene, the
objects' two captures, the videos), on the photos and frames `import` kept, OUT gets the raw JPEGs
undistorted with the *true* lens onto the truth capture's pinhole and shrunk to its size, with the truth's
cameras and region, and the truth's masks (`mask/` for the objects, `mask_<body>/` for the videos), and
IMPORTED's `capture.json` and `session.json`. `run` on OUT is then the method on the same pixels as on
IMPORTED, with nothing computed that the truth knows: the cameras and the masks.
Needs numpy and OpenCV (opencv-contrib-python-headless, as .ci/run installs).
"""

import json
import os
import shutil
import sys

import cv2
import numpy as np

from calibrated_training_datasets import intrinsics, on_truth_pinhole


def main() -> None:
    session, imported, out = sys.argv[1], sys.argv[2], sys.argv[3]
    truth = json.load(open(f"{session}/camera_truth.json"))
    report = json.load(open(f"{imported}/calibration.json"))
    lens_k = np.array(truth["lens"]["K"])
    lens_d = np.array(truth["lens"]["distortion"])
    if os.path.exists(out):
        sys.exit(f"{out} exists: give a new folder")
    os.makedirs(out)
    shutil.copy(f"{imported}/session.json", out)
    for capture in report["captures"]:
        name = capture["name"]
        files = next(c for c in truth["captures"] if c["name"] == name)["files"]
        truth_mats = np.load(f"{session}/{name}/cameras_sphere.npz")
        renders = sorted(os.listdir(f"{session}/{name}/image"))
        mask_dirs = sorted(d for d in os.listdir(f"{session}/{name}") if d == "mask" or d.startswith("mask_"))
        cd = f"{out}/{name}"
        for d in ["image"] + mask_dirs:
            os.makedirs(f"{cd}/{d}")
        # The raw photos over the truth's capture: the factor between their pinholes.
        f = truth["image_size"][0] / cv2.imread(f"{session}/{name}/image/{renders[0]}").shape[1]
        mats = {}
        for k, image in enumerate(capture["images"]):
            i = files.index(image)
            kc = intrinsics(truth_mats[f"world_mat_{i}"])
            raw = cv2.imread(f"{session}/raw/{name}/{image}")
            cv2.imwrite(f"{cd}/image/{k:03d}.png", on_truth_pinhole(raw, kc, f, lens_k, lens_d))
            mats[f"world_mat_{k}"] = truth_mats[f"world_mat_{i}"]
            mats[f"scale_mat_{k}"] = truth_mats[f"scale_mat_{i}"]
            for d in mask_dirs:
                masks = sorted(os.listdir(f"{session}/{name}/{d}"))
                shutil.copy(f"{session}/{name}/{d}/{masks[i]}", f"{cd}/{d}/{k:03d}.png")
        np.savez(f"{cd}/cameras_sphere.npz", **mats)
        shutil.copy(f"{imported}/{name}/capture.json", f"{cd}/capture.json")
        print(f"{cd}: {len(capture['images'])} images, masks {mask_dirs}")


if __name__ == "__main__":
    main()
