"""Where a 2-D GPDM starts: its latent trajectory fitted from the principal components (001's
start, the library's default) and from 002's Generalised Laplacian Eigenmap
(``make_gpdm(..., init="gle")``), on the demo's training motion and, with ``--cmu``, on the
CMU walk protocol's training takes.

For each start it prints the fitted objective (001 eq. 11, to be maximised), the fit time and
the *fold gap*: for every frame, the latent distance to the nearest frame of the same take whose
pose is far from it (farther than the take's median pair of poses), in median latent steps, the
median over the frames. A small gap is a fold: the cycle's two sides lie side by side, phase
phi beside phase pi - phi (the same stride, the legs swinging the other way), and a particle
that drifts across the loop runs the cycle backwards. The figure plots each fitted trajectory
coloured by which leg is ahead (left hip flexion minus right).

    taskset -c 0,1 python experiments/gpdm_starts.py --cmu /tmp/cmu --plot docs/figures/gpdm_starts.png --json starts.json
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "benchmarks"))  # bench_output, real_motion
from bench_output import add_output_arguments, pin_threads, write_json

STARTS = ("pca", "gle")


def fold_gap(latent, angles, starts):
    """Median over frames of the latent distance to the nearest frame of the same take whose pose
    is farther from it than the take's median pair of poses, over the median latent step
    (module docstring)."""
    import numpy as np

    gaps = []
    for begin, end in itertools.pairwise(starts):
        z, y = latent[begin:end], angles[begin:end]
        far = np.sqrt(np.sum((y[:, None] - y[None]) ** 2, axis=-1))
        far = far > np.median(far)
        apart = np.sqrt(np.sum((z[:, None] - z[None]) ** 2, axis=-1))
        step = np.median(np.linalg.norm(np.diff(z, axis=0), axis=1))
        gaps.append(np.min(np.where(far, apart, np.inf), axis=1) / step)
    return float(np.median(np.concatenate(gaps)))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cmu", help="folder with the converted CMU takes (35_01.npz, ...): adds the CMU walk's training takes")
    parser.add_argument("--steps", type=int, default=300, help="fit steps (the experiment's default; its default optimiser, optax L-BFGS)")
    add_output_arguments(parser, plot="write the fitted latent trajectories here")
    args = parser.parse_args()
    pin_threads(args.threads)

    import jax
    import numpy as np

    from jaxtrack.body import humaneva_skeleton, joint_angles
    from jaxtrack.demo import demo_sequences
    from jaxtrack.io import load_sequence
    from jaxtrack.manifold import make_gpdm

    names = list(humaneva_skeleton().dof_names[3:])
    lead = (names.index("lhip_flex"), names.index("rhip_flex"))
    train, _, _, _ = demo_sequences(jax.random.key(0))
    sets = {"demo (walk, jog of S1, S2)": [np.asarray(joint_angles(np.asarray(s.pose))) for s in train]}
    if args.cmu:
        sets["CMU walk (35_01, 35_02)"] = [np.asarray(joint_angles(np.asarray(load_sequence(os.path.join(args.cmu, f"35_{t}.npz")).pose)))
                                           for t in ("01", "02")]
    rows, panels = [], []
    with jax.enable_x64(True):
        for name, angles in sets.items():
            starts = np.cumsum([0] + [len(a) for a in angles])
            stacked = np.concatenate(angles)
            for start in STARTS:
                begin = time.perf_counter()
                model, info = make_gpdm(angles, 2, init=start).fit(max_steps=args.steps, optimiser="optax")
                seconds = time.perf_counter() - begin
                latent = np.asarray(model.training_latent())
                rows.append({"motion": name, "start": start, "objective": float(info.objective), "steps": int(info.steps),
                             "fit_s": round(seconds, 1), "fold_gap": round(fold_gap(latent, stacked, starts), 2)})
                panels.append((f"{name}: {start.upper()} start", latent, stacked[:, lead[0]] - stacked[:, lead[1]]))
                print(f"{name:28s} {start:4s} objective {info.objective:10.1f}, fold gap {rows[-1]['fold_gap']:5.2f} median steps, "
                      f"fit {seconds:.0f} s", flush=True)
                write_json(rows, args.json)
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(len(sets), len(STARTS), figsize=(5 * len(STARTS), 4.5 * len(sets)), squeeze=False)
        for ax, (title, latent, ahead) in zip(axes.ravel(), panels):
            limit = np.max(np.abs(ahead))
            points = ax.scatter(latent[:, 0], latent[:, 1], c=ahead, cmap="coolwarm", vmin=-limit, vmax=limit, s=7)
            ax.set_title(title, fontsize=10)
            ax.set_aspect("equal")
        fig.colorbar(points, ax=axes, label="left hip flexion - right (rad): which leg is ahead")
        fig.savefig(args.plot, dpi=110, bbox_inches="tight")
        print(f"wrote {args.plot}")


if __name__ == "__main__":
    main()
