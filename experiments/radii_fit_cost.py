"""What the capsule radii fit of a joints-only file costs, and what stopping it early loses
(docs/motion_files.md, "The radii's cost").

On the test file of ``benchmarks/bench_experiment_size.py`` (a 320x240 walk drawn by the solid
body, 3 views, stripped to joints and silhouettes; made there with ``--scene``), the fit of
``tracking.prepare_test`` (``likelihood.fit_radii`` at the joints' poses of frames spread over the
take, the floor prior's band left out) with several settings: frames, sampled pixels per view and
frame (or every pixel), Adam's step, the stopping rule. Each row: the steps taken, the time of a
second call (compiled), and every radius against a 1000-step fit on 12 frames' 2048 pixels, the
clavicles apart (the silhouettes do not see them).

    taskset -c 0,1 python benchmarks/bench_experiment_size.py --scene scene.npz --repeats 1
    taskset -c 0,1 python experiments/radii_fit_cost.py --scene scene.npz [--dense]
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.io import load_sequence
from jaxtrack.likelihood import (
    RADII_LEARNING_RATE,
    RADII_STOP_TOLERANCE,
    SampledSilhouetteLikelihood,
    fit_radii,
    make_ground_prior,
    sample_frames,
)
from jaxtrack.tracking import CALIBRATION_CLEARANCE, RADII_FRAMES, prepare_test, spread_frames

REFERENCE = (RADII_FRAMES, 2048, 0.05, None, 1000)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", required=True, help="the benchmark's drawn test file")
    parser.add_argument("--dense", action="store_true", help="also every pixel, 300 steps (what the fit did before: minutes)")
    args = parser.parse_args()
    drawn = load_sequence(args.scene)
    frames = drawn.num_frames
    scene = prepare_test(drawn, "walk", key=jax.random.key(0), fit_radii=False, frames=frames)
    floor = make_ground_prior(scene.body.skeleton, CALIBRATION_CLEARANCE)
    names = scene.body.capsule_names
    seen = [i for i, n in enumerate(names) if "clavicle" not in n]
    rows = [REFERENCE, (RADII_FRAMES, 2048, 0.05, None, 300), (RADII_FRAMES, 2048, 0.05, RADII_STOP_TOLERANCE, 300),
            (RADII_FRAMES, 2048, RADII_LEARNING_RATE, RADII_STOP_TOLERANCE, 300), (8, 2048, RADII_LEARNING_RATE, RADII_STOP_TOLERANCE, 300),
            (RADII_FRAMES, 1024, RADII_LEARNING_RATE, RADII_STOP_TOLERANCE, 300)]
    if args.dense:
        rows.append((RADII_FRAMES, None, 0.05, None, 300))
    reference = None
    for count, samples, rate, tolerance, steps in rows:
        picks = spread_frames(frames, count)
        observations = jnp.asarray(np.asarray(scene.observations)[picks])
        likelihood = scene.likelihood
        if samples is not None:  # as the scene fits them above 160x120: on the pixels the tracker scores
            likelihood = SampledSilhouetteLikelihood.from_dense(scene.likelihood)
            observations = sample_frames(jax.random.key(9), observations, samples=samples)
        for _ in range(2 if samples is not None else 1):  # the second call compiled (every pixel: one call, minutes)
            started = time.perf_counter()
            _, report = fit_radii(likelihood + floor, np.asarray(scene.truth_poses)[picks], observations,
                                  stop_tolerance=tolerance, steps=steps, learning_rate=rate)
            seconds = time.perf_counter() - started
        radii = report.radii_after
        reference = radii if reference is None else reference
        off = 100 * (radii / reference - 1)
        worst = int(np.argmax(np.abs(off[seen])))
        print(f"{count:2d} frames, {'every' if samples is None else samples} pixels, step {rate:g}, "
              f"{'no stopping' if tolerance is None else f'stopping at {tolerance:g}'}: {len(report.trace)} steps, {seconds:.1f} s; "
              f"largest radius off the 1000-step fit {abs(off[seen][worst]):.1f} % ({names[seen[worst]]}), "
              f"clavicles {off[names.index('lclavicle')]:+.0f} %", flush=True)


if __name__ == "__main__":
    main()
