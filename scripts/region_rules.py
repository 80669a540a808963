#!/usr/bin/env python3
"""The scene-region rules measured side by side on calibrated captures (issue 67; docs/notebook/calibrate.md).

For each `calibrate` output folder given (its `background/` capture), the radius of the ball around the part of the board's plane seen
by a share (the quorum) of the background's photos, counting a photo only where the point falls inside a
border of its frame: half, two thirds and three quarters of the photos over the whole frame, half and two
thirds within a border. `calibrate --scene` uses three quarters (`calib::region::SCENE_QUORUM`).
The radii are on a 1 cm grid without the one-cell margin `calibrate` adds, so they run up to ~2 cm under
the radius `calibrate` writes for the same rule (ChArUco seed 3, three quarters: 0.433 m here, 0.450 m there).

    python scripts/region_rules.py captures/raw960 ...      # needs numpy
"""
import os
import re
import sys

import numpy as np


def projections(capture):
    """Each view's 3 x 4 projection (world_mat: K [R | t], pixels) and the images' width and height."""
    m = np.load(os.path.join(capture, "cameras_sphere.npz"))
    count = len([k for k in m.files if re.fullmatch(r"world_mat_\d+", k)])
    first = sorted(os.listdir(os.path.join(capture, "image")))[0]
    with open(os.path.join(capture, "image", first), "rb") as f:
        header = f.read(24)
    if header[:8] != b"\x89PNG\r\n\x1a\n":
        sys.exit(f"{capture}/image/{first}: not a PNG")
    width, height = int.from_bytes(header[16:20], "big"), int.from_bytes(header[20:24], "big")
    return [m[f"world_mat_{i}"][:3, :4] for i in range(count)], width, height


def seen_radius(views, width, height, quorum, border):
    """The radius (metres) of the ball around the part of z = 0 that `quorum` of the views see inside a
    `border` (a share of the frame) of their images; the ball centred on that part's bounding box."""
    g = np.linspace(-1.5, 1.5, 301)
    x, y = np.meshgrid(g, g)
    points = np.stack([x.ravel(), y.ravel(), np.zeros(x.size), np.ones(x.size)])
    count = np.zeros(x.size)
    for p in views:
        u, v, z = p @ points
        u, v = u / z, v / z
        inside = (u >= border * width) & (u <= (1 - border) * width)
        inside &= (v >= border * height) & (v <= (1 - border) * height)
        count += (z > 0) & inside
    seen = count >= np.ceil(quorum * len(views))
    xs, ys = x.ravel()[seen], y.ravel()[seen]
    cx, cy = (xs.min() + xs.max()) / 2, (ys.min() + ys.max()) / 2
    return np.sqrt((xs - cx) ** 2 + (ys - cy) ** 2).max()


RULES = [(1 / 2, 0.0), (2 / 3, 0.0), (3 / 4, 0.0), (1 / 2, 0.1), (2 / 3, 0.05)]

if len(sys.argv) < 2:
    sys.exit(__doc__)
for out in sys.argv[1:]:
    views, width, height = projections(os.path.join(out, "background"))
    row = [f"quorum {q:.2f} border {b:.2f}: {seen_radius(views, width, height, q, b):.3f} m" for q, b in RULES]
    print(f"{os.path.basename(os.path.normpath(out))}: " + "; ".join(row))
