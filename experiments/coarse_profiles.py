"""What coarse-to-fine annealing changes in the likelihood (issue #13, item 5): the cost of 000
eq. 12 (mean over views) along one pose entry at a time, at the tracked resolution and at the
coarse level the first annealing layers score (``likelihood.coarsen_likelihood``: silhouettes
block-averaged by ``--factor``, cameras rescaled, the soft edge one coarse pixel wide).

    python experiments/coarse_profiles.py --plot docs/figures/coarse_profiles.png --json profiles.json

Scene: the demo's S2 jog (synthetic, 60 Hz), frame ``--frame``, rendered with
background-subtraction noise into the default 4-view rig at ``--width`` x ``--height``; the
tracker's default capsules. Each profile moves one entry of the true pose (the others stay);
printed per profile and level: the basin's half-width, the smallest offset either side where
the cost has climbed half-way from its minimum to the profile's largest value (a wider basin is
what lets an early layer find the body from further off), and where the minimum lies. Then
the cost of one evaluation of ``--particles`` poses at each level, with the window the
experiment sizes (``window="auto"``): compile time and the median of ``--repeats`` steady-state
calls, and the ratio coarse / tracked.
"""

from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "benchmarks"))  # bench_output, real_motion
from bench_output import add_output_arguments, pin_threads, write_json

PROFILES = (  # (entry, label, unit scale for the axis, half-range in pose units)
    ("x", "root x (mm)", 1000.0, 0.25),
    ("root_yaw", "root yaw (rad)", 1.0, 0.8),
    ("lknee_flex", "left knee flexion (rad)", 1.0, 1.2),
    ("rshoulder_flex", "right shoulder flexion (rad)", 1.0, 1.2),
)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--width", type=int, default=80)
    parser.add_argument("--height", type=int, default=60)
    parser.add_argument("--factor", type=int, default=2, help="the coarse level's reduction factor")
    parser.add_argument("--frame", type=int, default=10)
    parser.add_argument("--points", type=int, default=121, help="offsets per profile")
    parser.add_argument("--particles", type=int, default=100, help="poses per timed evaluation")
    parser.add_argument("--repeats", type=int, default=30, help="timed steady-state calls per level")
    add_output_arguments(parser, plot="draw the profiles here")
    args = parser.parse_args()
    pin_threads(args.threads)
    import json

    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack.body import humaneva_skeleton
    from jaxtrack.camera import default_rig
    from jaxtrack.data import SilhouetteNoise, build_scene, generate_motion
    from jaxtrack.likelihood import coarsen_likelihood
    from jaxtrack.tracking import prepare_test

    key = jax.random.key(0)
    motion = generate_motion("jog", "S2", num_frames=args.frame + 1, fps=60.0, key=key)
    scene = build_scene(jax.random.fold_in(key, 1), motion, default_rig(args.width, args.height), SilhouetteNoise())
    test = prepare_test(scene, "jog", key=key, window=None)
    fine = test.likelihood
    levels = {f"{args.width}x{args.height}": fine,
              f"{args.width // args.factor}x{args.height // args.factor}": coarsen_likelihood(fine, args.factor)}
    observed = test.observations[args.frame]
    truth = jnp.asarray(motion.pose[args.frame], observed.dtype)
    names = ("x", "y", "z", *humaneva_skeleton().dof_names)
    score = jax.jit(lambda lik, poses: -lik(poses, observed) / lik_scale(lik))

    rows = []
    for entry, label, unit, half_range in PROFILES:
        offsets = np.linspace(-half_range, half_range, args.points)
        poses = jnp.tile(truth, (args.points, 1)).at[:, names.index(entry)].add(jnp.asarray(offsets, truth.dtype))
        for level, likelihood in levels.items():
            cost = np.asarray(score(likelihood, poses), np.float64)
            rows.append({"entry": entry, "label": label, "level": level, "offsets": (offsets * unit).tolist(),
                         "cost": cost.tolist(), "basin_half_width": basin_half_width(offsets * unit, cost),
                         "minimum_at": float(offsets[np.argmin(cost)] * unit), "frame": args.frame})
            print(json.dumps({k: v for k, v in rows[-1].items() if k not in ("offsets", "cost")}), flush=True)
    windowed = prepare_test(scene, "jog", key=key).likelihood
    timed = {"tracked": windowed, "coarse": coarsen_likelihood(windowed, args.factor)}
    poses = truth + 0.05 * jax.random.normal(jax.random.fold_in(key, 2), (args.particles, truth.shape[0]), truth.dtype)
    seconds = {}
    for level, likelihood in timed.items():
        compile_s, steady = time_calls(jax.jit(lambda p, lik=likelihood: lik(p, observed)), poses, args.repeats)
        seconds[level] = steady
        rows.append({"timing": level, "particles": args.particles, "compile_s": compile_s, "median_ms": 1e3 * steady})
        print(json.dumps(rows[-1]), flush=True)
    rows.append({"timing": "coarse / tracked", "ratio": seconds["coarse"] / seconds["tracked"]})
    print(json.dumps(rows[-1]), flush=True)
    write_json(rows, args.json)
    if args.plot:
        plot(rows, args.plot)
        print(f"wrote {args.plot}", flush=True)


def time_calls(function, poses, repeats):
    """(compile seconds, median steady-state seconds) of ``function(poses)``."""
    import statistics
    import time

    start = time.perf_counter()
    function(poses).block_until_ready()
    compile_s = time.perf_counter() - start
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function(poses).block_until_ready()
        times.append(time.perf_counter() - start)
    return compile_s, statistics.median(times)


def lik_scale(likelihood):
    """The likelihood's temperature, so that ``-log p / scale`` is eq. 12's mean cost."""
    return likelihood.coarse.scale if hasattr(likelihood, "coarse") else likelihood.scale


def basin_half_width(offsets, cost):
    """Half the width of the interval around the minimum where the cost stays below half-way from
    its minimum to its largest value (one side's edge when the other runs off the profile)."""
    import numpy as np

    level = cost.min() + 0.5 * (cost.max() - cost.min())
    best = int(np.argmin(cost))
    above = np.nonzero(cost >= level)[0]
    left, right = above[above < best], above[above > best]
    edges = [offsets[best] - offsets[left[-1]]] if len(left) else []
    edges += [offsets[right[0]] - offsets[best]] if len(right) else []
    return float(min(edges)) if edges else float("nan")


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in rows if "entry" in r]
    entries = list(dict.fromkeys(r["entry"] for r in rows))
    fig, axes = plt.subplots(1, len(entries), figsize=(3.3 * len(entries), 3.0))
    for ax, entry in zip(axes, entries):
        for r in (r for r in rows if r["entry"] == entry):
            ax.plot(r["offsets"], r["cost"], label=r["level"])
        ax.axvline(0.0, color="0.6", lw=0.8, ls=":")
        ax.set_xlabel(next(r["label"] for r in rows if r["entry"] == entry) + ", from the truth")
    axes[0].set_ylabel("000 eq. 12 cost (mean over views)")
    axes[0].legend(frameon=False, fontsize=8)
    fig.suptitle("The silhouette cost along one pose entry: tracked resolution and the coarse layers' level", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
