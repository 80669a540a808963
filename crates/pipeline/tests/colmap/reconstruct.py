"""COLMAP (pycolmap, PyPI) reconstructs a folder of images from the images alone: SIFT features with one
OPENCV camera for every image, exhaustive matching, incremental mapping. The largest model is written as
COLMAP's binary files to OUT/sparse/0; a line of JSON says how many images it registered.

    python reconstruct.py IMAGES_DIR OUT [fx,fy,cx,cy,k1,k2,p1,p2]

With the lens given (COLMAP's convention: the top-left pixel's centre at 0.5, 0.5), COLMAP holds it and
solves the poses only, as with a lens calibrated beforehand; without, it calibrates itself (the principal
point too: COLMAP holds it at the image's centre unless asked, and a real lens's is pixels off).
"""

import json
import sys
import time
from pathlib import Path

import pycolmap


def main() -> None:
    images, out = Path(sys.argv[1]), Path(sys.argv[2])
    lens = sys.argv[3] if len(sys.argv) > 3 else None
    out.mkdir(parents=True, exist_ok=True)
    database = out / "database.db"
    if database.exists():
        database.unlink()
    start = time.time()
    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = "OPENCV"
    if lens:
        reader.camera_params = lens
    extraction = pycolmap.FeatureExtractionOptions()
    extraction.sift.max_num_features = 4096
    pycolmap.extract_features(
        database,
        images,
        camera_mode=pycolmap.CameraMode.SINGLE,
        reader_options=reader,
        extraction_options=extraction,
        device=pycolmap.Device.cpu,
    )
    pycolmap.match_exhaustive(database, device=pycolmap.Device.cpu)
    mapping = pycolmap.IncrementalPipelineOptions()
    if lens:
        mapping.ba_refine_focal_length = False
        mapping.ba_refine_extra_params = False
    else:
        mapping.ba_refine_principal_point = True
    models = pycolmap.incremental_mapping(database, images, out / "mapping", options=mapping)
    if not models:
        print(json.dumps({"registered": 0, "seconds": time.time() - start}))
        sys.exit(1)
    best = max(models.values(), key=lambda m: m.num_reg_images())
    sparse = out / "sparse" / "0"
    sparse.mkdir(parents=True, exist_ok=True)
    best.write_binary(str(sparse))
    print(json.dumps({"registered": best.num_reg_images(), "points": best.num_points3D(), "seconds": round(time.time() - start, 1)}))


if __name__ == "__main__":
    main()
