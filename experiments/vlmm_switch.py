"""VLMM-PF against single-model latent trackers on a motion that changes activity (docs/trackers.md,
"VLMM-PF"), and the prototype picture.

    taskset -c 0,1 python experiments/vlmm_switch.py --runs 5 --budget 500 --json vlmm_switch.json \
        --plot docs/figures/vlmm_prototypes.png

Training: the demo's walks and jogs of subjects S1 and S2 (80 frames each, 60 Hz); validation:
the demo's. Test: subject S1 walking for 60 frames, then jogging, the two joined by a 12-frame
cross-fade of the pose vectors (the jog generated on the walk's circle from where the fade
starts), rendered in the default 4 views at 80x60 with the default silhouette noise; 120 frames.
Prints each tracker's mean error before the fade, during and after it, over ``--runs`` runs.
"""

import argparse
import json

import jax
import numpy as np

from jaxtrack.body import forward_kinematics
from jaxtrack.camera import default_rig
from jaxtrack.data import SilhouetteNoise, SyntheticMotion, build_scene, generate_motion
from jaxtrack.demo import demo_sequences
from jaxtrack.experiment import ExperimentConfig, run_experiment

WALK, FADE, TOTAL = 60, 12, 120


def switching_motion(key, fps=60.0) -> SyntheticMotion:
    """S1 walking, then jogging on the same circle, joined by a cross-fade of the pose vectors."""
    walk = generate_motion("walk", "S1", num_frames=WALK + FADE, fps=fps, key=jax.random.fold_in(key, 0))
    start = np.arctan2(walk.pose[WALK, 1], walk.pose[WALK, 0])  # where on the circle the fade starts
    jog = generate_motion("jog", "S1", num_frames=TOTAL - WALK, fps=fps, start_angle=float(start), key=jax.random.fold_in(key, 1))
    weight = np.clip((np.arange(FADE) + 0.5) / FADE, 0, 1)[:, None]
    a, b = walk.pose[WALK:WALK + FADE].astype(np.float64), jog.pose[:FADE].astype(np.float64)
    b[:, 3] = a[:, 3] + np.angle(np.exp(1j * (b[:, 3] - a[:, 3])))  # yaw on the same branch
    pose = np.concatenate([walk.pose[:WALK], (1 - weight) * a + weight * b, jog.pose[FADE:]]).astype(walk.pose.dtype)
    joints = np.asarray(forward_kinematics(walk.body.skeleton, jax.numpy.asarray(pose)))
    return SyntheticMotion(body=walk.body, pose=pose, joints3d=joints, fps=fps, gait="walk-to-jog", subject="S1",
                           speed=float(np.mean([walk.speed, jog.speed])))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--budget", type=int, default=500)
    parser.add_argument("--methods", nargs="+", default=["latentpf", "mrpf", "vlmmpf"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="write the per-segment errors here")
    parser.add_argument("--plot", help="write the VLMM-PF's prototype picture here (PNG)")
    args = parser.parse_args()
    key = jax.random.key(args.seed)
    train, validation, _, names = demo_sequences(key)
    scene = build_scene(jax.random.fold_in(key, 900), switching_motion(jax.random.fold_in(key, 901)), default_rig(80, 60),
                        SilhouetteNoise())
    config = ExperimentConfig(methods=tuple(args.methods), budget=args.budget, runs=args.runs, fit_steps=100, seed=args.seed)
    results = run_experiment(train, validation, [scene], config, names={**names, "test": ["S1 walk to jog"]}, progress=False)
    segments = {"walk": slice(0, WALK), "fade": slice(WALK, WALK + FADE), "jog": slice(WALK + FADE, TOTAL)}
    rows = {}
    print(f"| tracker | walk (0-{WALK}) | fade ({WALK}-{WALK + FADE}) | jog ({WALK + FADE}-{TOTAL}) | all |")
    print("|---|---:|---:|---:|---:|")
    for method in args.methods:
        entry = results["sequences"]["S1 walk to jog"].get(method)
        if entry is None:
            print(f"| {method} | refused: {results['refused'].get(method)} | | | |")
            continue
        curves = np.asarray(entry["per_frame_error_mm_per_run"])
        per_run = {name: curves[:, part].mean(axis=1) for name, part in segments.items()}
        rows[method] = {name: [float(np.mean(v)), float(np.std(v))] for name, v in per_run.items()}
        rows[method]["all"] = [entry["error_mm_mean"], entry["error_mm_std"]]
        cells = " | ".join(f"{m:.1f} ({s:.1f})" for m, s in rows[method].values())
        print(f"| {method} | {cells} |")
    if args.plot and "vlmmpf" in args.methods:
        from jaxtrack.dynamics import fit_vlmm_dynamics, plot_prototypes
        from jaxtrack.tracking import fit_manifold, motion_data, sequence_poses

        train_poses = [sequence_poses(s, "train", key=key) for s in train]
        validation_poses = [sequence_poses(s, "validation", key=key) for s in validation]
        model, _, starts = fit_manifold(train_poses, 3, 100, kind="bc-gplvm")
        motion = motion_data(train_poses, validation_poses, model, starts)
        with jax.enable_x64(True):
            dynamics, fit = fit_vlmm_dynamics(motion.manifold, list(motion.validation), motion.training_starts, key=key)
        plot_prototypes(dynamics, fit.augmented, np.concatenate(fit.labels), args.plot)
        rows["prototypes"] = {"count": dynamics.prototypes.num_components, "message_lengths": fit.mixture_fit.message_lengths,
                              "vlmm_states": dynamics.vlmm.num_states, "vlmm_depth": fit.tree.depth,
                              "step_scale": float(dynamics.step_scale)}
        print(f"{rows['prototypes']['count']} prototypes (message length per count: "
              f"{ {k: round(v, 1) for k, v in sorted(fit.mixture_fit.message_lengths.items())} }), VLMM of "
              f"{rows['prototypes']['vlmm_states']} states, longest context {rows['prototypes']['vlmm_depth']}, "
              f"lambda {rows['prototypes']['step_scale']:.3f}; wrote {args.plot}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1, default=str)


if __name__ == "__main__":
    main()
