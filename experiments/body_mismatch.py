"""Tracking when the body is not the tracker's: the demo's walk and jog rendered with a subject
whose torso is 20 % thicker, legs 15 % thinner and arms 10 % thicker than jaxtrack's default
capsules. The test files carry no ``capsule_radii``, so the trackers start from the defaults
(with the subject's limb lengths), with and without ``--calibrate-shape``, in 4 views and in 3.

    taskset -c 0,1 python experiments/body_mismatch.py --json body_mismatch.json

Prints one table per setting and, with ``--json PATH``, writes every result there.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "benchmarks"))  # bench_output, real_motion
from bench_output import write_json

BODY_FACTORS = {"torso": 1.2, "legs": 0.85, "arms": 1.1, "head": 1.0}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--methods", nargs="+", default=["sir", "apf", "mrpf", "gpapf", "latentpf"])
    parser.add_argument("--budget", type=int, default=300)
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--views", type=int, nargs="+", default=[4, 3])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="also write the results to this JSON file")
    args = parser.parse_args()
    import equinox as eqx
    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack.camera import default_rig
    from jaxtrack.data import SilhouetteNoise, build_scene, generate_motion
    from jaxtrack.demo import DEMO_TEST, demo_sequences
    from jaxtrack.experiment import ExperimentConfig, results_table, run_experiment

    key = jax.random.key(args.seed)
    train, validation, _, names = demo_sequences(key, test_frames=args.frames)
    rows = []
    for views in args.views:
        rig = default_rig(80, 60, num_views=views)
        test = []
        for i, (gait, subject) in enumerate(DEMO_TEST):
            motion = generate_motion(gait, subject, num_frames=args.frames, fps=60.0, key=jax.random.fold_in(key, 200 + i))
            radii = np.asarray(motion.body.radii) * np.array([BODY_FACTORS[g] for g in motion.body.capsule_groups])
            other = dataclasses.replace(motion, body=eqx.tree_at(lambda b: b.radii, motion.body, jnp.asarray(radii, jnp.float32)))
            scene = build_scene(jax.random.fold_in(key, 300 + i), other, rig, SilhouetteNoise())
            test.append(scene.replace(capsule_radii=None))  # the tracker does not know the subject's shape
        for calibrate in (False, True):
            config = ExperimentConfig(methods=tuple(args.methods), budget=args.budget, runs=args.runs, fit_steps=100, seed=args.seed,
                                      calibrate_shape=calibrate)
            results = run_experiment(train, validation, test, config, names=names, progress=False)
            print(f"\n{views} views, other body, calibrate_shape={calibrate}\n")
            print(results_table(results), flush=True)
            rows.append({"views": views, "calibrate_shape": calibrate, "body_factors": BODY_FACTORS,
                         "sequences": {n: {m: {k: v[m][k] for k in ("error_mm_mean", "error_mm_std", "error_mm_per_run")}
                                           for m in args.methods} for n, v in results["sequences"].items()},
                         "shape_calibration": results["shape_calibration"]})
    write_json(rows, args.json)


if __name__ == "__main__":
    main()
