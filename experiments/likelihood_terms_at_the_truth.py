"""How well each term of the silhouette + edge + foreground likelihood tells the truth from
nearby poses on a filmed scene (docs/likelihood.md, "Where the silhouettes are corrupted").

    python experiments/likelihood_terms_at_the_truth.py /tmp/video_study/tune_160x120_4 [--noise 0.03 0.08] \\
        [--option edge_colour=true] [--json PATH]

For every 10th of the first 100 frames: the true pose on the default body against ``--count``
poses with Gaussian noise of ``--noise`` radians on every joint angle (the root held). Each term
(000's silhouettes, 001's edge term, 001's foreground term) scores them all; printed is the
fraction of the perturbed poses each term scores below the truth (1 for a term that always puts
the truth first), with the renderer's true silhouettes and with background subtraction's.
"""

import argparse
import json
import os

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from corrupted_silhouettes import read

from jaxtrack.image import fit_background, subtract_background
from jaxtrack.io import load_sequence
from jaxtrack.tracking import prepare_test


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("film")
    parser.add_argument("--noise", type=float, nargs="+", default=[0.03, 0.08], help="radians")
    parser.add_argument("--count", type=int, default=64)
    parser.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                        help="an option of silhouette+edge+foreground (JSON value)")
    parser.add_argument("--json")
    args = parser.parse_args()
    options = {k: json.loads(v) for k, v in (o.split("=", 1) for o in args.option)}
    truth = load_sequence(os.path.join(args.film, "truth.npz"))
    names = [str(n) for n in truth.camera_names]
    frames = read([os.path.join(args.film, f"{n}.mp4") for n in names])
    empty = read([os.path.join(args.film, "background", f"{n}.mp4") for n in names])
    model = fit_background(np.moveaxis(empty, 1, 0))
    masks = np.asarray(subtract_background(model, jnp.asarray(np.moveaxis(frames, 1, 0))).mask).swapaxes(0, 1)
    score = eqx.filter_jit(lambda likelihood, poses, observation: likelihood.log_likelihood(poses, observation))
    rows = []
    for label, silhouettes in (("true", truth.silhouettes), ("background subtraction", masks.astype(np.uint8))):
        scene = prepare_test(truth.replace(silhouettes=silhouettes, images=frames), "film", key=jax.random.key(0),
                             likelihood="silhouette+edge+foreground", likelihood_options=options, body="default",
                             frames=min(100, truth.num_frames))
        silhouette_term, image_terms = scene.likelihood.terms
        for noise in args.noise:
            below = {"silhouette": [], "edge": [], "foreground": []}
            for t in range(0, scene.num_frames, 10):
                pose = jnp.asarray(scene.truth_poses[t], jnp.float32)
                step = noise * jax.random.normal(jax.random.key(t), (args.count, pose.shape[0]))
                poses = jnp.concatenate([pose[None], pose + step.at[:, :6].set(0.0)])
                observation = jax.tree.map(lambda x, t=t: x[t], scene.observations)
                edge, foreground = jax.vmap(image_terms.costs, in_axes=(0, None))(poses, observation)
                for name, value in (("silhouette", np.asarray(score(silhouette_term, poses, observation))),
                                    ("edge", -np.asarray(edge)), ("foreground", -np.asarray(foreground))):
                    below[name].append(float(np.mean(value[1:] < value[0])))
            row = {"silhouettes": label, "noise_rad": noise, **{k: float(np.mean(v)) for k, v in below.items()}}
            rows.append(row)
            print(f"{label} silhouettes, noise {noise} rad: " + ", ".join(f"{k} {row[k]:.3f}" for k in below), flush=True)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(rows, handle, indent=1)


if __name__ == "__main__":
    main()
