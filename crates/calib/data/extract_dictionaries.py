"""Writes dictionaries.txt: the bit tables of OpenCV's predefined ArUco and AprilTag dictionaries.

Run once with the OpenCV named in the header it writes (opencv-contrib-python-headless from PyPI):
    python crates/calib/data/extract_dictionaries.py > crates/calib/data/dictionaries.txt
Each marker's code is its bits at rotation 0 (OpenCV's `getBitsFromByteList`), row by row from the top-left,
the first bit the most significant, in hexadecimal. OpenCV's 50/100/250/1000 dictionaries of one marker size
are prefixes of one table (the script checks it), so a table is written once and the dictionaries name a
count and their own error-correction budget (`maxCorrectionBits`).
"""
import cv2
import numpy as np

aruco = cv2.aruco

# (table name, dictionaries that are prefixes of it)
TABLES = [
    ("DICT_4X4_1000", ["DICT_4X4_50", "DICT_4X4_100", "DICT_4X4_250", "DICT_4X4_1000"]),
    ("DICT_5X5_1000", ["DICT_5X5_50", "DICT_5X5_100", "DICT_5X5_250", "DICT_5X5_1000"]),
    ("DICT_6X6_1000", ["DICT_6X6_50", "DICT_6X6_100", "DICT_6X6_250", "DICT_6X6_1000"]),
    ("DICT_7X7_1000", ["DICT_7X7_50", "DICT_7X7_100", "DICT_7X7_250", "DICT_7X7_1000"]),
    ("DICT_ARUCO_ORIGINAL", ["DICT_ARUCO_ORIGINAL"]),
    ("DICT_ARUCO_MIP_36H12", ["DICT_ARUCO_MIP_36H12"]),
    ("DICT_APRILTAG_16H5", ["DICT_APRILTAG_16H5"]),
    ("DICT_APRILTAG_25H9", ["DICT_APRILTAG_25H9"]),
    ("DICT_APRILTAG_36H10", ["DICT_APRILTAG_36H10"]),
    ("DICT_APRILTAG_36H11", ["DICT_APRILTAG_36H11"]),
]


def codes(d):
    n = d.markerSize
    out = []
    for i in range(d.bytesList.shape[0]):
        bits = aruco.Dictionary.getBitsFromByteList(d.bytesList[i : i + 1], n).flatten()
        value = 0
        for b in bits:
            value = (value << 1) | int(b)
        out.append(value)
    return out


def main():
    print(f"# OpenCV's predefined marker dictionaries, extracted from opencv-contrib-python-headless {cv2.__version__}")
    print("# by crates/calib/data/extract_dictionaries.py (see there for the format). Do not edit by hand.")
    for table, members in TABLES:
        full = aruco.getPredefinedDictionary(getattr(aruco, table))
        n = full.markerSize
        all_codes = codes(full)
        width = (n * n + 3) // 4
        print(f"table {table} marker_size {n} count {len(all_codes)}")
        for start in range(0, len(all_codes), 12):
            print(" ".join(f"{c:0{width}x}" for c in all_codes[start : start + 12]))
        for name in members:
            d = aruco.getPredefinedDictionary(getattr(aruco, name))
            assert d.markerSize == n
            member_codes = codes(d)
            assert member_codes == all_codes[: len(member_codes)], f"{name} is not a prefix of {table}"
            print(f"dictionary {name} table {table} count {len(member_codes)} max_correction_bits {d.maxCorrectionBits}")


if __name__ == "__main__":
    main()
