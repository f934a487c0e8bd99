"""When is VLMM-PF lost under 004's blob likelihood, and does restarting from the automaton's
initial states bring it back (docs/vlmm.md, "Restarting a lost tracker")?

    taskset -c 0,1 python experiments/vlmm_restart.py --json vlmm_restart.json    # about 10 minutes on 2 cores

Training and validation: the demo's walks and jogs of subjects S1 and S2; the manifold a 3-D
BC-GPLVM (100 steps), VLMM-PF's prototypes and automaton fitted on it. Test: the demo's S1 walk
(4 noisy 80x60 views, 40 frames), scored by the blob likelihood at power 10, budget 500.

1. Divergences: VLMM-PF without restarts and without a velocity tracks the walk and the jog
   (``--runs`` runs); per frame, the evidence is fitted from the previous and the current
   estimate, and the estimate's and the truth's divergence ``D(F || G)`` from it are binned by
   the estimate's joint error. A lost-divergence threshold should sit above the tracked frames'
   and below the lost ones'.
2. Restarts: VLMM-PF with its Kalman velocity on the walk, from the true start and from a wrong
   one (the walk's root with the jog's joint angles at frame 10), with restarts at several
   thresholds (``lost_divergence``) and none.
"""

import argparse
import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack import tracking
from jaxtrack.body import forward_kinematics
from jaxtrack.demo import demo_sequences
from jaxtrack.evaluation import mean_joint_error_mm
from jaxtrack.filters import run_filter
from jaxtrack.likelihood import BlobLikelihood, mixture_kl, pose_blobs

POWER = 10.0


def frame_errors(scene, estimates):
    joints = forward_kinematics(scene.body.skeleton, jnp.asarray(estimates, jnp.float32))
    truth = jnp.asarray(scene.truth_joints, jnp.float32)
    return np.array([float(mean_joint_error_mm(joints[t:t + 1], truth[t:t + 1])) for t in range(len(estimates))])


def divergences(blob, scene, estimates):
    """Per frame: the estimate's and the truth's D(F || G), G fitted from the previous and the current estimate."""
    out = []
    for t in range(len(estimates)):
        previous = estimates[t - 1] if t else np.asarray(scene.initial_pose)
        observation = jax.tree.map(lambda x, t=t: x[t], scene.observations)
        evidence = blob.fit_evidence(observation, jnp.stack([jnp.asarray(previous), jnp.asarray(estimates[t])]))
        best = int(jnp.argmax(evidence.fit))
        row = []
        for pose in (estimates[t], np.asarray(scene.truth_poses[t], np.float32)):
            a, m, c = pose_blobs(blob.body, jnp.asarray(pose)[None])
            row.append(float(mixture_kl(a, m, c, evidence.weights[best][None], evidence.means[best][None],
                                        evidence.covariances[best][None])[0]))
        out.append(row)
    return np.array(out)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=2, help="runs of part 1 (part 2: 3)")
    parser.add_argument("--json", help="write the results here")
    args = parser.parse_args()
    key = jax.random.key(0)
    train, validation, test, names = demo_sequences(key, test_frames=40)
    train_poses = [tracking.sequence_poses(s, "train", key=key) for s in train]
    validation_poses = [tracking.sequence_poses(s, "validation", key=key) for s in validation]
    recipe = tracking.get_tracker("vlmmpf")
    model, _, starts = tracking.fit_manifold(train_poses, 3, 100, kind="bc-gplvm")[:3]
    motion = tracking.motion_data(train_poses, validation_poses, model, starts)
    fitted = tracking.fit_tracker(recipe, tracking.tracker_keys(0, "vlmmpf")[0], motion)
    scenes = [tracking.prepare_test(seq, name, key=key, likelihood="blobs", likelihood_options={"power": POWER, "lost_divergence": 0})
              for seq, name in zip(test, names["test"])]
    blob = scenes[0].likelihood
    assert isinstance(blob, BlobLikelihood)

    rows = []
    for scene in scenes:
        tracker = tracking.build_tracker(recipe, fitted, scene.likelihood, tracking.Budget(500, 5))
        for run in range(args.runs):
            _, info = run_filter(tracker, jax.random.fold_in(key, run), scene.initial_pose, scene.observations)
            estimates = np.asarray(info.estimate)
            rows.append(np.column_stack([frame_errors(scene, estimates), divergences(blob, scene, estimates)]))
    rows = np.concatenate(rows)
    binned = []
    for low, high in ((0, 30), (30, 60), (60, 120), (120, np.inf)):
        chosen = (rows[:, 0] >= low) & (rows[:, 0] < high)
        if chosen.any():
            entry = {"error_mm": [low, None if np.isinf(high) else high], "frames": int(chosen.sum()),
                     "estimate_D_quartiles": np.percentile(rows[chosen, 1], [25, 50, 75]).round(2).tolist(),
                     "estimate_D_95": round(float(np.percentile(rows[chosen, 1], 95)), 2),
                     "truth_D_quartiles": np.percentile(rows[chosen, 2], [25, 50, 75]).round(2).tolist()}
            binned.append(entry)
            print(json.dumps(entry), flush=True)

    scene, other = scenes[0], scenes[1]
    wrong = jnp.asarray(scene.initial_pose).at[6:].set(jnp.asarray(other.truth_poses[10, 6:], jnp.float32))
    restarts = []
    for lost in (None, 3.0, 5.0, 10.0):
        tracker = tracking.build_tracker(recipe, fitted, scene.likelihood, tracking.Budget(500, 5), velocity_from=validation_poses)
        tracker = dataclasses.replace(tracker, lost_below=None if lost is None else float(-POWER * np.log(lost)))
        for start_name, start in (("true start", scene.initial_pose), ("wrong start", wrong)):
            errors, counts = [], []
            for run in range(3):
                _, info = run_filter(tracker, jax.random.fold_in(key, run), start, scene.observations)
                errors.append(frame_errors(scene, np.asarray(info.estimate)))
                counts.append(0 if info.restarted is None else int(np.sum(np.asarray(info.restarted))))
            errors = np.array(errors)
            entry = {"lost_divergence": lost, "start": start_name, "frames_0_9": round(float(errors[:, :10].mean()), 1),
                     "frames_10_39": round(float(errors[:, 10:].mean()), 1), "mean": round(float(errors.mean()), 1),
                     "sd_over_runs": round(float(errors.mean(1).std()), 1), "restarts_per_run": counts}
            restarts.append(entry)
            print(json.dumps(entry), flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"divergences": binned, "restarts": restarts}, f, indent=1)


if __name__ == "__main__":
    main()
