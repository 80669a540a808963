"""Datasets for training on calibrate's captures against the true cameras on the same photos.

    python scripts/calibrated_training_datasets.py SESSION CALIBRATED OUT

SESSION is `synth --raw`'s output, CALIBRATED is `calibrate`'s (run with --width 160 on SESSION/raw).
For the background and toy_a, on the photos calibrate kept, writes these datasets for `bench-train`:
  OUT/truth_cameras     the raw JPEGs undistorted with the true lens to the truth capture's pinhole, the
                        truth's cameras, region and masks;
  OUT/truth_cameras_region  the same with calibrate's region (what its region rule costs, cameras aside);
  OUT/calibrated        calibrate's images and cameras, synth's region, the truth's masks;
  OUT/calibrated_region calibrate's images, cameras and region, the truth's masks;
  OUT/truth_renders     synth's clean renders of the same views with the truth's cameras, region and masks.
Needs numpy and OpenCV (opencv-contrib-python-headless, as .ci/run installs).
"""

import json
import os
import shutil
import sys

import cv2
import numpy as np


def intrinsics(world_mat):
    """K of world_mat = K [R | t] (RQ decomposition), positive diagonal, K[2,2] = 1."""
    q, r = np.linalg.qr(np.flipud(world_mat[:3, :3]).T)
    k = np.abs(np.fliplr(np.flipud(r.T)))
    return k / k[2, 2]


def main() -> None:
    session, calibrated, out = sys.argv[1], sys.argv[2], sys.argv[3]
    truth = json.load(open(f"{session}/camera_truth.json"))
    report = json.load(open(f"{calibrated}/calibration.json"))
    lens_k = np.array(truth["lens"]["K"])
    lens_d = np.array(truth["lens"]["distortion"])
    for kind in ["truth_cameras", "truth_cameras_region", "calibrated", "calibrated_region", "truth_renders"]:
        d = f"{out}/{kind}"
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(d)
        for f in ["synth.toml", "truth.json", "background.ply", "toy.ply"]:
            shutil.copy(f"{session}/{f}", d)
        for name in ["background", "toy_a"]:
            files = next(c for c in truth["captures"] if c["name"] == name)["files"]
            kept = next(c for c in report["captures"] if c["name"] == name)["images"]
            truth_mats = np.load(f"{session}/{name}/cameras_sphere.npz")
            cal_mats = np.load(f"{calibrated}/{name}/cameras_sphere.npz")
            cal_images = sorted(os.listdir(f"{calibrated}/{name}/image"))
            cd = f"{d}/{name}"
            os.makedirs(f"{cd}/image")
            masks = sorted(os.listdir(f"{session}/{name}/mask")) if os.path.isdir(f"{session}/{name}/mask") else None
            if masks:
                os.makedirs(f"{cd}/mask")
            mats = {}
            for k, image in enumerate(kept):
                i = files.index(image)
                if kind.startswith("truth_cameras"):
                    # The truth capture's pinhole at the raw size (OpenCV's pixel centres), then a third.
                    kc = intrinsics(truth_mats[f"world_mat_{i}"])
                    target = np.array([[3 * kc[0, 0], 0, 3 * kc[0, 2] - 0.5], [0, 3 * kc[1, 1], 3 * kc[1, 2] - 0.5], [0, 0, 1]])
                    raw = cv2.imread(f"{session}/raw/{name}/{image}")
                    h, w = raw.shape[:2]
                    m1, m2 = cv2.initUndistortRectifyMap(lens_k, lens_d, None, target, (w, h), cv2.CV_32FC1)
                    small = cv2.resize(cv2.remap(raw, m1, m2, cv2.INTER_LINEAR), (w // 3, h // 3), interpolation=cv2.INTER_AREA)
                    cv2.imwrite(f"{cd}/image/{k:03d}.png", small)
                    mats[f"world_mat_{k}"] = truth_mats[f"world_mat_{i}"]
                elif kind == "truth_renders":
                    renders = sorted(os.listdir(f"{session}/{name}/image"))
                    shutil.copy(f"{session}/{name}/image/{renders[i]}", f"{cd}/image/{k:03d}.png")
                    mats[f"world_mat_{k}"] = truth_mats[f"world_mat_{i}"]
                else:
                    shutil.copy(f"{calibrated}/{name}/image/{cal_images[k]}", f"{cd}/image/{k:03d}.png")
                    mats[f"world_mat_{k}"] = cal_mats[f"world_mat_{k}"]
                region = cal_mats[f"scale_mat_{k}"] if kind.endswith("_region") else truth_mats[f"scale_mat_{i}"]
                mats[f"scale_mat_{k}"] = region
                if masks:
                    shutil.copy(f"{session}/{name}/mask/{masks[i]}", f"{cd}/mask/{k:03d}.png")
            np.savez(f"{cd}/cameras_sphere.npz", **mats)
            shutil.copy(f"{session}/{name}/capture.json", f"{cd}/capture.json")
        print(f"{d}: written")


if __name__ == "__main__":
    main()
