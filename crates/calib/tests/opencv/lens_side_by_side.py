"""OpenCV's calibrateCamera (ArucoDetector with subpixel corners for a grid, CharucoDetector's chessboard
corners for ChArUco) on a synth raw session's close-ups, beside pganeus calibrate's lens from the same
folder (its calibration.json) and the truth (camera_truth.json): focal length and principal point.

    python lens_side_by_side.py SESSION_DIR CALIBRATE_OUT
"""

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import tomllib


def main() -> None:
    session, calibrated = Path(sys.argv[1]), Path(sys.argv[2])
    board = tomllib.loads((session / "raw/board.toml").read_text())
    board.setdefault("first_id", 0)
    images = sorted(str(p) for p in (session / "raw/calibration").iterdir())
    with tempfile.TemporaryDirectory() as tmp:
        case, out = Path(tmp) / "case.json", Path(tmp) / "opencv.json"
        case.write_text(json.dumps({"images": images, "board": board}))
        reference = Path(__file__).with_name("reference.py")
        subprocess.run([sys.executable, str(reference), "calibrate", str(case), str(out)], check=True, capture_output=True)
        cv = json.loads(out.read_text())
    truth = json.loads((session / "camera_truth.json").read_text())["lens"]["K"]
    ours = json.loads((calibrated / "calibration.json").read_text())["lens"]["K"]

    def errors(k):
        focal = max(abs(k[0][0] / truth[0][0] - 1), abs(k[1][1] / truth[1][1] - 1)) * 100
        principal = ((k[0][2] - truth[0][2]) ** 2 + (k[1][2] - truth[1][2]) ** 2) ** 0.5
        return f"focal {focal:.3f} %, principal point {principal:.2f} px"

    print(f"{session.name}: OpenCV {errors(cv['K'])} (rms {cv['rms']:.3f} px, {sum(p is not None for p in cv['poses'])} views); pganeus {errors(ours)}")


if __name__ == "__main__":
    main()
