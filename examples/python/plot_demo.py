"""Plot a demo's fitted trajectories against the truth (matplotlib).

    pganeus demo --out out/demo          # or pganeus.demo("out/demo") from Python
    python examples/python/plot_demo.py out/demo --out trajectories.png
"""

from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import pganeus  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("demo", help="a demo's output folder")
    parser.add_argument("--out", default="trajectories.png", help="the figure to write")
    args = parser.parse_args()
    demo = pganeus.load_run(args.demo)
    if not isinstance(demo, pganeus.DemoRun):
        raise SystemExit(f"{args.demo}: not a demo folder (no demo.json)")
    fits = demo.fits
    fig, axes = plt.subplots(len(fits), 2, figsize=(10, 3.2 * len(fits)), squeeze=False)
    for row, (video, fit) in enumerate(fits.items()):
        for body in fit.bodies:
            time = np.arange(len(fit.poses(body))) / fit.fps
            truth = demo.true_poses(video, body)
            for stage, style in (("final", "-"), ("simulated", ":")):
                p = fit.poses(body, stage)
                axes[row, 0].plot(time, p[:, 2] * 1000, style, label=f"{body} {stage}")
                err = np.linalg.norm(p[:, :3] - truth[: len(p), :3], axis=1) * 1000
                axes[row, 1].plot(time, err, style, label=f"{body} {stage}")
            axes[row, 0].plot(time, truth[: len(time), 2] * 1000, "k--", lw=1, label=f"{body} truth")
        axes[row, 0].set(title=f"{video}: height", xlabel="s", ylabel="mm")
        axes[row, 1].set(title=f"{video}: distance from the truth", xlabel="s", ylabel="mm")
        axes[row, 0].legend(fontsize=7)
        axes[row, 1].legend(fontsize=7)
        physics = fit.physics()
        print(video, {k: round(v, 3) for k, v in physics["contact"].items() if isinstance(v, float)})
    fig.tight_layout()
    fig.savefig(args.out, dpi=120)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
