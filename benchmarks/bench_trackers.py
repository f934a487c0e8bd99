"""Frames per second of each registered tracker (each on its own manifold) at several particle budgets, 4 views at 80x60,
float32, 2 XLA threads; compile time (first call) reported separately from the steady state
(median of repeated calls on the same compiled function). SIR at the same budget, run in the
same process, is the reference: each line carries the ratio ``fps / fps_SIR``.

    taskset -c 0,1 python benchmarks/bench_trackers.py --budgets 100 500 2000 --frames 30 --repeats 3 --json trackers.json
    taskset -c 0,1 python benchmarks/bench_trackers.py --methods vlmmpf mrpf --budgets 500 --likelihood blobs

``--likelihood`` tracks with another registered likelihood (default the silhouettes'); one that reads
images (``colour-blobs``) gets the test take filmed in colour by ``data.render_rgb``.

    taskset -c 0,1 python benchmarks/bench_trackers.py --methods vlmmpf mrpf --budgets 500 --likelihood colour-blobs

Prints one JSON line per (method, budget) and, with ``--json PATH``, writes the list there.
"""

from __future__ import annotations

import argparse
import json
import time

from bench_output import pin_threads, write_json


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--budgets", type=int, nargs="+", default=[100, 500, 2000])
    parser.add_argument("--methods", nargs="+", help="registered tracker names (default: the papers' five)")
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--likelihood", default="silhouette", help="a registered likelihood (e.g. blobs, 004's)")
    parser.add_argument("--likelihood-option", action="append", default=[], metavar="KEY=VALUE",
                        help="an option of that likelihood, e.g. power=10 (numbers)")
    parser.add_argument("--json", help="also write the rows to this JSON file")
    args = parser.parse_args()
    pin_threads(args.threads)
    import jax
    import numpy as np

    from jaxtrack.demo import demo_sequences
    from jaxtrack.filters import run_filter
    from jaxtrack.likelihood import get_likelihood
    from jaxtrack.tracking import (
        PAPER_TRACKERS,
        Budget,
        build_tracker,
        fit_manifold,
        fit_tracker,
        get_tracker,
        motion_data,
        prepare_test,
        sequence_poses,
        tracker_keys,
    )

    methods = args.methods or list(PAPER_TRACKERS)
    key = jax.random.key(0)
    train, validation, test, _ = demo_sequences(key, test_frames=args.frames)
    train_poses = [sequence_poses(s, "train", key=key) for s in train]
    validation_poses = [sequence_poses(s, "validation", key=key) for s in validation]
    motions = {}  # each tracker on its own manifold kind and latent dimension, as the experiment fits them
    fitted = {}
    for m in ["sir"] + methods:
        recipe = get_tracker(m)
        spec = (recipe.manifold, recipe.latent_dim_for(recipe.manifold, None)) if recipe.needs_manifold else None
        if spec not in motions:
            model, starts = (None, None) if spec is None else fit_manifold(train_poses, spec[1], 100, kind=spec[0])[::2]
            motions[spec] = motion_data(train_poses, validation_poses, model, starts)
        fitted[m] = fit_tracker(recipe, tracker_keys(0, m)[0], motions[spec])
    options = {k: float(v) for k, v in (item.split("=", 1) for item in args.likelihood_option)}
    sequence = test[0]
    if "images" in get_likelihood(args.likelihood).observes:  # filmed in colour: the solid body over a photograph
        from jaxtrack.data import SolidBody, render_rgb

        pictures, _ = render_rgb(key, SolidBody(sequence.body().skeleton), sequence.rig(), sequence.pose, fps=sequence.fps)
        sequence = sequence.replace(images=np.asarray(pictures))
    scene = prepare_test(sequence, "S1 walk", key=key, likelihood=args.likelihood, likelihood_options=options)
    rows = []
    for budget in args.budgets:
        reference = None
        for method in ["sir"] + [m for m in methods if m != "sir"]:
            tracker = build_tracker(get_tracker(method), fitted[method], scene.likelihood, Budget(budget, 5))
            start = time.perf_counter()
            jax.block_until_ready(run_filter(tracker, jax.random.key(0), scene.initial_pose, scene.observations)[1].estimate)
            first = time.perf_counter() - start
            times = []
            for r in range(args.repeats):
                start = time.perf_counter()
                jax.block_until_ready(run_filter(tracker, jax.random.key(r + 1), scene.initial_pose, scene.observations)[1].estimate)
                times.append(time.perf_counter() - start)
            fps = args.frames / float(np.median(times))
            reference = fps if method == "sir" else reference
            if method in methods:
                row = {"method": method, "budget": budget, "frames": args.frames, "likelihood": args.likelihood,
                       "window": getattr(scene.likelihood, "window", None),
                       "compile_s": round(first - args.frames / fps, 2), "frames_per_s": round(fps, 1),
                       "ms_per_frame": round(1000 / fps, 1), "ratio_to_sir": round(fps / reference, 2),
                       "device": jax.devices()[0].device_kind}
                rows.append(row)
                print(json.dumps(row), flush=True)
    write_json(rows, args.json)


if __name__ == "__main__":
    main()
