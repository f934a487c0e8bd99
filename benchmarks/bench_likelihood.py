"""Silhouette likelihood speed: fast (windowed) vs dense reference, compile and steady state.

Usage (pin threads to the cores you have; the figure quoted in the README came from this):

    taskset -c 0,1 python benchmarks/bench_likelihood.py --particles 500 --repeats 30

Scene: the embedded synthetic walk (subject S1) seen by the default 4-camera rig at 80x60
with background-subtraction noise; particles are Gaussian perturbations of the true pose
(0.1 rad on angles, 3 cm on the root). Prints one JSON line per evaluation mode.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--particles", type=int, default=500)
    parser.add_argument("--width", type=int, default=80)
    parser.add_argument("--height", type=int, default=60)
    parser.add_argument("--frames", type=int, default=30, help="frames of the scene cycled through")
    parser.add_argument("--repeats", type=int, default=60, help="timed calls per mode")
    parser.add_argument("--threads", type=int, default=os.cpu_count())
    args = parser.parse_args()
    os.environ.setdefault(
        "XLA_FLAGS", f"--xla_cpu_multi_thread_eigen=true intra_op_parallelism_threads={args.threads}"
    )
    os.environ.setdefault("OMP_NUM_THREADS", str(args.threads))

    import equinox as eqx
    import jax
    import jax.numpy as jnp

    from jaxtrack.camera import default_rig
    from jaxtrack.data import SilhouetteNoise, build_scene, generate_motion
    from jaxtrack.likelihood import check_silhouettes, make_silhouette_likelihood

    key = jax.random.key(0)
    motion = generate_motion("walk", "S1", num_frames=args.frames, fps=60.0, key=key)
    rig = default_rig(args.width, args.height)
    scene = build_scene(jax.random.fold_in(key, 1), motion, rig, SilhouetteNoise())
    observed = jnp.asarray(check_silhouettes(scene.silhouettes, rig))
    truth = jnp.asarray(scene.pose, jnp.float32)
    sigma = jnp.full(truth.shape[1:], 0.1, jnp.float32).at[:3].set(0.03)
    noise = jax.random.normal(jax.random.fold_in(key, 2), (args.frames, args.particles, truth.shape[1]))
    particles = truth[:, None] + sigma * noise

    fast = make_silhouette_likelihood(scene.body(), rig, silhouettes=observed)
    dense = make_silhouette_likelihood(scene.body(), rig, window=None)
    score = eqx.filter_jit(lambda lik, poses, obs: lik.statistics(poses, obs))

    modes = {"dense": dense, "windowed": fast}
    compile_s, times, overflow = {}, {m: [] for m in modes}, dict.fromkeys(modes, 0)
    for name, lik in modes.items():
        start = time.perf_counter()
        jax.block_until_ready(score(lik, particles[0], observed[:, 0]))
        compile_s[name] = time.perf_counter() - start
    # Interleave the modes in rounds so machine noise hits both alike; report medians.
    for r in range(args.repeats):
        t = r % args.frames
        for name, lik in modes.items():
            start = time.perf_counter()
            out = jax.block_until_ready(score(lik, particles[t], observed[:, t]))
            times[name].append(time.perf_counter() - start)
            overflow[name] += int(out[2])
    results = {}
    for name, lik in modes.items():
        median = statistics.median(times[name])
        results[name] = median
        print(
            json.dumps(
                {
                    "mode": name,
                    "window": lik.window,
                    "particles": args.particles,
                    "views": rig.num_views,
                    "image": f"{args.width}x{args.height}",
                    "threads": args.threads,
                    "compile_s": round(compile_s[name], 3),
                    "median_ms": round(1000 * median, 2),
                    "p10_ms": round(1000 * sorted(times[name])[len(times[name]) // 10], 2),
                    "particle_views_per_s": round(args.particles * rig.num_views / median),
                    "overflowing_particle_views": overflow[name],
                    "device": jax.devices()[0].device_kind,
                    "cpu": platform.processor() or platform.machine(),
                }
            )
        )
    # Same particles, both modes: the fast path must agree with the reference.
    a = score(dense, particles[0], observed[:, 0])[0]
    b = score(fast, particles[0], observed[:, 0])[0]
    print(json.dumps({"speedup_dense_over_windowed": round(results["dense"] / results["windowed"], 2),
                      "max_rel_diff": float(jnp.max(jnp.abs(a - b) / jnp.abs(a)))}))

    # As a filter uses it: every frame's likelihood inside one jitted lax.scan over the frames
    # (no per-call dispatch); per-frame time = median total / frames.
    frames_first = jnp.moveaxis(observed, 1, 0)

    @eqx.filter_jit
    def scanned(lik, particles, frames):
        return jax.lax.scan(lambda c, xs: (c, lik.log_likelihood(*xs)), 0, (particles, frames))[1]

    for name, lik in modes.items():
        start = time.perf_counter()
        jax.block_until_ready(scanned(lik, particles, frames_first))
        first = time.perf_counter() - start
        totals = []
        for _ in range(max(3, args.repeats // args.frames)):
            start = time.perf_counter()
            jax.block_until_ready(scanned(lik, particles, frames_first))
            totals.append(time.perf_counter() - start)
        per_frame = statistics.median(totals) / args.frames
        print(json.dumps({"mode": f"{name} in lax.scan", "window": lik.window, "frames": args.frames,
                          "compile_s": round(first - per_frame * args.frames, 3),
                          "median_ms_per_frame": round(1000 * per_frame, 2),
                          "particle_views_per_s": round(args.particles * rig.num_views / per_frame)}))


if __name__ == "__main__":
    main()
