"""Makes the safetensors fixture of crates/io/tests/safetensors.rs (STYLE.md habit 11).

Run from this folder:  python3 gen_safetensors.py
(made with safetensors 0.8.0, numpy 2.4.6, Python 3.11)

- official.safetensors: safetensors.numpy.save_file of one tensor of each
  dtype the Rust reader supports (F32, F64, U8, I64, U32), including a 0-d
  tensor and an empty one, with one metadata entry (the official writer puts
  several in hash-map order, which would make the bytes vary between runs).

The values parse to the same numbers in Rust, so the test compares with ==,
and it checks that the Rust writer gives these very bytes.
"""

import numpy as np
from safetensors.numpy import save_file

tensors = {
    "weights": (np.arange(12, dtype=np.float32).reshape(3, 4) * 0.25 - 1.0),
    "bias": np.array([0.5, -1.5, 1e-3], dtype=np.float64),
    "mask": np.array([[0, 1, 255], [128, 7, 3]], dtype=np.uint8),
    "step": np.array(123456789012, dtype=np.int64),
    "index": np.array([0, 1, 4294967295], dtype=np.uint32),
    "empty": np.zeros((0, 3), dtype=np.float32),
}
save_file(tensors, "official.safetensors", metadata={"format": "pt"})
