"""Makes the NumPy fixtures of crates/io/tests/npz.rs (STYLE.md habit 11).

Run from this folder:  python3 gen_npz.py   (made with numpy 2.4.6, Python 3.11)

- cameras_sphere.npz: np.savez (entries stored) of 3 cameras laid out as NeuS
  data: camera_mat_i, camera_mat_inv_i, world_mat_i, world_mat_inv_i,
  scale_mat_i, scale_mat_inv_i, float64 4x4.
- compressed.npz: np.savez_compressed (DEFLATE entries) of arrays of every
  dtype and layout the reader must handle.
- fortran.npy: np.save of a Fortran-ordered array (fortran_order True).

Every value is exactly representable, so the Rust test compares with ==.
The ZIP timestamps are the time of the run, so re-running changes the bytes
of the .npz files but not their contents.
"""

import numpy as np


def world_mat(i):
    # [[K, 0], [0, 1]] @ W2C with a camera at distance 4 looking at the origin,
    # turned by 90 degrees per image about z (exact in binary).
    K = np.array([[100.0, 0.0, 32.0, 0.0],
                  [0.0, 100.0, 24.0, 0.0],
                  [0.0, 0.0, 1.0, 0.0],
                  [0.0, 0.0, 0.0, 1.0]])
    c, s = [(1, 0), (0, 1), (-1, 0)][i]
    R = np.array([[c, -s, 0.0], [0.0, 0.0, -1.0], [s, c, 0.0]])
    W2C = np.eye(4)
    W2C[:3, :3] = R
    W2C[:3, 3] = [0.0, 0.0, 4.0]
    return K @ W2C


def scale_mat():
    S = np.diag([0.5, 0.5, 0.5, 1.0])
    S[:3, 3] = [0.25, -0.125, 0.5]
    return S


cams = {}
for i in range(3):
    cams["camera_mat_%d" % i] = np.eye(4)
    cams["camera_mat_inv_%d" % i] = np.eye(4)
    cams["world_mat_%d" % i] = world_mat(i)
    cams["world_mat_inv_%d" % i] = np.linalg.inv(world_mat(i))
    cams["scale_mat_%d" % i] = scale_mat()
    cams["scale_mat_inv_%d" % i] = np.linalg.inv(scale_mat())
np.savez("cameras_sphere.npz", **cams)

np.savez_compressed(
    "compressed.npz",
    f8=np.arange(12, dtype="<f8").reshape(3, 4) * 0.5,
    f4=np.arange(7, dtype="<f4") * 0.25,
    i8=np.array([[-3, 2**40], [7, -(2**50)]], dtype="<i8"),
    i4=np.array([1, -2, 3], dtype="<i4"),
    u1=np.arange(256, dtype="u1"),
    b1=np.array([True, False, True, True]),
    scalar=np.float64(2.5),
    big=np.array([1.5, -2.25, 1e300], dtype=">f8"),
    big_i4=np.array([[1, -2], [65536, 7]], dtype=">i4"),
    fortran=np.asfortranarray(np.arange(24, dtype="<f8").reshape(2, 3, 4)),
    empty=np.zeros((0, 3)),
)

np.save("fortran.npy", np.asfortranarray(np.arange(6, dtype="<i4").reshape(2, 3)))
