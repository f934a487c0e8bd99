"""Frames per second of each tracker at several particle budgets, 4 views at 80x60, float32,
2 XLA threads; compile time (first call) reported separately from the steady state (median of
repeated calls on the same compiled function). SIR at the same budget, run in the same process,
is the reference: each line carries the ratio ``fps / fps_SIR``.

    taskset -c 0,1 python benchmarks/bench_trackers.py --budgets 100 500 2000 --frames 30 --repeats 3

Prints one JSON line per (method, budget).
"""

from __future__ import annotations

import argparse
import json
import os
import time


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--budgets", type=int, nargs="+", default=[100, 500, 2000])
    parser.add_argument("--methods", nargs="+", default=["sir", "apf", "mrpf", "gpapf", "latentpf"])
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    os.environ.setdefault("XLA_FLAGS", f"--xla_cpu_multi_thread_eigen=true intra_op_parallelism_threads={args.threads}")
    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack._demo import demo_sequences
    from jaxtrack._experiment import ExperimentConfig, fit_manifold, make_tracker, sequence_poses
    from jaxtrack.filters import fit_noise_scales, make_manifold_prior, run_filter
    from jaxtrack.likelihood import check_silhouettes, make_silhouette_likelihood

    train, validation, test, _ = demo_sequences(jax.random.key(0), test_frames=args.frames)
    train_poses = [sequence_poses(s, "train") for s in train]
    model, _, starts = fit_manifold(train_poses, 2, 100)
    with jax.enable_x64(True):
        prior64 = make_manifold_prior(model, 32)
        scales = fit_noise_scales(prior64, [sequence_poses(s, "validation") for s in validation], starts)
    prior = prior64.astype(jnp.float32)
    seq = test[0]
    rig, body = seq.rig(dtype=jnp.float32), seq.body(dtype=jnp.float32)
    observed = check_silhouettes(seq.silhouettes, rig)
    likelihood = make_silhouette_likelihood(body, rig, scale=100.0, silhouettes=observed)
    observations = jnp.asarray(np.moveaxis(observed, 1, 0))
    initial = jnp.asarray(seq.pose[0], jnp.float32)
    for budget in args.budgets:
        reference = None
        for method in ["sir"] + [m for m in args.methods if m != "sir"]:
            config = ExperimentConfig(methods=(method,), budget=budget, runs=1)
            tracker = make_tracker(method, config, likelihood, prior, scales)
            start = time.perf_counter()
            jax.block_until_ready(run_filter(tracker, jax.random.key(0), initial, observations)[1].estimate)
            first = time.perf_counter() - start
            times = []
            for r in range(args.repeats):
                start = time.perf_counter()
                jax.block_until_ready(run_filter(tracker, jax.random.key(r + 1), initial, observations)[1].estimate)
                times.append(time.perf_counter() - start)
            fps = args.frames / float(np.median(times))
            reference = fps if method == "sir" else reference
            if method in args.methods:
                print(json.dumps({"method": method, "budget": budget, "frames": args.frames, "window": likelihood.window,
                                  "compile_s": round(first - args.frames / fps, 2), "frames_per_s": round(fps, 1),
                                  "ms_per_frame": round(1000 / fps, 1), "ratio_to_sir": round(fps / reference, 2)}), flush=True)


if __name__ == "__main__":
    main()
