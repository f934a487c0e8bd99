"""A person's own posture: does removing each subject's mean joint angles carry a manifold across people?

Issue #46's first suggestion, "poses normalised per subject (joint angles relative to the
subject's own mean posture)", on a leave-one-subject-out protocol (``--protocol walk-loso``, the
default, or ``jog-loso``: ``jaxtrack protocol``'s folds, 3 noisy 80x60 views of the solid body,
budget 500). For each fold:

- **centred training**: each training and validation take's joint angles shifted by the pooled
  mean ``P`` of the training takes less its own subject's mean, so every training subject walks
  about one posture and the manifold learns the gait, not the people;
- **the test person's offset** ``m = M - P``, ``M`` the person's mean joint angles: from the
  truth (``--estimate oracle``, a bound: what a perfect estimate would give) or from a first
  pass of MRPF on the uncentred training (``--estimate mrpf``: what a user without ground truth
  has); or ``m = 0`` (``--estimate centred``: the training centred, the person assumed to
  stand as the training subjects do on average);
- the latent trackers' pose residual (their fading start, ``tracking.FADING_START``) fades to
  ``m`` instead of to the manifold (``ExperimentConfig.residual_target``, ``dynamics.PoseResidual``'s
  ``target``), and their start is the start pose less ``m`` projected onto the manifold.

``--estimate none`` is the protocol as it stands (the same trackers, keys and scenes as
``jaxtrack protocol walk-loso``). Prints one JSON line per fold, and also the nearest-pose floor
(``experiment.nearest_pose_floor_mm``'s rule) with and without the oracle's centring.

    taskset -c 0,1 python experiments/subject_posture.py --data ../shared/data --estimate none --json none.json
    taskset -c 0,1 python experiments/subject_posture.py --data ../shared/data --estimate oracle --json oracle.json
    taskset -c 0,1 python experiments/subject_posture.py --data ../shared/data --without cmu35 --estimate mrpf --json nested.json
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile


def posture_floor_mm(train_angles, test_sequence, frames, shift=None):
    """The nearest-training-pose floor (``experiment.nearest_pose_floor_mm``'s rule) of the test
    take's first ``frames`` frames, the test angles less ``shift`` matched and ``shift`` added back."""
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack.body import GLOBAL_DOFS, forward_kinematics

    pose = np.asarray(test_sequence.pose, np.float64)[:frames]
    shift = np.zeros(pose.shape[1] - GLOBAL_DOFS) if shift is None else shift
    query = pose[:, GLOBAL_DOFS:] - shift
    d = (query ** 2).sum(-1)[:, None] - 2 * query @ train_angles.T + (train_angles ** 2).sum(-1)[None]
    nearest = train_angles[np.argmin(d, axis=1)] + shift
    skeleton = test_sequence.body().skeleton
    truth = forward_kinematics(skeleton, jnp.asarray(pose))
    closest = forward_kinematics(skeleton, jnp.asarray(np.concatenate([pose[:, :GLOBAL_DOFS], nearest], axis=1)))
    return float(1000.0 * jnp.linalg.norm(closest - truth, axis=-1).mean())


def track_fold(train, validation, scene, names, config, target):
    """``run_experiment`` on the fold with the latent trackers' residual fading to ``target``
    (``ExperimentConfig.residual_target``; None: the protocol as it stands). Returns
    ``{method: {"mm", "sd", "drift", "frame0"}}``."""
    import dataclasses

    import numpy as np

    from jaxtrack.experiment import drift_ratio, run_experiment

    config = dataclasses.replace(config, residual_target=None if target is None else tuple(np.asarray(target, float)))
    results = run_experiment(train, validation, [scene], config, names=names, progress=False, animations=False)
    out = {}
    for method, r in results["sequences"][names["test"][0]].items():
        out[method] = {"mm": round(r["error_mm_mean"], 1), "sd": round(r["error_mm_std"], 1),
                       "drift": round(drift_ratio(r["per_frame_error_mm"]), 2), "frame0": round(r["frame0_error_mm"], 1)}
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--protocol", default="walk-loso", help="walk-loso or jog-loso")
    parser.add_argument("--data", default="../shared/data")
    parser.add_argument("--subjects", nargs="+", help="test subjects (default: each in turn)")
    parser.add_argument("--without", nargs="*", default=[], help="the protocol without these subjects (nested validation)")
    parser.add_argument("--modes", nargs="+", default=["cross"])
    parser.add_argument("--estimate", choices=("none", "centred", "oracle", "mrpf"), default="mrpf")
    parser.add_argument("--methods", nargs="+", default=["latentpf", "glegbpf"])
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--budget", type=int, default=500)
    parser.add_argument("--json")
    args = parser.parse_args()  # XLA's threads as the command line leaves them, so that "none" is the protocol's own run
    import jax
    import numpy as np

    from jaxtrack.body import GLOBAL_DOFS
    from jaxtrack.experiment import (
        ExperimentConfig,
        centre_subjects,
        convert_takes,
        fold_takes,
        fold_test_scene,
        get_protocol,
        run_experiment,
    )

    protocol = get_protocol(args.protocol)
    if args.without:
        protocol = protocol.without(*args.without)
    converted = os.path.join(tempfile.gettempdir(), f"jaxtrack_subject_posture_{args.protocol}")
    sequences = convert_takes(protocol.takes(), args.data, converted, say=lambda *a, **k: None)

    def angles(sequence):
        return np.asarray(sequence.pose, np.float64)[:, GLOBAL_DOFS:]

    rows = []
    config = ExperimentConfig(methods=tuple(args.methods), budget=args.budget, runs=args.runs, seed=0)
    for fold in protocol.folds(args.modes, args.subjects):
        train, validation = fold_takes(protocol, fold, sequences)
        scene = fold_test_scene(protocol, fold, sequences)  # the protocol's scene at seed 0
        names = fold.names
        pooled = np.concatenate([angles(x) for x in train]).mean(0)
        centred, c_validation = centre_subjects(fold, train, validation)
        true_mean = angles(scene).mean(0)
        raw_angles = np.concatenate([angles(x) for x in train])
        centred_angles = np.concatenate([angles(x) for x in centred])
        row = {"fold": fold.label, "estimate": args.estimate, "budget": args.budget, "runs": args.runs,
               "floor_mm": round(posture_floor_mm(raw_angles, sequences[fold.test.name], protocol.test_frames), 1),
               "floor_oracle_centred_mm": round(posture_floor_mm(centred_angles, sequences[fold.test.name], protocol.test_frames,
                                                                 true_mean - pooled), 1),
               "offset_rms_rad": round(float(np.sqrt(np.mean((true_mean - pooled) ** 2))), 4)}
        if args.estimate == "none":
            row["methods"] = track_fold(train, validation, scene, names, config, None)
        else:
            if args.estimate == "centred":  # the training centred, the person assumed to stand as the pooled training does
                person = pooled
            elif args.estimate == "oracle":
                person = true_mean
            else:  # a first pass of MRPF on the training takes as they are: its estimates' mean angles
                first = run_experiment(train, validation, [scene], ExperimentConfig(methods=("mrpf",), budget=args.budget, runs=1, seed=0),
                                       names=names, progress=False, animations=False)
                person = np.asarray(first["estimates"][fold.test.name]["mrpf"][0], np.float64)[:, GLOBAL_DOFS:].mean(0)
                row["first_pass_mm"] = round(first["sequences"][fold.test.name]["mrpf"]["error_mm_mean"], 1)
            row["offset_error_rms_rad"] = round(float(np.sqrt(np.mean((person - true_mean) ** 2))), 4)
            row["methods"] = track_fold(centred, c_validation, scene, names, config, person - pooled)
        print(json.dumps(row), flush=True)
        rows.append(row)
        jax.clear_caches()
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(rows, handle, indent=1)


if __name__ == "__main__":
    main()
