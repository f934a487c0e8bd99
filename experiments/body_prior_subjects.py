"""What centres the body calibration's prior: the default body's proportions, or the motion model's
subject's (docs/body.md, "The motion model's subject").

For each film (a folder ``jaxtrack scene --rgb --video`` wrote: ``truth.npz`` and the detector-like
``keypoints.npz``), the body is calibrated from the first ``--frames`` frames' 2-D keypoints alone,
started automatically, as ``jaxtrack track --body calibrate --likelihood keypoints`` prepares a scene
(``tracking.prepare_test``; no ground truth read), once per ``--priors`` entry
(``tracking.CALIBRATION_PRIORS``: ``motion``, the validation take's proportions and clavicle posture;
``proportions``, its proportions with the clavicles at rest; ``default``, the default body's, as
before 2026-12-06). Prints each limb's error (mm) against the film's true limb lengths (the median
segment lengths of its joints, ``body.fit_limb_lengths``) and their mean absolute value.

    # the films: CMU 35 (the model's subject), 07 and 16 (other CMU subjects), HDM05's bd (another lab)
    jaxtrack convert ../shared/data/multi_subject/cmu_07/07_01-walk.amc /tmp/cmu/07_01.npz --source-fps 120 --fps 60
    jaxtrack scene /tmp/cmu/07_01.npz --rgb --video /tmp/films/07_01 --frames 60 --width 320 --height 240 --views 4
    taskset -c 0,1 python experiments/body_prior_subjects.py /tmp/video_study/walk.eqx /tmp/cmu/35_03.npz \\
        /tmp/video_study/tune_320x240_4 /tmp/films/07_01 /tmp/films/16_24 /tmp/films/bd_jog [--json PATH]
"""

import argparse
import json
import os

import jax
import numpy as np

from jaxtrack.body import LIMB_SEGMENTS, fit_limb_lengths
from jaxtrack.io import load_keypoints, load_sequence
from jaxtrack.manifold import load_model
from jaxtrack.tracking import CALIBRATION_PRIORS, TrackingSpec, limb_lengths_of, motion_clearance, prepare_test, subject_body


def calibrated_lengths(film: str, manifold, validation, prior: str, frames: int) -> dict[str, float]:
    """The limb lengths (metres) ``prepare_test`` calibrates from the film's keypoints alone."""
    key = jax.random.key(0)
    donor = subject_body(validation, "the validation sequence", key=key)
    layout = [str(n) for n in donor.body.skeleton.pose_layout]
    clearance = motion_clearance([validation], [donor.poses], skeletons=[donor.body.skeleton])
    truth = load_sequence(os.path.join(film, "truth.npz"))
    sequence = truth.replace(keypoints2d=load_keypoints(os.path.join(film, "keypoints.npz"))[0], skeleton_offsets=None,
                             capsule_radii=None, pose=None, pose_layout=None, joints3d=None, subject=None)
    options = TrackingSpec(likelihood="keypoints", body="calibrate", start="auto").scene_options()
    scene = prepare_test(sequence, os.path.basename(film), key=key, frames=frames, calibration_frames=frames, start="auto",
                         start_model=manifold, root_height=float(np.mean(donor.poses[:, layout.index("root_z")])),
                         ground_clearance=clearance, donors=[("the validation sequence", donor, validation.subject)],
                         calibration_prior=prior, **options)
    return limb_lengths_of(scene.body)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("model")
    parser.add_argument("validation")
    parser.add_argument("films", nargs="+")
    parser.add_argument("--priors", nargs="+", default=list(CALIBRATION_PRIORS), choices=CALIBRATION_PRIORS)
    parser.add_argument("--frames", type=int, default=4)
    parser.add_argument("--json")
    args = parser.parse_args()
    manifold, _ = load_model(args.model)
    validation = load_sequence(args.validation)
    limbs = list(LIMB_SEGMENTS)
    rows = []
    print("| film | prior | " + " | ".join(limbs) + " | mean abs |")
    print("|---|---|" + "---:|" * (len(limbs) + 1))
    for film in args.films:
        true = fit_limb_lengths(load_sequence(os.path.join(film, "truth.npz")).joints3d)
        print(f"| {os.path.basename(film)} | true (mm) | " + " | ".join(f"{1000 * true[n]:.0f}" for n in limbs) + " | |")
        for prior in args.priors:
            lengths = calibrated_lengths(film, manifold, validation, prior, args.frames)
            errors = [1000 * (lengths[n] - true[n]) for n in limbs]
            print(f"| {os.path.basename(film)} | {prior} | " + " | ".join(f"{e:+.0f}" for e in errors)
                  + f" | {np.mean(np.abs(errors)):.1f} |", flush=True)
            rows.append({"film": film, "prior": prior, "errors_mm": dict(zip(limbs, errors)),
                         "mean_abs_mm": float(np.mean(np.abs(errors)))})
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"frames": args.frames, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
