"""How the silhouette likelihood's cost grows with particles, views and pixels, as the filters
use it (every frame inside one jitted ``lax.scan``), and the peak memory of a large batch.

    taskset -c 0,1 python benchmarks/bench_scaling.py --json scaling.json --plot docs/figures/likelihood_scaling.png

Three sweeps from a base of 500 particles, 4 views, 80x60 (float32, the windowed likelihood):
particles 100..2000; views 1..4 (the default rig's first cameras); images 80x60 .. 640x480 (the
same cameras, intrinsics rescaled), with every pixel of the window and with ``--samples``
stratified sample pixels per view (``SampledSilhouetteLikelihood``; the per-frame draw is
made once before the scan, as ``prepare_test`` does, and not timed). Each point: compile time (``jit(...).lower(...).compile()``) and
the median per-frame time of ``--repeats`` scans over ``--frames`` frames. Peak memory for
``--memory-particles`` particles x 4 views at 160x120: XLA's own count for the compiled scan
(arguments, outputs and temporaries) and the process's peak resident set.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import time

from bench_output import add_output_arguments, pin_threads, write_json


def scene(width, height, views, frames, key):
    import jax

    from jaxtrack.camera import default_rig
    from jaxtrack.data import SilhouetteNoise, build_scene, generate_motion

    motion = generate_motion("walk", "S1", num_frames=frames, fps=60.0, key=key)
    rig = default_rig(width, height, num_views=4)
    if views < 4:
        rig = rig.view(0) if views == 1 else _first_views(rig, views)
    return build_scene(jax.random.fold_in(key, 1), motion, rig, SilhouetteNoise()), rig


def _first_views(rig, views):
    from jaxtrack.camera import CameraRig

    return CameraRig(K=rig.K[:views], R=rig.R[:views], t=rig.t[:views], dist=rig.dist[:views],
                     image_size=rig.image_size[:views], names=rig.names[:views])


def measure(particles, views, width, height, frames, repeats, key, samples=None):
    """Compile seconds, median seconds per frame, and XLA's memory count (bytes) of the scan
    (``samples``: the likelihood on that many sample pixels per view instead)."""
    import jax
    import jax.numpy as jnp

    from jaxtrack.likelihood import SampledSilhouetteLikelihood, check_silhouettes, make_silhouette_likelihood, sample_frames

    built, rig = scene(width, height, views, frames, key)
    observed = jnp.moveaxis(jnp.asarray(check_silhouettes(built.silhouettes, rig)), 1, 0)  # (T, C, H, W)
    truth = jnp.asarray(built.pose, jnp.float32)
    sigma = jnp.full(truth.shape[1:], 0.1, jnp.float32).at[:3].set(0.03)
    poses = truth[:, None] + sigma * jax.random.normal(jax.random.fold_in(key, 2), (frames, particles, truth.shape[1]))
    likelihood = make_silhouette_likelihood(built.body(), rig, silhouettes=jnp.moveaxis(observed, 0, 1))
    if samples is not None:
        likelihood = SampledSilhouetteLikelihood.from_dense(likelihood)
        observed = jax.block_until_ready(sample_frames(jax.random.fold_in(key, 3), observed, samples=samples))

    def scanned(poses, frames):
        return jax.lax.scan(lambda c, xs: (c, likelihood.log_likelihood(*xs)), 0, (poses, frames))[1]

    start = time.perf_counter()
    compiled = jax.jit(scanned).lower(poses, observed).compile()
    compile_s = time.perf_counter() - start
    memory = compiled.memory_analysis()
    peak_bytes = None
    if memory is not None:
        peak_bytes = int(memory.argument_size_in_bytes + memory.output_size_in_bytes + memory.temp_size_in_bytes)
    jax.block_until_ready(compiled(poses, observed))
    totals = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(compiled(poses, observed))
        totals.append(time.perf_counter() - start)
    per_frame = statistics.median(totals) / frames
    return {"particles": particles, "views": views, "image": f"{width}x{height}", "pixels": width * height,
            "window": list(likelihood.window) if getattr(likelihood, "window", None) else None, "samples": samples,
            "compile_s": compile_s, "ms_per_frame": 1000 * per_frame,
            "particle_views_per_s": particles * views / per_frame, "xla_bytes": peak_bytes}


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    labels = ("particles (4 views, 80x60)", "views (500 particles, 80x60)", "pixels per view (500 particles, 4 views)")
    for ax, sweep, label in zip(axes, ("particles", "views", "pixels"), labels):
        for name in (sweep, sweep + " sampled"):
            chosen = [r for r in rows if r["sweep"] == name]
            if not chosen:
                continue
            xs, ys = zip(*sorted((r[sweep], r["ms_per_frame"]) for r in chosen))
            samples = chosen[0].get("samples")
            ax.plot(xs, ys, "o-", label="every pixel of the window" if samples is None else f"{samples} sample pixels per view")
        ax.set_xlabel(label)
        ax.set_ylabel("ms per frame (in lax.scan)")
        if sweep != "pixels":
            ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        if sweep == "pixels":
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.legend(fontsize=8)
            for r in rows:
                if r["sweep"] == "pixels":
                    ax.annotate(r["image"], (r["pixels"], r["ms_per_frame"]), textcoords="offset points", xytext=(4, -10), fontsize=8)
    fig.suptitle("Silhouette likelihood, float32, 2 CPU cores: cost per frame")
    fig.tight_layout()
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    fig.savefig(path, dpi=110)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--particles", type=int, nargs="+", default=[100, 250, 500, 1000, 2000])
    parser.add_argument("--views", type=int, nargs="+", default=[1, 2, 3, 4])
    parser.add_argument("--images", nargs="+", default=["80x60", "160x120", "320x240", "640x480"])
    parser.add_argument("--samples", type=int, default=2048, help="sample pixels per view for the sampled pixel sweep")
    parser.add_argument("--memory-particles", type=int, default=2000)
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=3)
    add_output_arguments(parser, plot="draw the three sweeps here")
    args = parser.parse_args()
    pin_threads(args.threads)
    import json

    import jax

    key = jax.random.key(0)
    rows = []

    def record(sweep, row):
        row["sweep"] = sweep
        rows.append(row)
        print(json.dumps(row), flush=True)
        write_json(rows, args.json)

    for n in args.particles:
        record("particles", measure(n, 4, 80, 60, args.frames, args.repeats, key))
    for views in args.views:
        record("views", measure(500, views, 80, 60, args.frames, args.repeats, key))
    for image in args.images:
        width, height = (int(v) for v in image.split("x"))
        record("pixels", measure(500, 4, width, height, args.frames, args.repeats, key))
        record("pixels sampled", measure(500, 4, width, height, args.frames, args.repeats, key, samples=args.samples))
    memory = measure(args.memory_particles, 4, 160, 120, args.frames, args.repeats, key)
    memory["peak_rss_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # kB on Linux
    record("memory", memory)
    if args.plot:
        plot(rows, args.plot)
        print(f"wrote {args.plot}")


if __name__ == "__main__":
    main()
