"""Datasets for training on calibrate's captures against the true cameras on the same photos.

    python scripts/calibrated_training_datasets.py SESSION CALIBRATED OUT

SESSION is `synth --raw`'s output, CALIBRATED is `calibrate`'s (run with --width 160 on SESSION/raw).
For the background, toy_a and toy_b, on the photos calibrate kept, writes these datasets for `bench-train`,
`train` and `merge`:
  OUT/truth_cameras     the raw JPEGs undistorted with the true lens to the truth capture's pinhole, the
                        truth's cameras, region and masks;
  OUT/truth_cameras_region  the same with calibrate's region (what its region rule costs, cameras aside);
  OUT/calibrated        calibrate's images and cameras, synth's region, the truth's masks carried into
                        calibrate's images;
  OUT/calibrated_region calibrate's whole capture (images, cameras, region), the truth's masks carried
                        into its images;
  OUT/truth_renders     synth's clean renders of the same views with the truth's cameras, region and masks.
The truth's masks are drawn on synth's pinhole images; for calibrate's images each pixel is followed back
through calibrate's lens to the raw photo and forward through the true lens to the truth's pinhole (the
same photo's content, so only the lens error moves it).
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


def on_truth_pinhole(raw, kc, f, lens_k, lens_d):
    """A raw photo undistorted with the lens (lens_k, lens_d) onto the truth capture's pinhole kc at the raw
    size (OpenCV's pixel centres), then shrunk by f to the capture's size."""
    h, w = raw.shape[:2]
    target = np.array([[f * kc[0, 0], 0, f * kc[0, 2] - 0.5], [0, f * kc[1, 1], f * kc[1, 2] - 0.5], [0, 0, 1]])
    m1, m2 = cv2.initUndistortRectifyMap(lens_k, lens_d, None, target, (w, h), cv2.CV_32FC1)
    return cv2.resize(cv2.remap(raw, m1, m2, cv2.INTER_LINEAR), (round(w / f), round(h / f)), interpolation=cv2.INTER_AREA)


def carried_mask(mask, truth_k, report, truth_lens):
    """The truth's mask (drawn with the pinhole truth_k) resampled onto calibrate's capture pixels; truth_lens:
    camera_truth.json's `lens`."""
    cap_k = np.array(report["capture_K"])
    w, h = report["capture_size"]
    lens_k = np.array(report["lens"]["K"])
    lens_d = np.array(report["lens"]["distortion"])
    truth = truth_lens
    u, v = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    rays = np.stack([(u - cap_k[0, 2]) / cap_k[0, 0], (v - cap_k[1, 2]) / cap_k[1, 1], np.ones_like(u)], -1)
    raw, _ = cv2.projectPoints(rays.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), lens_k, lens_d)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)
    back = cv2.undistortPointsIter(raw, np.array(truth["K"]), np.array(truth["distortion"]), None, None, criteria)
    back = back.reshape(h, w, 2)
    mx = (truth_k[0, 0] * back[..., 0] + truth_k[0, 2] - 0.5).astype(np.float32)
    my = (truth_k[1, 1] * back[..., 1] + truth_k[1, 2] - 0.5).astype(np.float32)
    out = cv2.remap(mask, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return np.where(out >= 128, 255, 0).astype(np.uint8)


def main() -> None:
    session, calibrated, out = sys.argv[1], sys.argv[2], sys.argv[3]
    truth = json.load(open(f"{session}/camera_truth.json"))
    report = json.load(open(f"{calibrated}/calibration.json"))
    raw_width = truth["image_size"][0]
    lens_k = np.array(truth["lens"]["K"])
    lens_d = np.array(truth["lens"]["distortion"])
    for kind in ["truth_cameras", "truth_cameras_region", "calibrated", "calibrated_region", "truth_renders"]:
        d = f"{out}/{kind}"
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(d)
        for f in ["synth.toml", "truth.json", "background.ply", "toy.ply", "camera_truth.json"]:
            shutil.copy(f"{session}/{f}", d)
        for name in ["background", "toy_a", "toy_b"]:
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
            renders = sorted(os.listdir(f"{session}/{name}/image"))
            # The raw photos over the truth's capture: the factor between their pinholes.
            f = raw_width / cv2.imread(f"{session}/{name}/image/{renders[0]}").shape[1]
            for k, image in enumerate(kept):
                i = files.index(image)
                kc = intrinsics(truth_mats[f"world_mat_{i}"])
                if kind.startswith("truth_cameras"):
                    raw = cv2.imread(f"{session}/raw/{name}/{image}")
                    cv2.imwrite(f"{cd}/image/{k:03d}.png", on_truth_pinhole(raw, kc, f, lens_k, lens_d))
                    mats[f"world_mat_{k}"] = truth_mats[f"world_mat_{i}"]
                elif kind == "truth_renders":
                    shutil.copy(f"{session}/{name}/image/{renders[i]}", f"{cd}/image/{k:03d}.png")
                    mats[f"world_mat_{k}"] = truth_mats[f"world_mat_{i}"]
                else:
                    shutil.copy(f"{calibrated}/{name}/image/{cal_images[k]}", f"{cd}/image/{k:03d}.png")
                    mats[f"world_mat_{k}"] = cal_mats[f"world_mat_{k}"]
                region = cal_mats[f"scale_mat_{k}"] if kind.endswith("_region") else truth_mats[f"scale_mat_{i}"]
                mats[f"scale_mat_{k}"] = region
                if masks and kind.startswith("calibrated"):
                    mask = cv2.imread(f"{session}/{name}/mask/{masks[i]}", cv2.IMREAD_GRAYSCALE)
                    cv2.imwrite(f"{cd}/mask/{k:03d}.png", carried_mask(mask, kc, report, truth["lens"]))
                elif masks:
                    shutil.copy(f"{session}/{name}/mask/{masks[i]}", f"{cd}/mask/{k:03d}.png")
            np.savez(f"{cd}/cameras_sphere.npz", **mats)
            shutil.copy(f"{session}/{name}/capture.json", f"{cd}/capture.json")
        print(f"{d}: written")


if __name__ == "__main__":
    main()
