"""Paper 002's experiment in spirit: trackers on a subject left out of training, the manifolds
learnt from other people's motion (002 sec. 3 trains GLE on several subjects' walks, and on
walk + jog, its "Combo", and tests on a held-out subject).

Three protocols on the shared real motion (converted at 60 Hz; see the shell scripts), each
test take rendered into noisy 80x60 views with a body that is not the tracker's (as
``real_motion.py`` does; its radii withheld):

- ``bandai-to-cmu``: trained on two Bandai walks, tested on CMU subject 35's walk (200 frames);
- ``combo-bandai-to-cmu``: trained on two Bandai walks and two runs, tested on CMU 35's walk and
  jog;
- ``combo-cmu-to-bandai``: trained on CMU 35's walks and jogs, tested on a Bandai walk (200
  frames) and run (80).

CMU 35 is never in the Bandai training set and the reverse, so every test subject is unseen.
A fourth, ``synthetic-s3``, is the demo's training and validation motion (walks and jogs of the
synthetic subjects S1 and S2) with the held-out synthetic subject S3 (other proportions,
cadence, stride, arm swing, knee bend and lean) walking and jogging for 100 frames at 60 Hz.
Every tracker runs at each ``--budgets`` value (likelihood evaluations per frame; the annealed
ones in 5 layers: APF 5 x 100 at 500), ``--runs`` runs, with its own defaults (GLE-GbPF on a
3-D GLE, MRPF on a 2-D GPDM, GPAPF and LatentPF on a 3-D one).

    taskset -c 0,1 python benchmarks/gle_cross_subject.py --cmu /tmp/real/cmu --bandai /tmp/real/bandai \\
        --runs 5 --budgets 500 1500 --json gle_cross_subject.json

``--residual 1 --velocity off --methods glegbpf latentpf`` gives the latent trackers an
off-manifold pose residual (README, "Leaving the manifold").

``--plot-latent PATH`` draws the LE and GLE embeddings of the combo training sets coloured by
take and by gait phase instead (no tracking); ``--floors`` measures how close each protocol's
training poses and GLE can get to its test poses (``manifold_floors``).
"""

from __future__ import annotations

import argparse
import itertools
import os
import time

from bench_output import write_json
from real_motion import body_factors, drift_ratio, other_body_scene

# name: (training takes, validation takes, [(test take, frames)]); a take is (dataset, name)
PROTOCOLS = {
    "bandai-to-cmu": ([("bandai", "walk_normal_001"), ("bandai", "walk_normal_002")], [("bandai", "walk_normal_003")],
                      [(("cmu", "35_29"), 200)]),
    "combo-bandai-to-cmu": ([("bandai", "walk_normal_001"), ("bandai", "walk_normal_002"), ("bandai", "run_normal_001"),
                             ("bandai", "run_normal_002")], [("bandai", "walk_normal_003"), ("bandai", "run_normal_003")],
                            [(("cmu", "35_29"), 200), (("cmu", "35_18"), None)]),
    "combo-cmu-to-bandai": ([("cmu", "35_01"), ("cmu", "35_02"), ("cmu", "35_17"), ("cmu", "35_19"), ("cmu", "35_20")],
                            [("cmu", "35_03"), ("cmu", "35_21")],
                            [(("bandai", "walk_normal_003"), 200), (("bandai", "run_normal_005"), 80)]),
}
SYNTHETIC = "synthetic-s3"
METHODS = ["sir", "apf", "mrpf", "gpapf", "latentpf", "glegbpf"]


def synthetic_protocol(key, views, frames=100):
    """The demo's S1 / S2 training and validation motion; S3's walk and jog as the test, rendered
    with the other body (``body_factors()``, radii withheld) in ``views`` noisy 80x60 views."""
    import dataclasses

    import equinox as eqx
    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack.camera import default_rig
    from jaxtrack.data import SilhouetteNoise, build_scene, generate_motion
    from jaxtrack.demo import demo_sequences

    train, validation, _, _ = demo_sequences(key)
    test, names = [], []
    for i, gait in enumerate(("walk", "jog")):
        motion = generate_motion(gait, "S3", num_frames=frames, fps=60.0, key=jax.random.fold_in(key, 500 + i))
        radii = np.asarray(motion.body.radii) * np.array([body_factors()[g] for g in motion.body.capsule_groups])
        other = dataclasses.replace(motion, body=eqx.tree_at(lambda b: b.radii, motion.body, jnp.asarray(radii, jnp.float32)))
        scene = build_scene(jax.random.fold_in(key, 600 + i), other, default_rig(80, 60, num_views=views), SilhouetteNoise())
        test.append(scene.replace(capsule_radii=None))
        names.append(f"S3 {gait}")
    return train, validation, test, names


