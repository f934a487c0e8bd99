"""Do 2-D keypoints place the limbs that silhouettes alone cannot? The body calibration
(``likelihood.calibrate_body``) of ``benchmarks/subject_body.py``'s test subject (limbs 10-14 %
off the default, capsules 20 % thicker), from the default body, on its walk's first 4 frames in
4 views at 160x120 (or ``--setting``), rendered by the tracker's capsules or by ``data.SolidBody``
(``--renderer solid``: ellipsoids pinched at the joints, feet, an egg-shaped head; ``solid-joints``:
the same with the masses round the joints, ``SolidBody(joints=True)``), with

- ``silhouettes``: the rendered noisy silhouettes (what ``prepare_test`` calibrates from);
- ``keypoints``: the true joints projected into every view, plus N(0, ``--noise`` px) and
  ``--dropped`` of them missing (what a 2-D pose detector gives, at its better); ``calibrate_body``
  keeps them untempered (its ``data_weight`` of 30 undoes the silhouettes' tempering, which the
  keypoints do not have; at 30 times their weight the fit followed the noise, 1 px of which is 3 cm
  here);
- ``both``: the two summed (``ObservationPart`` on a dict observation).

Each starts from frame 0's pose (solved on the default body) and keeps the feet out of the
floor; prints each limb's error against the subject's true length (mm) and the start error.
A study for docs/body.md, not a benchmark.

    taskset -c 0,1 python experiments/keypoint_calibration.py --json keypoint_calibration.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "benchmarks"))  # subject_body
from subject_body import LIMB_FACTORS, RADIUS_FACTOR

from jaxtrack.body import forward_kinematics
from jaxtrack.camera import default_rig, project_points
from jaxtrack.data import SilhouetteNoise, SolidBody, SubjectStyle, build_scene, generate_motion
from jaxtrack.errors import ConfigurationError
from jaxtrack.likelihood import (
    ObservationPart,
    body_of,
    calibrate_body,
    make_ground_prior,
    make_keypoint_likelihood,
    with_body,
)
from jaxtrack.tracking import limb_lengths_of, prepare_test

FRAMES = 4


def detections(key, joints, rig, noise_px, dropped):
    """(F, C, 15, 3) keypoints of (F, 15, 3) world joints: projected, noisy, some missing."""
    uv, _, _ = project_points(rig, jnp.asarray(joints, jnp.float32))  # (F, 15, C, 2)
    uv = np.swapaxes(np.asarray(uv, np.float64), 1, 2)
    noise_key, drop_key = jax.random.split(key)
    uv = uv + noise_px * np.asarray(jax.random.normal(noise_key, uv.shape))
    seen = np.asarray(jax.random.uniform(drop_key, uv.shape[:-1])) >= dropped
    return np.concatenate([uv, seen[..., None].astype(np.float64)], axis=-1)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--setting", default="4x160x120", help="VIEWSxWIDTHxHEIGHT")
    parser.add_argument("--noise", type=float, default=1.0, help="keypoint noise, pixels (sd); the likelihood's sigma is the same")
    parser.add_argument("--dropped", type=float, default=0.1, help="fraction of keypoints missing")
    parser.add_argument("--renderer", choices=("capsules", "solid", "solid-joints"), default="capsules", help="what draws the test scene")
    parser.add_argument("--variants", nargs="+", choices=("silhouettes", "keypoints", "both"), default=("silhouettes", "keypoints", "both"))
    parser.add_argument("--torso-top", type=float, default=1.0,
                        help="the tracker's torso capsule ends at this fraction of the pelvis-thorax bone (default 1: at the thorax)")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    views, width, height = (int(v) for v in args.setting.split("x"))
    key = jax.random.key(0)
    motion = generate_motion("walk", SubjectStyle("X", limb_lengths=LIMB_FACTORS, radius_scale=RADIUS_FACTOR), num_frames=40,
                             fps=60.0, key=jax.random.fold_in(key, 500))
    rig = default_rig(width, height, num_views=views)
    solid = None if args.renderer == "capsules" else SolidBody(motion.body.skeleton, joints=args.renderer == "solid-joints")
    scene_seq = build_scene(jax.random.fold_in(key, 600), motion, rig, SilhouetteNoise(), solid=solid)
    test = scene_seq.replace(**dict.fromkeys(("pose", "pose_layout", "skeleton_offsets", "capsule_radii")))
    true_lengths = limb_lengths_of(motion.body)
    scene = prepare_test(test, "walk", key=key, body="default", pixel_samples=None)
    if args.torso_top != 1.0:  # a torso whose dome ends below the thorax, as a person's shoulders do
        spans = list(scene.body.capsule_span)
        spans[scene.body.capsule_names.index("torso")] = (0.0, args.torso_top)
        torso = dataclasses.replace(scene.body, capsule_span=tuple(spans))
        scene = dataclasses.replace(scene, likelihood=with_body(scene.likelihood, torso))
    true_joints = np.asarray(forward_kinematics(motion.body.skeleton, jnp.asarray(motion.pose[:FRAMES], jnp.float32)))
    keypoints = detections(jax.random.fold_in(key, 700), true_joints, scene.likelihood.rig, args.noise, args.dropped)
    silhouettes = np.asarray(scene.observations[:FRAMES])
    floor = make_ground_prior(scene.body.skeleton, 0.06)
    points = make_keypoint_likelihood(scene.body, scene.likelihood.rig, sigma_px=max(args.noise, 1.0))
    variants = {  # label: likelihood, observations
        "silhouettes": (scene.likelihood + floor, jnp.asarray(silhouettes)),
        "keypoints": (points + floor, jnp.asarray(keypoints, jnp.float32)),
        "both": (ObservationPart(scene.likelihood, "silhouettes") + ObservationPart(points, "keypoints") + floor,
                 {"silhouettes": jnp.asarray(silhouettes), "keypoints": jnp.asarray(keypoints, jnp.float32)}),
    }
    start = np.repeat(np.asarray(scene.truth_poses)[:1], FRAMES, axis=0)
    rows = []
    for label in args.variants:
        likelihood, observations = variants[label]
        began = time.perf_counter()
        try:
            fitted, poses, _ = calibrate_body(likelihood, start, observations)
        except ConfigurationError as err:  # not converged: reported, as prepare_test would refuse it
            rows.append({"variant": label, "refused": str(err)})
            print(f"{label:>12}: refused: {err}", flush=True)
            continue
        body = body_of(fitted)
        lengths = limb_lengths_of(body)
        errors = {k: round(1000 * (lengths[k] - true_lengths[k]), 1) for k in lengths}
        start_error = 1000 * float(np.mean(np.linalg.norm(
            np.asarray(forward_kinematics(body.skeleton, jnp.asarray(poses[0], jnp.float32))) - true_joints[0], axis=-1)))
        rows.append({"variant": label, "errors_mm": errors, "max_abs_mm": max(abs(v) for v in errors.values()),
                     "frame0_error_mm": round(start_error, 1), "seconds": round(time.perf_counter() - began, 1)})
        print(f"{label:>12}: " + ", ".join(f"{k} {v:+.0f}" for k, v in errors.items())
              + f"; worst {rows[-1]['max_abs_mm']:.0f} mm; frame 0 {start_error:.1f} mm", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"setting": args.setting, "renderer": args.renderer, "torso_top": args.torso_top,
                       "noise_px": args.noise, "dropped": args.dropped,
                       "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
