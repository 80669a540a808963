"""OpenCV as the independent reference for the calib crate's tests (opencv-contrib-python-headless).

    python reference.py boards CASES.json OUT_DIR
        each case's board drawn by OpenCV's generateImage into OUT_DIR/<name>.png; the names of the cases
        OpenCV refuses to draw (it asserts) in OUT_DIR/refused.json

    python reference.py detect CASES.json OUT.json
        each case's image ({"image", "dictionary"}) through OpenCV's ArucoDetector with CORNER_REFINE_SUBPIX:
        {"<image>": {"ids": [...], "corners": [[[x, y] x 4], ...]}} in OUT.json

    python reference.py calibrate CASE.json OUT.json
        OpenCV's whole calibration of one session: ArucoDetector (CORNER_REFINE_SUBPIX), matchImagePoints,
        calibrateCamera (k3 fixed at 0 unless "k3": true). CASE: {"images": [...], "board": a board case}.
        OUT: {"K", "dist", "rms", "poses": [{"rvec", "tvec"} or null per image]}

A board case: {"name", "kind": "aruco_grid"|"charuco", "dictionary", "size": [cols, rows], "marker_length",
"marker_separation" | "square_length", "legacy", "first_id", "width", "height", "margin"}.
"""
import json
import sys
from pathlib import Path

import cv2
import numpy as np

aruco = cv2.aruco


def board_of(case):
    dictionary = aruco.getPredefinedDictionary(getattr(aruco, case["dictionary"].upper()))
    cols, rows = case["size"]
    if case["kind"] == "aruco_grid":
        ids = np.arange(case["first_id"], case["first_id"] + cols * rows, dtype=np.int32)
        return aruco.GridBoard((cols, rows), case["marker_length"], case["marker_separation"], dictionary, ids)
    board = aruco.CharucoBoard((cols, rows), case["square_length"], case["marker_length"], dictionary)
    board.setLegacyPattern(bool(case.get("legacy", False)))
    count = len(board.getIds())
    # The ids of a board with first_id > 0: the same layout, shifted ids.
    if case["first_id"]:
        ids = np.arange(case["first_id"], case["first_id"] + count, dtype=np.int32)
        board = aruco.CharucoBoard((cols, rows), case["square_length"], case["marker_length"], dictionary, ids)
        board.setLegacyPattern(bool(case.get("legacy", False)))
    return board


def boards(cases_path, out_dir):
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    refused = []
    for case in json.loads(Path(cases_path).read_text()):
        try:
            image = board_of(case).generateImage((case["width"], case["height"]), marginSize=case["margin"], borderBits=1)
        except cv2.error:
            # OpenCV asserts when a marker's rounded square runs past the drawing region.
            refused.append(case["name"])
            continue
        cv2.imwrite(str(out / f"{case['name']}.png"), image)
    (out / "refused.json").write_text(json.dumps(refused))
    print(cv2.__version__)


def detect(cases_path, out_path):
    results = {}
    for case in json.loads(Path(cases_path).read_text()):
        dictionary = aruco.getPredefinedDictionary(getattr(aruco, case["dictionary"].upper()))
        params = aruco.DetectorParameters()
        params.cornerRefinementMethod = aruco.CORNER_REFINE_SUBPIX
        detector = aruco.ArucoDetector(dictionary, params)
        gray = cv2.imread(case["image"], cv2.IMREAD_GRAYSCALE)
        corners, ids, _ = detector.detectMarkers(gray)
        ids = [] if ids is None else [int(i) for i in ids.flatten()]
        results[case["image"]] = {"ids": ids, "corners": [c.reshape(4, 2).tolist() for c in corners]}
    Path(out_path).write_text(json.dumps(results))
    print(cv2.__version__)


def calibrate(case_path, out_path):
    case = json.loads(Path(case_path).read_text())
    board = board_of(case["board"])
    params = aruco.DetectorParameters()
    params.cornerRefinementMethod = aruco.CORNER_REFINE_SUBPIX
    charuco = case["board"]["kind"] == "charuco"
    if charuco:
        # A ChArUco board as OpenCV's users calibrate it: the chessboard corners between the markers.
        detector = aruco.CharucoDetector(board, aruco.CharucoParameters(), params)
    else:
        detector = aruco.ArucoDetector(board.getDictionary(), params)
    object_points, image_points, used = [], [], []
    size = None
    for path in case["images"]:
        gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        size = (gray.shape[1], gray.shape[0])
        if charuco:
            corners, ids, _, _ = detector.detectBoard(gray)
            enough = ids is not None and len(ids) >= 6
        else:
            corners, ids, _ = detector.detectMarkers(gray)
            enough = ids is not None and len(ids) >= 3
        if not enough:
            used.append(False)
            continue
        obj, img = board.matchImagePoints(corners, ids)
        object_points.append(obj)
        image_points.append(img)
        used.append(True)
    flags = 0 if case.get("k3") else cv2.CALIB_FIX_K3
    rms, k, dist, rvecs, tvecs = cv2.calibrateCamera(object_points, image_points, size, None, None, flags=flags)
    poses, i = [], 0
    for u in used:
        if u:
            poses.append({"rvec": rvecs[i].flatten().tolist(), "tvec": tvecs[i].flatten().tolist()})
            i += 1
        else:
            poses.append(None)
    Path(out_path).write_text(json.dumps({"K": k.tolist(), "dist": dist.flatten().tolist(), "rms": rms, "poses": poses}))
    print(cv2.__version__)


if __name__ == "__main__":
    command = sys.argv[1]
    if command == "boards":
        boards(sys.argv[2], sys.argv[3])
    elif command == "detect":
        detect(sys.argv[2], sys.argv[3])
    elif command == "calibrate":
        calibrate(sys.argv[2], sys.argv[3])
    else:
        sys.exit(f"unknown command {command}")
