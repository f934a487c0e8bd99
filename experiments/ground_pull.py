"""Where do the silhouettes put the body's height? Each test scene's true poses are lowered or
raised as a whole (the root's height shifted by -40 to +20 mm) and scored under the silhouette
likelihood at the experiment's scale, alone and times the ground plane's prior
(``jaxtrack.likelihood.GroundPlanePrior``, its clearance fitted on the scene's validation
motion as the experiment does). A likelihood that sees the height right peaks at 0 mm.

Scenes: the demo's two test scenes (4 views, rendered with the tracker's own body), noisy as the
demo renders them and clean (``NO_NOISE``); with ``--cmu`` / ``--bandai``, also
``real_motion.py``'s protocols (the test take rendered with another body into noisy 80x60
views). Prints per scene the shift of the best total log-likelihood, the median of each frame's
best shift, and the log-likelihood lost at the true height (nats per frame); ``--plot`` draws
the mean log-likelihood per frame against the shift.

    taskset -c 0,1 python experiments/ground_pull.py --plot docs/figures/ground_pull.png --json ground_pull.json
    taskset -c 0,1 python experiments/ground_pull.py --cmu /tmp/cmu --bandai /tmp/bandai --views 4 3
"""

from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "benchmarks"))  # bench_output, real_motion
from bench_output import add_output_arguments, pin_threads, write_json
from real_motion import PROTOCOLS, add_protocol_arguments, load_protocol_takes, other_body_scene, protocol_names

SHIFTS_MM = tuple(x / 2 for x in range(-80, 41, 5))  # -40 to +20 mm in 2.5 mm steps


def height_profile(scene, likelihood, shifts_mm):
    """(shifts, T) log-likelihood of every frame's true pose with the root's height shifted."""
    import equinox as eqx
    import jax
    import jax.numpy as jnp
    import numpy as np

    truth = jnp.asarray(scene.truth_poses, scene.initial_pose.dtype)

    @eqx.filter_jit
    def frames(likelihood, shift):
        return jax.vmap(lambda pose, observation: likelihood(pose[None], observation)[0])(truth.at[:, 2].add(shift), scene.observations)

    return np.stack([np.asarray(frames(likelihood, jnp.asarray(s / 1000, truth.dtype)), np.float64) for s in shifts_mm])


def summary(profile, shifts_mm) -> dict:
    """The best shift of the total, the median of the frames' best shifts, and the nats per
    frame lost at 0 mm against the best shift."""
    import numpy as np

    shifts = np.asarray(shifts_mm)
    mean = profile.mean(axis=1)
    zero = int(np.argmin(np.abs(shifts)))
    return {"best_shift_mm": float(shifts[np.argmax(mean)]), "median_frame_best_mm": float(np.median(shifts[profile.argmax(axis=0)])),
            "nats_lost_at_truth": float(mean.max() - mean[zero]), "mean_log_likelihood": (mean - mean.max()).round(4).tolist()}


def demo_scenes(clean: bool):
    """The demo's test scenes (noisy or clean) with its validation sequences."""
    import jax

    from jaxtrack.data import NO_NOISE
    from jaxtrack.demo import demo_sequences

    _train, validation, test, names = demo_sequences(jax.random.key(0), noise=NO_NOISE if clean else None)
    label = "clean" if clean else "noisy"
    return [(f"demo {name}, {label}", sequence, validation) for name, sequence in zip(names["test"], test)]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_protocol_arguments(parser)
    parser.set_defaults(sequences=[])
    parser.add_argument("--views", type=int, nargs="+", default=[4], help="views of the protocols' scenes")
    add_output_arguments(parser, plot="draw the mean log-likelihood per frame against the height shift")
    args = parser.parse_args()
    pin_threads(args.threads)
    import jax

    from jaxtrack.tracking import add_ground_prior, motion_clearance, prepare_test, sequence_poses

    key = jax.random.key(0)
    cases = demo_scenes(clean=False) + demo_scenes(clean=True)
    if args.cmu or args.bandai:
        folders = {"cmu": args.cmu, "bandai": args.bandai}
        for name in protocol_names(args.sequences or [n for n in PROTOCOLS if PROTOCOLS[n][0] in
                                                      [d for d, f in folders.items() if f]][:4]):
            _dataset, _train, validation_takes, test_take, frames = PROTOCOLS[name]
            takes = load_protocol_takes(parser, folders, name, validation_takes + [test_take])
            for views in args.views:
                scene = other_body_scene(jax.random.fold_in(key, views), takes[test_take], views, frames)
                cases.append((f"{name}, {views} views", scene, [takes[t] for t in validation_takes]))
    rows = []
    for label, sequence, validation in cases:
        scene = prepare_test(sequence, label, key=key)
        clearance = motion_clearance(validation, [sequence_poses(s, "validation", key=key) for s in validation])
        grounded = add_ground_prior(scene, clearance)
        row = {"scene": label, "frames": scene.num_frames, "clearance_m": float(grounded.ground_prior.clearance),
               "shifts_mm": list(SHIFTS_MM)}
        for which, likelihood in (("silhouettes", scene.likelihood), ("with_ground_prior", grounded.likelihood)):
            row[which] = summary(height_profile(scene, likelihood, SHIFTS_MM), SHIFTS_MM)
        rows.append(row)
        alone, with_prior = row["silhouettes"], row["with_ground_prior"]
        print(f"{label:28s} best shift {alone['best_shift_mm']:+6.1f} mm (frames' median {alone['median_frame_best_mm']:+6.1f}), "
              f"{alone['nats_lost_at_truth']:.2f} nats/frame lost at the truth; with the ground prior "
              f"{with_prior['best_shift_mm']:+6.1f} mm ({with_prior['median_frame_best_mm']:+6.1f}), "
              f"{with_prior['nats_lost_at_truth']:.2f}", flush=True)
        write_json(rows, args.json)
    if args.plot:
        plot(rows, args.plot)


def plot(rows, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns = min(4, len(rows))
    lines = -(-len(rows) // columns)
    fig, axes = plt.subplots(lines, columns, figsize=(2.8 * columns, 2.5 * lines), sharex=True, sharey=True, squeeze=False)
    for ax in axes.flat[len(rows):]:
        ax.set_visible(False)
    for ax, row in zip(axes.flat, rows):
        ax.plot(row["shifts_mm"], row["silhouettes"]["mean_log_likelihood"], label="silhouettes")
        ax.plot(row["shifts_mm"], row["with_ground_prior"]["mean_log_likelihood"], label="x ground prior")
        ax.axvline(0, color="k", lw=0.6)
        ax.set_title(row["scene"], fontsize=8)
        ax.set_ylim(-3, 0.2)
    for ax in axes[-1]:
        ax.set_xlabel("root height shift (mm)", fontsize=8)
    for ax in axes[:, 0]:
        ax.set_ylabel("log-likelihood per frame\n(nats, from its best)", fontsize=8)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
