#!/usr/bin/env python3
"""How a video's fitted contact values move with the geometry they are simulated in.

For the tabletop preset's demo (`pganeus demo --out DEMO`): the truth's motion of VIDEO (slide or drop)
is simulated again on perturbed analytic geometries (the wall moved or tilted, the board raised, the toy
grown or its edges rounded otherwise) and on the demo's reconstructions (its baked scene, its merged toy);
for each it prints how far the truth's launch and values then leave the truth's poses (worst frame,
mm / degrees) and what `fit-physics --fix-omega` fits to the true poses there.

    python3 scripts/geometry_sensitivity.py DEMO slide [--pganeus target/release/pganeus]

The scene below is the tabletop preset's (`synth --preset tabletop`: a 0.6 m board 10 mm thick on a table,
the wall a 40 × 240 × 70 mm box at x = 0.22 m, the toy a 60 × 44 × 36 mm box rounded by 5 mm, 80 g).
"""
import argparse, json, math, os, re, subprocess, tempfile

SIM = """[sim]
fps = {fps}
frames = {frames}
substeps = {substeps}
contact_model = "{contact_model}"
contact_threshold = {contact_threshold}
speculative_contacts = true
friction_model = "{friction_model}"

[contact]
restitution = {r}
friction = {mu}
"""


def scene(wall_dx=0.0, wall_tilt_deg=0.0, board_dz=0.0):
    h = math.radians(wall_tilt_deg) / 2
    return f"""[[scene]]
shape = "box"
half = [0.3, 0.3, 0.005]
t = [0.0, 0.0, {-0.005 + board_dz}]
[[scene]]
shape = "plane"
normal = [0, 0, 1]
offset = -0.01
[[scene]]
shape = "box"
half = [0.02, 0.12, 0.035]
t = [{0.22 + wall_dx}, 0.0, 0.035]
q = [{math.cos(h)}, 0.0, {math.sin(h)}, 0.0]
"""


def body(initial, v, omega, grow=0.0, radius=0.005, mesh=None):
    head = f"""[[body]]
name = "toy"
mass = 0.08
t = {initial['t']}
q = {initial['q']}
v = {v}
omega = {omega}
contact_points = 1000
"""
    if mesh:
        return head + f'mesh = "{mesh}"\n'
    return head + f"""[body.shape]
shape = "rounded_box"
half = [{0.03 + grow}, {0.022 + grow}, {0.018 + grow}]
radius = {radius}
"""


def poses(path, video=None):
    j = json.load(open(path))
    if "videos" in j:
        j = next(v for v in j["videos"] if v["capture"] == video)
    return j["bodies"][0]["poses"]


def worst(a, b):
    """The worst frame's position (mm) and rotation (°) between two pose lists."""
    out = (0.0, 0.0, 0)
    for k, (x, y) in enumerate(zip(a, b)):
        d = math.dist(x["t"], y["t"]) * 1e3
        ang = 2 * math.degrees(math.acos(min(1.0, abs(sum(p * q for p, q in zip(x["q"], y["q"]))))))
        if d > out[0]:
            out = (d, ang, k)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("demo")
    ap.add_argument("video")
    ap.add_argument("--pganeus", default="target/release/pganeus")
    a = ap.parse_args()
    truth = json.load(open(os.path.join(a.demo, "data", "truth.json")))
    video = next(v for v in truth["videos"] if v["capture"] == a.video)
    init = video["bodies"][0]["initial"]
    sim = {**video["sim"], "frames": len(video["bodies"][0]["poses"])}
    head = lambda r, mu: SIM.format(r=r, mu=mu, **sim)
    c = video["contact"]
    recon_scene = f'[[scene]]\nshape = "grid"\nfile = "{os.path.abspath(os.path.join(a.demo, "scene.sdf"))}"\n'
    merged = os.path.abspath(os.path.join(a.demo, "merged", "toy", "merged.ply"))
    cases = {
        "truth's geometry": (scene(), {}),
        "wall +0.5 mm": (scene(wall_dx=0.0005), {}),
        "wall -0.5 mm": (scene(wall_dx=-0.0005), {}),
        "wall tilted 1°": (scene(wall_tilt_deg=1.0), {}),
        "board +0.3 mm": (scene(board_dz=0.0003), {}),
        "toy +0.3 mm": (scene(), {"grow": 0.0003}),
        "toy edges 3 mm": (scene(), {"radius": 0.003}),
        "toy edges 7 mm": (scene(), {"radius": 0.007}),
        "reconstructed scene": (recon_scene, {}),
        "merged toy": (scene(), {"mesh": merged}),
        "both reconstructed": (recon_scene, {"mesh": merged}),
    }
    observed = poses(os.path.join(a.demo, "data", "truth.json"), a.video)
    run = lambda *args: subprocess.run([a.pganeus, *args], capture_output=True, text=True, check=True).stdout
    with tempfile.TemporaryDirectory() as d:
        # The observed poses as a trajectory file: the truth's geometry simulated again (the same poses).
        obs = os.path.join(d, "observed.json")
        open(os.path.join(d, "truth.toml"), "w").write(head(c["restitution"], c["friction"]) + scene() + body(init, init["v"], init["omega"]))
        run("simulate", "--scene", os.path.join(d, "truth.toml"), "--out", obs)
        again = worst(observed, poses(obs))
        assert again[0] < 0.01, f"the truth's scene does not give the truth's motion ({again}): not the tabletop preset?"
        for name, (sc, b) in cases.items():
            true_file, guess_file = os.path.join(d, "true.toml"), os.path.join(d, "guess.toml")
            open(true_file, "w").write(head(c["restitution"], c["friction"]) + sc + body(init, init["v"], init["omega"], **b))
            # The guess: the launch 30 % fast, restitution halved, friction 1.5 times; the spin held at the truth's.
            v = [1.3 * x for x in init["v"]]
            open(guess_file, "w").write(head(0.5 * c["restitution"], 1.5 * c["friction"]) + sc + body(init, v, init["omega"], **b))
            run("simulate", "--scene", true_file, "--out", os.path.join(d, "sim.json"))
            pos, rot, k = worst(observed, poses(os.path.join(d, "sim.json")))
            out = run("fit-physics", "--poses", obs, "--scene", guess_file, "--out", os.path.join(d, "fit.json"), "--fix-omega")
            vals = dict(re.findall(r"(restitution|friction)\s+=\s+([0-9.]+)", out))
            err = re.search(r"pose error\s+=\s+(.*)", out)
            print(f"{name:22} the truth's values: worst {pos:.1f} mm / {rot:.1f}° (frame {k}); "
                  f"fitted restitution {vals.get('restitution')}, friction {vals.get('friction')} ({err.group(1) if err else '?'})", flush=True)


if __name__ == "__main__":
    main()
