"""Does colour in 004's blobs track better than position alone (docs/vlmm.md, "Colour in the blobs")?

    taskset -c 0,1 python experiments/colour_blobs.py --json colour_blobs.json    # about 15 minutes on 2 cores

Training and validation: the demo's walks and jogs of subjects S1 and S2; the manifold a 3-D
BC-GPLVM (100 steps), each tracker's dynamics fitted on it. Test: the demo's S1 walk and S2 jog
(40 frames, 4 views), filmed in colour by ``data.render_rgb``: the solid body (ellipsoids, not
the tracker's capsules) in a red shirt, blue trousers and skin over a photograph, with shading,
a lighting change and sensor noise. Both likelihoods read the solid body's true silhouettes;
``colour-blobs`` reads the pictures as well (the person's blob colours taken at the true start
pose on frame 0). Blobs at power 10 (docs/vlmm.md), budget 500, ``--runs`` runs per cell.
"""

import argparse
import json

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack import tracking
from jaxtrack.body import forward_kinematics
from jaxtrack.data import SolidBody, render_rgb
from jaxtrack.demo import demo_sequences
from jaxtrack.filters import run_filter

POWER = 10.0


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--budget", type=int, default=500)
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--size", default="80x60", help="image size WIDTHxHEIGHT the scenes are filmed at")
    parser.add_argument("--methods", nargs="+", default=["vlmmpf", "mrpf"])
    parser.add_argument("--likelihoods", nargs="+", default=["blobs", "colour-blobs", "colour-in-score"],
                        help="blobs, colour-blobs (colour guides the fit), colour-in-score (colour-blobs with "
                             "colour_in_score=True: 004's 6-D blobs)")
    parser.add_argument("--json", help="write the results here")
    args = parser.parse_args()
    width, height = map(int, args.size.split("x"))
    key = jax.random.key(0)
    train, validation, test, names = demo_sequences(key, test_frames=args.frames, width=width, height=height)
    train_poses = [tracking.sequence_poses(s, "train", key=key) for s in train]
    validation_poses = [tracking.sequence_poses(s, "validation", key=key) for s in validation]
    model, _, starts = tracking.fit_manifold(train_poses, 3, 100, kind="bc-gplvm")[:3]
    motion = tracking.motion_data(train_poses, validation_poses, model, starts)
    rows = []
    for sequence, name in zip(test, names["test"]):
        pictures, masks = render_rgb(jax.random.fold_in(key, 7), SolidBody(sequence.body().skeleton), sequence.rig(),
                                     sequence.pose[: args.frames], fps=sequence.fps)
        filmed = sequence.replace(images=np.asarray(pictures), silhouettes=np.asarray(masks).astype(np.uint8))
        for likelihood in args.likelihoods:
            options = {"power": POWER} | ({"colour_in_score": True} if likelihood == "colour-in-score" else {})
            scene = tracking.prepare_test(filmed, name, key=key, likelihood="colour-blobs" if likelihood == "colour-in-score"
                                          else likelihood, likelihood_options=options)
            truth = jnp.asarray(scene.truth_joints, jnp.float32)
            for method in args.methods:
                recipe = tracking.get_tracker(method)
                fitted = tracking.fit_tracker(recipe, tracking.tracker_keys(0, method)[0], motion)
                tracker = tracking.build_tracker(recipe, fitted, scene.likelihood, tracking.Budget(args.budget, 5),
                                                 velocity_from=validation_poses)
                errors = []
                for run in range(args.runs):
                    _, info = run_filter(tracker, jax.random.fold_in(key, run), scene.initial_pose, scene.observations)
                    joints = forward_kinematics(scene.body.skeleton, jnp.asarray(info.estimate, jnp.float32))
                    errors.append(float(1000 * jnp.mean(jnp.linalg.norm(joints - truth, axis=-1))))
                row = {"scene": name, "size": args.size, "likelihood": likelihood, "method": method,
                       "mean_mm": round(float(np.mean(errors)), 1), "sd_mm": round(float(np.std(errors)), 1),
                       "runs_mm": [round(e, 1) for e in errors]}
                rows.append(row)
                print(json.dumps(row), flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
