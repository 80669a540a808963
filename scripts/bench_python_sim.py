"""The simulator's cost through Python against `pganeus bench-sim`'s figure for the same world.

    python3 scripts/bench_python_sim.py [PATH/TO/pganeus]

The world of `bench-sim` with one body (a 60 x 50 x 40 mm box of 1,000 contact points sliding into a wall,
50 frames at 60 fps, 10 substeps), built from a scene file: forward, and with the gradients of the body's
14 parameters; the median of 7 calls after a warm-up, in milliseconds. With the command's path, its
`bench-sim --threads 1` figures are printed beside them (docs/python.md).
"""

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pganeus

SCENE = """
name = "bench"
[sim]
fps = 60
frames = 50
substeps = 10
[contact]
restitution = 0.4
friction = 0.3
[[scene]]
shape = "plane"
[[scene]]
shape = "box"
half = [0.02, 0.5, 0.05]
t = [0.6, 0.0, 0.05]
[[body]]
name = "box0"
mass = 0.2
t = [0.0, 0.0, 0.05]
v = [1.5, 0.0, 0.5]
omega = [0.0, 0.0, 1.0]
contact_points = 1000
[body.shape]
shape = "box"
half = [0.03, 0.025, 0.02]
"""


def median_ms(call, runs=7):
    call()
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        call()
        times.append((time.perf_counter() - t0) * 1000)
    return sorted(times)[len(times) // 2]


def main():
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "bench.toml"
        path.write_text(SCENE)
        world = pganeus.World.from_scene_file(path)
    wrt = list(range(14))
    python = {
        "forward": median_ms(lambda: world.simulate()),
        "gradients_one_body": median_ms(lambda: world.simulate_with_gradients(wrt=wrt)),
    }
    rust = {}
    if len(sys.argv) > 1:
        out = subprocess.run([sys.argv[1], "bench-sim", "--threads", "1"], capture_output=True, text=True, check=True)
        for line in out.stdout.splitlines():
            row = json.loads(line)
            if row.get("bodies") == 1 and row["mode"] in python:
                rust[row["mode"]] = row["ms"]
    for mode, ms in python.items():
        row = {"mode": mode, "python_ms": round(ms, 3)}
        if mode in rust:
            row["rust_ms"] = rust[mode]
            row["overhead_percent"] = round(100 * (ms / rust[mode] - 1), 1)
        print(json.dumps(row))


if __name__ == "__main__":
    main()
