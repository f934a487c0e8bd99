"""Tracking 320x240 silhouettes without paying for every pixel, against scoring every pixel (of
the likelihood's window) at 320x240: the error and frames per second of the same runs (same
keys), and the bias of each cheap cost against the dense one. The cheap likelihoods:

- sampled: 000 eq. 12 on ``--samples`` stratified pixels per view and frame
  (``ExperimentConfig(pixel_samples=...)``, ``jaxtrack.likelihood.SampledSilhouetteLikelihood``);
- coarse: the silhouettes block-averaged to ``--coarse`` and the cameras rescaled
  (``ExperimentConfig(resolution=...)``).

    taskset -c 0,1 python benchmarks/bench_resolution.py --json resolution.json

Scenes: the demo's synthetic S1 walk and S2 jog (40 frames, 60 Hz) rendered at ``--width`` x
``--height`` with background-subtraction noise in ``--views`` cameras of the default rig;
manifold and dynamics fitted as in the demo. Bias: for ``--particles`` poses scattered around the
truth of the walk's first frame, the cost of 000 eq. 12 (mean over views) of each cheap
likelihood against the dense one at full resolution, over ``--draws`` pixel samples: the mean
difference, its sd across the poses within a draw (the part that changes the weights; a shift
common to every pose does not) and their correlation.
"""

from __future__ import annotations

import argparse

from bench_output import add_output_arguments, pin_threads, write_json


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--coarse", default="80x60", help="the level tracked at, WxH (must divide the image size)")
    parser.add_argument("--samples", type=int, nargs="+", default=[2048], help="sample pixels per view and frame")
    parser.add_argument("--likelihoods", nargs="*", choices=["every", "sampled", "coarse"], default=["every", "sampled", "coarse"],
                        help="which likelihoods to track with (none: only the bias)")
    parser.add_argument("--draws", type=int, default=5, help="pixel samples drawn for the bias measurement")
    parser.add_argument("--views", type=int, default=3)
    parser.add_argument("--methods", nargs="+", default=["mrpf"])
    parser.add_argument("--budget", type=int, default=500)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--particles", type=int, default=200, help="poses for the bias measurement")
    add_output_arguments(parser, plot="draw one view's strata and sample, and sampled against dense costs, here")
    args = parser.parse_args()
    pin_threads(args.threads)
    import json

    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack.camera import default_rig
    from jaxtrack.data import SilhouetteNoise, build_scene, generate_motion, motion_sequence
    from jaxtrack.demo import DEMO_TEST, DEMO_TRAINING, DEMO_VALIDATION
    from jaxtrack.experiment import ExperimentConfig, run_experiment
    from jaxtrack.likelihood import SampledSilhouetteLikelihood, sample_frames
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
    # The bias of each cheap cost against every pixel, around the walk's first frame.
    fine = prepare_test(test[0], "walk", key=key, frames=1, window=None)
    low = prepare_test(test[0], "walk", key=key, frames=1, window=None, resolution=coarse)
    truth = jnp.asarray(fine.initial_pose)
    sigma = jnp.full(truth.shape, 0.1, truth.dtype).at[:3].set(0.03)
    poses = truth + sigma * jax.random.normal(jax.random.fold_in(key, 9), (args.particles, truth.shape[0]), truth.dtype)
    scale = float(fine.likelihood.scale)
    cost_fine = -np.asarray(fine.likelihood(poses, fine.observations[0])) / scale
    cheap = {f"coarse {args.coarse}": [-np.asarray(low.likelihood(poses, low.observations[0])) / scale]}
    sampled = SampledSilhouetteLikelihood.from_dense(fine.likelihood)
    for samples in args.samples:
        draws = [sample_frames(jax.random.key(draw), fine.observations, samples=samples) for draw in range(args.draws)]
        cheap[f"sampled {samples}"] = [-np.asarray(sampled(poses, jax.tree.map(lambda x: x[0], d))) / scale for d in draws]
    for what, costs in cheap.items():
        difference = np.stack(costs) - cost_fine
        rows.append({"what": "cost bias", "likelihood": what, "image": f"{args.width}x{args.height}", "views": args.views,
                     "particles": args.particles, "draws": len(costs), "fine_cost_mean": float(cost_fine.mean()),
                     "fine_cost_sd": float(cost_fine.std()), "bias_mean": float(difference.mean()),
                     "bias_sd_within_draw": float(difference.std(axis=1).mean()),
                     "bias_mean_sd_across_draws": float(difference.mean(axis=1).std()),
                     "correlation": float(np.mean([np.corrcoef(c, cost_fine)[0, 1] for c in costs]))})
        print(json.dumps(rows[-1]), flush=True)
    write_json(rows, args.json)
    if args.plot:
        plot(fine, draws[0], cost_fine, cheap, args.plot)
        print(f"wrote {args.plot}", flush=True)

    settings = [("every", "every pixel", {}), *(("sampled", f"sampled {n}", {"pixel_samples": n}) for n in args.samples),
                ("coarse", f"coarse {args.coarse}", {"resolution": coarse})]
    for kind, label, options in settings:
        if kind not in args.likelihoods:
            continue
        config = ExperimentConfig(methods=tuple(args.methods), budget=args.budget, runs=args.runs, **options)
        results = run_experiment(train, validation, test, config, names=names, progress=False, animations=False)
        for name, per_method in results["sequences"].items():
            for method, r in per_method.items():
                rows.append({"what": "tracking", "sequence": name, "method": method,
                             "likelihood": label, "image": f"{args.width}x{args.height}",
                             "views": args.views, "budget": args.budget, "runs": args.runs,
                             "error_mm_mean": r["error_mm_mean"], "error_mm_per_run": r["error_mm_per_run"],
                             "frames_per_second": r["frames_per_second"], "compile_s": r.get("compile_s")})
                print(json.dumps(rows[-1]), flush=True)
                write_json(rows, args.json)


