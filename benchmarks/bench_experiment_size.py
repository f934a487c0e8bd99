"""What a larger image costs a whole experiment on a joints-only file: the same run at 320x240
and at 80x60, stage by stage (the test files read and their scenes built, which at 45 pixels of
person or more fits the capsule radii; the manifolds and dynamics fitted; the tracking), and the
radii fit's steps and time. The target (issue: the radii fit costs what it should): the whole
experiment at 320x240 within 1.5x of the same run at 80x60.

    taskset -c 0,1 python benchmarks/bench_experiment_size.py --json experiment_size.json

Inputs, made here (nothing read from disk): synthetic walks of subject S1 as the training and
validation files; the test file a 200-frame walk of a subject whose limbs are 10-14 % off the
default (``data.SubjectStyle``), drawn at the largest size by ``data.SolidBody`` (a body that is
not the tracker's) in ``--views`` noisy views of the default rig, then stripped to its joints,
cameras and silhouettes (a HumanEva-style file: the body is fitted to its joints and the radii to
its silhouettes); the smaller sizes block-average those silhouettes (``Sequence.resized``). Each
size runs in a fresh process of its own, ``--repeats`` times: the first includes compiling, the
median of the others is the steady state.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

from bench_output import add_output_arguments, pin_threads, write_json

LIMB_FACTORS = (("spine", 1.12), ("neck", 0.9), ("shoulder", 1.1), ("upper_arm", 0.87), ("forearm", 1.13), ("hip", 0.88),
                ("thigh", 1.12), ("shin", 0.86))
JOINTS_ONLY = dict.fromkeys(("pose", "pose_layout", "skeleton_offsets", "capsule_radii"))


def _run_size(args, test_path: str, size: str) -> list[dict]:
    """Every repeat of the experiment at ``size`` (run in a fresh process: ``--child``)."""
    import jax
    import jax.numpy as jnp

    from jaxtrack.data import generate_motion, motion_sequence
    from jaxtrack.experiment import ExperimentConfig, fit_methods, new_results, prepare_inputs, track_methods
    from jaxtrack.io import load_sequence

    width, height = (int(v) for v in size.split("x"))
    walk = lambda frames, seed: generate_motion("walk", "S1", num_frames=frames, fps=60.0,  # noqa: E731
                                                key=jax.random.key(seed), dtype=jnp.float64)
    train = [motion_sequence(walk(120, 1)).replace(**JOINTS_ONLY)]
    validation = [motion_sequence(walk(60, 2)).replace(**JOINTS_ONLY)]
    drawn = load_sequence(test_path)
    test = drawn if tuple(drawn.image_size[0]) == (width, height) else drawn.resized(width, height)
    config = ExperimentConfig(methods=tuple(args.methods), runs=args.runs, budget=args.budget, seed=0)
    quiet = lambda *a, **k: None  # noqa: E731
    rows = []
    for repeat in range(args.repeats):
        results = new_results(config)
        stages = {}
        clock = time.perf_counter()
        inputs = prepare_inputs(train, validation, [test], config, results,
                                names={"train": ["train"], "validation": ["val"], "test": ["walk"]}, say=quiet)
        stages["files and scenes"] = time.perf_counter() - clock
        clock = time.perf_counter()
        fitted = fit_methods(inputs, config, results, progress=False, say=quiet)
        stages["manifolds and dynamics"] = time.perf_counter() - clock
        clock = time.perf_counter()
        track_methods(inputs, fitted, config, results, say=quiet)
        stages["tracking"] = time.perf_counter() - clock
        radii = results["shape_calibration"].get("walk")
        error = {m: round(r["error_mm_mean"], 1) for m, r in results["sequences"]["walk"].items()}
        rows.append({"size": size, "repeat": repeat, "total_s": sum(stages.values()), "stages_s": stages,
                     "radii_fit_steps": None if radii is None else radii.get("steps"), "error_mm": error})
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", nargs="+", default=["320x240", "80x60"], help="image sizes WxH, the first the largest")
    parser.add_argument("--frames", type=int, default=200)
    parser.add_argument("--views", type=int, default=3)
    parser.add_argument("--methods", nargs="+", default=["mrpf"])
    parser.add_argument("--runs", type=int, default=1)
    parser.add_argument("--budget", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--scene", default="bench_experiment_size_scene.npz",
                        help="the drawn test file: made (minutes at 320x240) where it does not exist, read where it does")
    parser.add_argument("--child", metavar="SIZE", help=argparse.SUPPRESS)
    add_output_arguments(parser)
    args = parser.parse_args()
    pin_threads(args.threads)
    if args.child:  # one size in this fresh process: its rows as JSON on the last line
        print(json.dumps(_run_size(args, args.scene, args.child)))
        return

    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack.camera import default_rig
    from jaxtrack.data import SilhouetteNoise, SolidBody, SubjectStyle, build_scene, generate_motion
    from jaxtrack.io import save_sequence

    largest = tuple(int(v) for v in args.sizes[0].split("x"))
    if not os.path.exists(args.scene):
        person = generate_motion("walk", SubjectStyle("X", limb_lengths=LIMB_FACTORS), num_frames=args.frames, fps=60.0,
                                 key=jax.random.key(3), dtype=jnp.float64)
        started = time.perf_counter()
        drawn = build_scene(jax.random.key(4), person, default_rig(*largest, num_views=args.views, dtype=jnp.float64),
                            SilhouetteNoise(), solid=SolidBody(person.body.skeleton))
        save_sequence(args.scene, drawn.replace(**JOINTS_ONLY))
        print(f"test scene drawn at {args.sizes[0]} in {time.perf_counter() - started:.0f} s: {args.scene}")
    rows = []
    for size in args.sizes:  # each in a fresh process: its compiling counted, none shared with another size
        command = [sys.executable, __file__, "--child", size, "--scene", args.scene, "--threads", str(args.threads),
                   "--methods", *args.methods, "--runs", str(args.runs), "--budget", str(args.budget), "--repeats", str(args.repeats)]
        out = subprocess.run(command, check=True, capture_output=True, text=True).stdout
        for row in json.loads(out.strip().splitlines()[-1]):
            rows.append(row)
            print(f"{size} run {row['repeat']}: {row['total_s']:.1f} s (" + ", ".join(f"{k} {v:.1f}" for k, v in row["stages_s"].items())
                  + f"); radii fit {'not run' if row['radii_fit_steps'] is None else str(row['radii_fit_steps']) + ' steps'}; "
                  f"error {row['error_mm']}")
        write_json(rows, args.json)
    for label, pick in (("first run (compiling)", lambda r: r["repeat"] == 0), ("steady", lambda r: r["repeat"] > 0)):
        totals = {s: np.median([r["total_s"] for r in rows if r["size"] == s and pick(r)] or [np.nan]) for s in args.sizes}
        print(f"{label}: " + ", ".join(f"{s} {t:.1f} s" for s, t in totals.items())
              + f"; {args.sizes[0]} over {args.sizes[-1]}: {totals[args.sizes[0]] / totals[args.sizes[-1]]:.2f}x")


if __name__ == "__main__":
    main()
