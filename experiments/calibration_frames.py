"""Does the body calibration (``likelihood.calibrate_body``) get better with frames spread over
the gait cycle, or with a ground-contact prior? A study for docs/body.md, not a benchmark.

The test subject of ``benchmarks/subject_body.py`` (limbs 10-14 % off the default, capsules 20 %
thicker), its walk rendered by the library's capsules with the default background-subtraction
noise, 4 views at 160x120 (or ``--setting``). Each variant calibrates from the default body with
the floor's one-sided prior (ankles at least 6 cm above the floor) and prints each limb's error
against the subject's true length (mm):

- ``first4``: the first 4 frames, all started at frame 0's pose (what ``prepare_test`` does);
- ``first4-ik``: the first 4 frames, each started at its own pose (inverse kinematics of the
  true joints on the default skeleton: information a user does not have);
- ``spread5-ik``, ``spread8-ik``: 5 or 8 frames spread over the 40 (0.65 s, about one gait
  cycle), each started at its own pose, as a second pass on tracked poses would;
- ``contact``: ``first4`` plus a two-sided ground-contact prior (the lowest ankle of each frame at
  the clearance, sd 2 cm), at 6 cm and at the true clearance.

    taskset -c 0,1 python experiments/calibration_frames.py --json calibration_frames.json
"""

from __future__ import annotations

import argparse
import json
import time
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.body import Skeleton, forward_kinematics
from jaxtrack.camera import default_rig
from jaxtrack.data import SilhouetteNoise, SubjectStyle, build_scene, generate_motion
from jaxtrack.likelihood import AbstractLikelihood, body_of, calibrate_body, make_ground_prior
from jaxtrack.tracking import limb_lengths_of, prepare_test

LIMB_FACTORS = (("spine", 1.12), ("neck", 0.9), ("shoulder", 1.1), ("upper_arm", 0.87), ("forearm", 1.13), ("hip", 0.88),
                ("thigh", 1.12), ("shin", 0.86))


class GroundContact(AbstractLikelihood):
    """``-0.5 ((min ankle height - height) / sd)^2`` per pose: the lowest foot on the floor."""

    reads_observation: ClassVar[bool] = False
    skeleton: Skeleton
    height: float
    sd: float
    ankles: tuple[int, ...] = eqx.field(static=True, default=())

    def log_likelihood(self, poses, observation):
        del observation
        lowest = forward_kinematics(self.skeleton, poses)[:, jnp.asarray(self.ankles), 2].min(axis=1)
        return -0.5 * jnp.square((lowest - self.height) / self.sd)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--setting", default="4x160x120", help="VIEWSxWIDTHxHEIGHT")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    views, width, height = (int(v) for v in args.setting.split("x"))
    key = jax.random.key(0)
    motion = generate_motion("walk", SubjectStyle("X", limb_lengths=LIMB_FACTORS, radius_scale=1.2), num_frames=40, fps=60.0,
                             key=jax.random.fold_in(key, 500))
    scene_seq = build_scene(jax.random.fold_in(key, 600), motion, default_rig(width, height, num_views=views), SilhouetteNoise())
    test = scene_seq.replace(**dict.fromkeys(("pose", "pose_layout", "skeleton_offsets", "capsule_radii")))
    true_lengths = limb_lengths_of(motion.body)
    scene = prepare_test(test, "walk", key=key, body="default")  # the default body; poses solved on it
    skeleton = scene.body.skeleton
    ankles = tuple(skeleton.joint_index(n) for n in ("lankle", "rankle"))
    lowest = np.asarray(scene.truth_joints)[:, list(ankles), 2].min(axis=1)
    floor = make_ground_prior(skeleton, 0.06)
    poses = np.asarray(scene.truth_poses)
    observations = np.asarray(scene.observations)
    first4, spread5, spread8 = [0, 1, 2, 3], list(range(0, 40, 9)), list(range(0, 40, 5))
    variants = [("first4", first4, False, None), ("first4-ik", first4, True, None), ("spread5-ik", spread5, True, None),
                ("spread8-ik", spread8, True, None), ("contact 6 cm", first4, False, 0.06),
                ("contact true", first4, False, float(np.percentile(lowest, 5)))]
    rows = []
    for label, frames, own_pose, contact in variants:
        likelihood = scene.likelihood + floor
        if contact is not None:
            likelihood = likelihood + GroundContact(skeleton=skeleton, height=contact, sd=0.02, ankles=ankles)
        start = poses[frames] if own_pose else np.repeat(poses[:1], len(frames), axis=0)
        began = time.perf_counter()
        fitted, _, report = calibrate_body(likelihood, start, jnp.asarray(observations[frames]))
        lengths = limb_lengths_of(body_of(fitted))
        errors = {k: round(1000 * (lengths[k] - true_lengths[k]), 1) for k in lengths}
        rows.append({"variant": label, "frames": frames, "errors_mm": errors, "cost_after": report.cost_after,
                     "seconds": time.perf_counter() - began})
        print(f"{label:>14}: " + ", ".join(f"{k} {v:+.0f}" for k, v in errors.items()) + f"  (cost {report.cost_after:.3f})",
              flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
