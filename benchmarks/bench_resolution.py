"""Tracking 320x240 silhouettes at a coarse level (block-averaged to ``--coarse``, cameras
rescaled: ``ExperimentConfig(resolution=...)``) against scoring every pixel at 320x240: the error
and frames per second of the same runs (same keys), and the bias of the coarse cost.

    taskset -c 0,1 python benchmarks/bench_resolution.py --json resolution.json

Scenes: the demo's synthetic S1 walk and S2 jog (40 frames, 60 Hz) rendered at ``--width`` x
``--height`` with background-subtraction noise in ``--views`` cameras of the default rig;
manifold and dynamics fitted as in the demo. Bias: for ``--particles`` poses scattered around the
truth of the walk's first frame, the cost of 000 eq. 12 (mean over views) at the coarse level
against the dense one at full resolution: mean and sd of the difference, and their correlation
(what the weights depend on is the ranking).
"""

from __future__ import annotations

import argparse
import os

from bench_output import write_json


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--coarse", default="80x60", help="the level tracked at, WxH (must divide the image size)")
    parser.add_argument("--views", type=int, default=3)
    parser.add_argument("--methods", nargs="+", default=["mrpf"])
    parser.add_argument("--budget", type=int, default=500)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--particles", type=int, default=200, help="poses for the bias measurement")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--json", metavar="PATH", help="also write the rows to this JSON file")
    args = parser.parse_args()
    os.environ.setdefault("XLA_FLAGS", f"--xla_cpu_multi_thread_eigen=true intra_op_parallelism_threads={args.threads}")
    import json

    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack.camera import default_rig
    from jaxtrack.data import SilhouetteNoise, build_scene, generate_motion, motion_sequence
    from jaxtrack.demo import DEMO_TEST, DEMO_TRAINING, DEMO_VALIDATION
    from jaxtrack.experiment import ExperimentConfig, run_experiment
    from jaxtrack.tracking import prepare_test

    coarse = tuple(int(v) for v in args.coarse.split("x"))
    key = jax.random.key(0)

    def motion(gait, subject, frames, tag):
        return generate_motion(gait, subject, num_frames=frames, fps=60.0, key=jax.random.fold_in(key, tag))

    train = [motion_sequence(motion(g, s, 80, i)) for i, (g, s) in enumerate(DEMO_TRAINING)]
    validation = [motion_sequence(motion(g, s, 80, 100 + i)) for i, (g, s) in enumerate(DEMO_VALIDATION)]
    rig = default_rig(args.width, args.height, num_views=args.views)
    test = [build_scene(jax.random.fold_in(key, 300 + i), motion(g, s, 40, 200 + i), rig, SilhouetteNoise())
            for i, (g, s) in enumerate(DEMO_TEST)]
    names = {"test": [f"{s} {g}" for g, s in DEMO_TEST]}

    rows = []
    # The bias of the coarse cost against every pixel, around the walk's first frame.
    fine = prepare_test(test[0], "walk", key=key, frames=1, window=None)
    low = prepare_test(test[0], "walk", key=key, frames=1, window=None, resolution=coarse)
    truth = jnp.asarray(fine.initial_pose)
    sigma = jnp.full(truth.shape, 0.1, truth.dtype).at[:3].set(0.03)
    poses = truth + sigma * jax.random.normal(jax.random.fold_in(key, 9), (args.particles, truth.shape[0]), truth.dtype)
    scale_fine, scale_low = float(fine.likelihood.scale), float(low.likelihood.scale)
    cost_fine = -np.asarray(fine.likelihood(poses, fine.observations[0])) / scale_fine
    cost_low = -np.asarray(low.likelihood(poses, low.observations[0])) / scale_low
    difference = cost_low - cost_fine
    rows.append({"what": "cost bias", "image": f"{args.width}x{args.height}", "coarse": args.coarse, "views": args.views,
                 "particles": args.particles, "fine_cost_mean": float(cost_fine.mean()), "fine_cost_sd": float(cost_fine.std()),
                 "bias_mean": float(difference.mean()), "bias_sd": float(difference.std()),
                 "correlation": float(np.corrcoef(cost_low, cost_fine)[0, 1])})
    print(json.dumps(rows[-1]), flush=True)
    write_json(rows, args.json)

    for resolution in (None, coarse):
        config = ExperimentConfig(methods=tuple(args.methods), budget=args.budget, runs=args.runs, resolution=resolution)
        results = run_experiment(train, validation, test, config, names=names, progress=False, animations=False)
        for name, per_method in results["sequences"].items():
            for method, r in per_method.items():
                rows.append({"what": "tracking", "sequence": name, "method": method,
                             "tracked_at": "x".join(map(str, resolution)) if resolution else f"{args.width}x{args.height}",
                             "views": args.views, "budget": args.budget, "runs": args.runs,
                             "error_mm_mean": r["error_mm_mean"], "error_mm_per_run": r["error_mm_per_run"],
                             "frames_per_second": r["frames_per_second"], "compile_s": r.get("compile_s")})
                print(json.dumps(rows[-1]), flush=True)
                write_json(rows, args.json)


if __name__ == "__main__":
    main()