def load(folders, take, parser, crop=None):
    from jaxtrack.io import load_sequence

    dataset, name = take
    if folders[dataset] is None:
        parser.error(f"{name} needs --{dataset} (the folder of the converted takes)")
    path = os.path.join(folders[dataset], name + ".npz")
    if not os.path.exists(path):
        parser.error(f"missing {path}; convert the shared data first (see the shell scripts)")
    sequence = load_sequence(path)
    return sequence.cropped(min(crop, sequence.num_frames)) if crop else sequence


def plot_latent_spaces(folders, parser, path, train_frames):
    """LE, temporal LE and GLE of the two combo training sets, coloured by take (subject and
    activity) and by gait phase. Temporal LE refuses several takes at once (its graph has one
    piece per take), so it is fitted on each take alone and each take's embedding is drawn in
    its own box, side by side: nothing places one take's frames beside another's."""
    import jax
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from jaxtrack.body import joint_angles
    from jaxtrack.errors import ConfigurationError
    from jaxtrack.manifold import fit_spectral

    jax.config.update("jax_enable_x64", True)
    names = ["combo-bandai-to-cmu", "combo-cmu-to-bandai"]
    fig, axes = plt.subplots(2, 6, figsize=(22, 7.2))
    for row, name in enumerate(names):
        takes = PROTOCOLS[name][0]
        sequences = [joint_angles(np.asarray(load(folders, t, parser, train_frames).pose)) for t in takes]
        owner = np.repeat(np.arange(len(takes)), [len(s) for s in sequences])
        # A phase shared by every take: the angle of each frame in the plane of the first two
        # principal components of the standardised joint angles, where a gait cycle is a loop.
        Y = np.concatenate(sequences)
        Y = (Y - Y.mean(0)) / (Y.std(0) + 1e-8)
        _, _, vt = np.linalg.svd(Y, full_matrices=False)
        phase = np.arctan2(Y @ vt[1], Y @ vt[0])
        for column, graph in enumerate(["le", "tle", "gle"]):
            label = graph.upper()
            if graph == "tle":  # one embedding per take, each scaled into its own unit box, side by side
                boxes = []
                for i, angles in enumerate(sequences):
                    own = np.asarray(fit_spectral([angles], "tle").latent)[:, :2]
                    own = (own - own.min(0)) / (np.ptp(own, axis=0) + 1e-12)
                    boxes.append(own + np.array([1.25 * i, 0.0]))
                Z = np.concatenate(boxes)
                label = "TLE, each take alone"
            elif graph == "le":  # k nearest neighbours in pose space: walks and runs may be two pieces at small k
                for k in (10, 20, 40, 80):
                    try:
                        model = fit_spectral(sequences, "le", k=k)
                        break
                    except ConfigurationError as err:
                        print(f"{name}: LE with k = {k}: {str(err).split(';')[0]}")
                label = f"LE (k = {k})"
                Z = np.asarray(model.latent)
            else:
                Z = np.asarray(fit_spectral(sequences, graph).latent)
            ax = axes[row, 2 * column]
            for i, take in enumerate(takes):
                ax.scatter(Z[owner == i, 0], Z[owner == i, 1], s=3, label=f"{take[0]} {take[1]}")
            ax.set_title(f"{label}, {name.split('-')[1]} takes", fontsize=9)
            ax.legend(fontsize=6, markerscale=3)
            ax = axes[row, 2 * column + 1]
            points = ax.scatter(Z[:, 0], Z[:, 1], s=3, c=phase, cmap="twilight")
            ax.set_title(f"{label}: by gait phase", fontsize=9)
            fig.colorbar(points, ax=ax, fraction=0.046)
    fig.suptitle("Latent spaces of the combo training sets, coloured by take and by gait phase (each pose's angle in the "
                 "plane of the poses' first two principal components)", fontsize=10)
    for ax in axes.ravel():
        ax.set_xlabel("latent 1", fontsize=8)
        ax.set_ylabel("latent 2", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    print(f"wrote {path}")


JOINT_GROUPS = {
    "arms": ("lshoulder", "lelbow", "lwrist", "rshoulder", "relbow", "rwrist"),
    "legs": ("lhip", "lknee", "lankle", "rhip", "rknee", "rankle"),
    "torso": ("pelvis", "thorax", "head"),
}
CONVENTION_ANGLES = ("lclavicle_elev", "lshoulder_abd", "lhip_twist", "rhip_twist")  # where the datasets differ most


def manifold_floors(folders, parser, train_frames):
    """How close each protocol's training poses, and its GLE, can get to its test poses, with
    the true root (mm; nearest in joint angles, radians):

    - ``nearest_training_pose_mm`` (and ``..._by_group``: arms, legs, torso): the training pose
      nearest to each test pose;
    - ``encode_decode_mm``: encode -> decode through the GLE's inverse and forward RBF networks;
    - ``legs_nearest_by_legs_mm``: the leg joints' error when the nearest pose is chosen by the
      leg angles alone (so the arms' conventions cannot pick it);
    - ``mean_centred_nearest_mm``: the nearest pose after shifting the training angles by the
      difference of the test take's and the training set's mean angles, an oracle for any
      per-dataset normalisation of the angles' conventions (it uses the test take's own mean);
    - ``mean_difference_rad``: that difference for ``CONVENTION_ANGLES``."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack.body import HUMANEVA_JOINTS, forward_kinematics, joint_angles
    from jaxtrack.manifold import fit_spectral
    from jaxtrack.tracking import sequence_poses

    jax.config.update("jax_enable_x64", True)
    key = jax.random.key(0)
    rows = []
    for name, (train_takes, _, tests) in PROTOCOLS.items():
        angles = [joint_angles(sequence_poses(load(folders, t, parser, train_frames), t[1], key=key)) for t in train_takes]
        model = fit_spectral(angles, "gle")
        training = np.asarray(model.training_poses())
        for take, frames in tests:
            sequence = load(folders, take, parser)
            poses = sequence_poses(sequence, take[1], key=key)[:frames]
            skeleton = sequence.body().skeleton
            truth = np.asarray(forward_kinematics(skeleton, jnp.asarray(poses)))
            layout = skeleton.pose_layout[6:]

            def per_joint(angles_, poses=poses, skeleton=skeleton, truth=truth):
                estimate = np.asarray(forward_kinematics(skeleton, jnp.asarray(np.concatenate([poses[:, :6], angles_], axis=1))))
                return 1000.0 * np.linalg.norm(estimate - truth, axis=-1).mean(axis=0)  # (15,) mm

            def group(errors, joints):
                return float(np.mean([errors[HUMANEVA_JOINTS.index(j)] for j in joints]))

            test = joint_angles(poses)

            def nearest(candidates, columns=slice(None), test=test):
                return candidates[np.argmin(((test[:, None, columns] - candidates[None, :, columns]) ** 2).sum(-1), axis=1)]

            plain = per_joint(nearest(training))
            legs = [i for i, entry in enumerate(layout) if entry.startswith(("lhip", "rhip", "lknee", "rknee"))]
            shift = test.mean(axis=0) - training.mean(axis=0)
            row = {"protocol": name, "test": f"{take[0]}-{take[1]}",
                   "nearest_training_pose_mm": float(plain.mean()),
                   "nearest_training_pose_mm_by_group": {g: group(plain, joints) for g, joints in JOINT_GROUPS.items()},
                   "encode_decode_mm": float(per_joint(np.asarray(model.decode(model.encode(jnp.asarray(test)))[0])).mean()),
                   "legs_nearest_by_legs_mm": group(per_joint(nearest(training, legs)), JOINT_GROUPS["legs"]),
                   "mean_centred_nearest_mm": float(per_joint(nearest(training + shift)).mean()),
                   "mean_difference_rad": {a: float(shift[layout.index(a)]) for a in CONVENTION_ANGLES}}
            print(row, flush=True)
            rows.append(row)
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cmu", help="folder with the converted CMU takes (35_01.npz, ...)")
    parser.add_argument("--bandai", help="folder with the converted Bandai takes (walk_normal_001.npz, ...)")
    parser.add_argument("--protocols", nargs="+", default=[*PROTOCOLS, SYNTHETIC], choices=[*PROTOCOLS, SYNTHETIC])
    parser.add_argument("--methods", nargs="+", default=METHODS)
    parser.add_argument("--budgets", type=int, nargs="+", default=[500, 1500])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--views", type=int, default=3)
    parser.add_argument("--velocity", choices=["own", "on", "off"], default="own",
                        help="Kalman-tracked velocity for every tracker (on), none (off), or each tracker's own default")
    parser.add_argument("--residual", nargs="+", default=["own"],
                        help="scales of the off-manifold pose residual of LatentPF and GLE-GbPF (several: one table each; "
                             "0: none; own: each tracker's default)")
    parser.add_argument("--train-frames", type=int, default=240,
                        help="first frames of each training take (60 Hz; 240: three to four walk cycles) (default: %(default)s)")
    parser.add_argument("--fit-steps", type=int, default=300)
    parser.add_argument("--fit-optimiser", choices=["optax", "lbfgs"], default="optax",
                        help="the manifold fit's L-BFGS (optax, the experiment's default: the README's tables)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--plot-latent", metavar="PNG", help="draw the LE and GLE latent spaces instead of tracking")
    parser.add_argument("--floors", action="store_true",
                        help="instead of tracking, how close each real protocol's GLE gets to its test poses (mm)")
    parser.add_argument("--json", help="also write the results to this JSON file")
    args = parser.parse_args()
    import jax

    from jaxtrack.experiment import ExperimentConfig, results_table, run_experiment

    folders = {"cmu": args.cmu, "bandai": args.bandai}
    if args.plot_latent:
        plot_latent_spaces(folders, parser, args.plot_latent, args.train_frames)
        return
    if args.floors:
        write_json(manifold_floors(folders, parser, args.train_frames), args.json)
        return
    key = jax.random.key(args.seed)
    rows = []
    for name in args.protocols:
        if name == SYNTHETIC:
            train, validation, test, test_names = synthetic_protocol(key, args.views)
            train_takes = [("synthetic", f"{s} {g}") for g, s in (("walk", "S1"), ("jog", "S1"), ("walk", "S2"), ("jog", "S2"))]
        else:
            train_takes, validation_takes, tests = PROTOCOLS[name]
            train = [load(folders, t, parser, args.train_frames) for t in train_takes]
            validation = [load(folders, t, parser) for t in validation_takes]
            test_names = [f"{t[0]}-{t[1]}" for t, _ in tests]
            test = [other_body_scene(jax.random.fold_in(key, i), load(folders, t, parser), args.views, frames)
                    for i, (t, frames) in enumerate(tests)]
        for budget, residual in itertools.product(args.budgets, [None if r == "own" else float(r) for r in args.residual]):
            config = ExperimentConfig(methods=tuple(args.methods), budget=budget, runs=args.runs, fit_steps=args.fit_steps,
                                      fit_optimiser=args.fit_optimiser, seed=args.seed,
                                      velocity={"own": None, "on": True, "off": False}[args.velocity], residual=residual)
            start = time.perf_counter()
            results = run_experiment(train, validation, test, config, names={"test": test_names}, progress=False, animations=False)
            seconds = time.perf_counter() - start
            print(f"\n{name}, budget {budget}, residual {residual if residual is not None else 'own'}, {args.views} views, "
                  f"other body ({seconds:.0f} s)\n")
            print(results_table(results), flush=True)
            for test_name, scene in zip(test_names, test):
                per_method = results["sequences"][test_name]
                rows.append({
                    "protocol": name, "test": test_name, "budget": budget, "views": args.views, "frames": scene.num_frames,
                    "train": [f"{t[0]}-{t[1]}" for t in train_takes], "train_frames": args.train_frames, "runs": args.runs,
                    "body_factors": body_factors(), "seconds": seconds, "velocity": args.velocity,
                    "manifolds": results["manifolds"],
                    "methods": {m: {"error_mm_mean": per_method[m]["error_mm_mean"], "error_mm_std": per_method[m]["error_mm_std"],
                                    "error_mm_per_run": per_method[m]["error_mm_per_run"],
                                    "last_over_first_quarter": drift_ratio(per_method[m]["per_frame_error_mm"]),
                                    "per_frame_error_mm": per_method[m]["per_frame_error_mm"],
                                    "per_frame_error_mm_per_run": per_method[m]["per_frame_error_mm_per_run"],
                                    "manifold": config.manifold_of(m), "latent_dim": config.latent_dim_of(m),
                                    "velocity": config.velocity_of(m), "residual": config.residual_of(m),
                                    "residual_decay": config.residual_decay_of(m)} for m in args.methods},
                })
            write_json(rows, args.json)
            jax.clear_caches()  # every experiment compiles its own trackers (see real_motion.py)


if __name__ == "__main__":
    main()