def plot(scene, sample, cost_fine, cheap, path):
    """Left: view 0's observed silhouette, its four strata and the frame's sample points; right:
    each cheap cost against the dense one over the scattered poses (first draw)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from jaxtrack.likelihood import default_band, default_near, pixel_strata

    observed = np.asarray(scene.observations[0])
    height = observed.shape[-2]
    strata = np.asarray(pixel_strata(observed, default_band(height), default_near(height)))[:, 0]
    colours = np.array([[0.85, 0.3, 0.2], [0.95, 0.85, 0.4], [0.55, 0.75, 0.9], [0.93, 0.93, 0.93]])
    image = np.tensordot(np.moveaxis(strata, 0, -1), colours, axes=1)
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2), gridspec_kw={"width_ratios": [1.25, 1]})
    left.imshow(image, interpolation="nearest")
    u, v = np.asarray(sample.u[0, 0]), np.asarray(sample.v[0, 0])
    left.scatter(u, v, s=1.5, c="k", linewidths=0)
    names = ("outline band (55 %)", "interior (20 %)", "near background (20 %)", "far background (5 %)")
    for colour, name in zip(colours, names):
        left.scatter([], [], color=colour, marker="s", s=40, label=name)
    left.legend(loc="lower right", fontsize=7, framealpha=0.9)
    left.set_title(f"view 0, {observed.shape[-1]}x{height}: strata and the {u.size} sampled pixels of one frame", fontsize=9)
    left.set_axis_off()
    for label, costs in cheap.items():
        right.scatter(cost_fine, costs[0], s=8, alpha=0.7, label=label)
    lo, hi = float(np.min(cost_fine)), float(np.max(cost_fine))
    right.plot([lo, hi], [lo, hi], "k--", lw=0.8, label="equal")
    right.set_xlabel("000 eq. 12 cost, every pixel")
    right.set_ylabel("cheap estimate")
    right.set_title("poses scattered around the truth (first draw)", fontsize=9)
    right.legend(fontsize=8)
    right.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
