"""Frames per second of paper 003's monocular trackers (``latentpf2d``, ``condensation2d``,
``mht2d``) on grey 320x240 frames, float32, 2 XLA threads; compile time (the first call)
reported apart from the steady state (the median of repeated calls of the compiled scan). 003
reports 0.3 s a frame for its tracker with 200 particles (Matlab), 7 s for Condensation with
1000 and 50 s for the MHT. The reference in the same process is the rate of one NCC likelihood
evaluation of all the markers, which every tracker makes once per particle: each line carries
``evaluations per second / reference rate``, what the rest of the step costs.

    taskset -c 0,1 python benchmarks/bench_planar.py --frames 100 --repeats 5 --json planar_speed.json
    taskset -c 0,1 python benchmarks/bench_planar.py --frames 100 --repeats 5 --silhouettes --json planar_sil_speed.json

``--silhouettes`` times each tracker a second time with the frames' foreground masks (background
subtraction against the video's empty-scene frames, done before the clock starts): the step
then also builds each frame's distance map and samples (``planar.silhouette_evidence``) and
scores the silhouette term of every particle.

The SPM model is fitted on one short gesture take (the speed does not depend on the model's
quality, only on its active set: 200 points); the frames are one rendered video.
"""

from __future__ import annotations

import argparse
import time

from bench_output import pin_threads, write_json


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--methods", nargs="+", default=["latentpf2d", "condensation2d", "mht2d"])
    parser.add_argument("--silhouettes", action="store_true", help="also time every tracker with foreground masks")
    parser.add_argument("--json")
    args = parser.parse_args()
    pin_threads(args.threads)
    import jax
    import jax.numpy as jnp
    import numpy as np

    jax.config.update("jax_enable_x64", True)
    import jaxtrack.planar as planar
    from jaxtrack.data import signalling_motion
    from jaxtrack.image import fit_background, rgb_to_grey, subtract_background

    motion = signalling_motion(jax.random.key(0), num_frames=300)
    model, _ = planar.fit_spm_model([motion.joints3d], every=6, iterations=1, max_steps=50)
    video = planar.gesture_video(jax.random.key(100), frames=args.frames + 1)
    grey = jnp.asarray(rgb_to_grey(video.images), jnp.float32)
    frames = grey[1:]
    masks = subtract_background(fit_background(video.background), video.images[1:]).mask if args.silhouettes else None
    rows = []
    templates = planar.marker_templates(grey[0], video.markers[0])
    one = jax.jit(lambda m: templates.log_likelihood(grey[1], m))
    markers = jnp.asarray(video.markers[1], jnp.float32)
    one(markers).block_until_ready()
    batch = jax.jit(jax.vmap(lambda m: templates.log_likelihood(grey[1], m)))
    many = jnp.broadcast_to(markers, (1000, 9, 2))
    batch(many).block_until_ready()
    times = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        batch(many).block_until_ready()
        times.append(time.perf_counter() - start)
    reference = 1000 / float(np.median(times))  # NCC evaluations per second
    print(f"reference: {reference:.0f} NCC likelihood evaluations per second (9 markers, batched 1000)")
    for method, with_masks in [(m, w) for m in args.methods for w in ((False, True) if args.silhouettes else (False,))]:
        tracker = planar.get_tracker2d(method).build(model, grey[0], video.markers[0])
        track_masks = masks if with_masks else None
        if method == "mht2d":
            evaluations = tracker.modes * tracker.samples * (1 + tracker.iterations * (2 + tracker.backtracks))
        else:
            evaluations = tracker.particles
        key = jax.random.key(1)
        start = time.perf_counter()
        jax.block_until_ready(planar.track_frames(tracker, frames, key, masks=track_masks))
        compile_s = time.perf_counter() - start
        times = []
        for r in range(args.repeats):
            start = time.perf_counter()
            jax.block_until_ready(planar.track_frames(tracker, frames, jax.random.key(2 + r), masks=track_masks))
            times.append(time.perf_counter() - start)
        steady = float(np.median(times))
        fps = args.frames / steady
        row = {"method": method, "silhouettes": with_masks, "frames": args.frames, "image": "320x240", "compile_s": compile_s - steady,
               "seconds_per_frame": steady / args.frames, "fps": fps, "likelihood_evaluations_per_frame": evaluations,
               "evaluations_per_s_over_reference": evaluations * fps / reference}
        rows.append(row)
        print(row)
    if args.json:
        write_json(rows, args.json)


if __name__ == "__main__":
    main()
