"""Can the silhouettes give a person's posture? A shared joint-angle offset fitted on a first pass.

docs/subjects.md, "Tried: a person's own posture": with the truth's mean joint angles put back,
the latent trackers gain 3-19 mm across people, and a first MRPF pass gives no estimate of them
(its estimates sit on the training posture). This script asks the images directly. For each
cross fold of ``jaxtrack protocol``'s walking protocol (levelled takes, the protocol's scene and
keys; 3 noisy 80x60 views by default):

1. a first pass of one tracker (GLE-GbPF by default, 1 run) gives poses ``P_t``;
2. on ``--frames`` frames spread over the take, the MAP fit of one shared offset ``d`` of the
   joint angles (prior sd ``--offset-sd`` radians) and, per frame, a deviation ``e_t`` (prior sd
   ``--frame-sd`` radians, 3 cm and 0.05 rad for the root; ``--frame-sd 0``: none), the poses
   ``P_t + d + e_t`` scored by the scene's own likelihood (silhouettes and ground prior), weighted
   30 against the priors as ``likelihood.calibrate_body`` does; ``--radii`` also fits the
   capsules' radii (sd 0.15 on each capsule group's log radius: torso, arms, legs, head); ``--exclude clavicle shoulder``
   holds the offset of the joint angles so named at 0. 300 Adam steps.

It prints, per fold, how far the first pass's mean joint angles are from the truth's (RMS,
radians), how far the fitted ones are, their correlation with the true offset, and the mean
joint error of the fitted frames against the first pass's. ``--renderer own`` draws the test
take with the tracker's own capsules (radii kept), the control: no body mismatch.

    taskset -c 0,1 python experiments/posture_from_silhouettes.py --data ../shared/data --plot docs/figures/posture_offsets.png  # 6 min
    taskset -c 0,1 python experiments/posture_from_silhouettes.py --data ../shared/data --subjects cmu07 --renderer own
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import tempfile


def fit_offset(scene, poses, picks, *, offset_sd, frame_sd, radii, exclude=(), steps=300, data_weight=30.0):
    """MAP of the shared joint-angle offset (and per-frame deviations, and radii) on frames
    ``picks`` of ``scene`` started at ``poses`` (T, D). Returns ``(offset (A,), fitted poses (F, D),
    radius factors per group or None, cost before, cost after)``. Joint angles whose name holds
    one of ``exclude`` keep no offset."""
    import equinox as eqx
    import jax
    import jax.numpy as jnp
    import numpy as np
    import optax

    from jaxtrack.body import GLOBAL_DOFS
    from jaxtrack.likelihood import body_of, with_body

    likelihood = scene.likelihood
    body = body_of(likelihood)
    skeleton = body.skeleton
    D = poses.shape[1]
    dtype = body.radii.dtype
    start = jnp.asarray(poses[picks], dtype)
    observations = jax.tree.map(lambda x: jnp.asarray(x)[jnp.asarray(picks)], scene.observations)
    sd = np.full(D, frame_sd)
    sd[:3], sd[3:GLOBAL_DOFS] = 0.03, 0.05
    sd = jnp.asarray(sd if frame_sd > 0 else np.zeros(D), dtype)
    groups = jnp.asarray(np.unique(np.asarray(body.capsule_groups), return_inverse=True)[1])
    names = skeleton.dof_names[-(D - GLOBAL_DOFS):]
    free = jnp.asarray([not any(part in name for part in exclude) for name in names], dtype)

    def unwhiten(u):
        offset = jnp.concatenate([jnp.zeros(GLOBAL_DOFS, dtype), offset_sd * free * u["offset"]])
        fitted = skeleton.clip_to_limits(start + offset[None] + sd[None] * u["frames"])
        factors = jnp.exp(0.15 * u["radii"]) if radii else jnp.ones_like(u["radii"])
        return fitted, factors

    def loss(u):
        fitted, factors = unwhiten(u)
        model = with_body(likelihood, eqx.tree_at(lambda b: b.radii, body, (body.radii * factors[groups]).astype(dtype)))
        per_frame = jax.vmap(lambda pose, obs: model.log_likelihood(pose[None], obs)[0])(fitted, observations)
        return -data_weight * jnp.sum(per_frame) + 0.5 * sum(jnp.sum(v ** 2) for v in jax.tree.leaves(u))

    optimiser = optax.adam(0.05)

    @jax.jit
    def run(u):
        def step(carry, _):
            u, state = carry
            value, grad = jax.value_and_grad(loss)(u)
            grad = jax.tree.map(lambda g: jnp.where(jnp.isfinite(g), g, 0.0), grad)
            updates, state = optimiser.update(grad, state)
            return (optax.apply_updates(u, updates), state), value
        (u, _), trace = jax.lax.scan(step, (u, optimiser.init(u)), None, length=steps)
        return u, trace

    u0 = {"offset": jnp.zeros(D - GLOBAL_DOFS, dtype), "frames": jnp.zeros((len(picks), D), dtype),
          "radii": jnp.zeros(int(groups.max()) + 1, dtype)}
    u, trace = run(u0)
    fitted, factors = unwhiten(u)
    return (offset_sd * np.asarray(free * u["offset"], np.float64), np.asarray(fitted, np.float64),
            np.asarray(factors, np.float64) if radii else None, float(trace[0]), float(trace[-1]))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", default="../shared/data")
    parser.add_argument("--subjects", nargs="+", help="left-out subjects (default: each in turn)")
    parser.add_argument("--first", default="glegbpf", help="the first pass's tracker")
    parser.add_argument("--renderer", choices=("solid", "capsules", "own"), default="solid")
    parser.add_argument("--views", type=int, default=3)
    parser.add_argument("--size", type=int, nargs=2, default=(80, 60), metavar=("W", "H"))
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--offset-sd", type=float, default=0.05)
    parser.add_argument("--frame-sd", type=float, default=0.0)
    parser.add_argument("--radii", action="store_true")
    parser.add_argument("--exclude", nargs="*", default=[], help="joint angles whose name holds one of these keep no offset")
    parser.add_argument("--json")
    parser.add_argument("--plot", help="a PNG of every joint angle's fitted and true offset, one panel per fold")
    args = parser.parse_args()
    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack.body import GLOBAL_DOFS, forward_kinematics
    from jaxtrack.camera import default_rig
    from jaxtrack.data import SilhouetteNoise, scene_from_sequence
    from jaxtrack.experiment import (
        ExperimentConfig,
        convert_takes,
        fit_methods,
        fold_takes,
        fold_test_scene,
        get_protocol,
        new_results,
        prepare_inputs,
        track_methods,
    )

    protocol = get_protocol("walk-loso")
    converted = os.path.join(tempfile.gettempdir(), "jaxtrack_posture_from_silhouettes")
    sequences = convert_takes(protocol.takes(), args.data, converted, say=lambda *a, **k: None, level_floor=True)
    quiet = lambda *a, **k: None  # noqa: E731
    rows = []
    for fold in protocol.folds(["cross"], args.subjects):
        train, validation = fold_takes(protocol, fold, sequences)
        if args.renderer == "own":  # the control: the tracker's own capsules (the skeleton's default radii), drawn and kept
            sequence = sequences[fold.test.name]
            rig = default_rig(*args.size, num_views=args.views)
            test_key = jax.random.fold_in(jax.random.key(0), [t.name for t in protocol.takes()].index(fold.test.name))
            test = scene_from_sequence(test_key, sequence.replace(capsule_radii=np.asarray(sequence.body().radii)), rig,
                                       SilhouetteNoise(), frames=min(protocol.test_frames, sequence.num_frames))
        else:  # the protocol's scene
            test = fold_test_scene(protocol, fold, sequences, views=args.views, size=tuple(args.size), renderer=args.renderer)
        config = ExperimentConfig(methods=(args.first,), budget=500, runs=1, seed=0)
        results = new_results(config)
        inputs = prepare_inputs(train, validation, [test], config, results, names=fold.names, say=quiet)
        fitted_methods = fit_methods(inputs, config, results, progress=False, say=quiet)
        track_methods(inputs, fitted_methods, config, results, say=quiet)
        scene = inputs.scenes[0]
        first = np.asarray(results["estimates"][fold.test.name][args.first][0], np.float64)
        truth = np.asarray(test.pose, np.float64)
        picks = np.unique(np.round(np.linspace(0, len(first) - 1, args.frames)).astype(int))
        offset, poses, factors, before, after = fit_offset(scene, first, picks, offset_sd=args.offset_sd,
                                                           frame_sd=args.frame_sd, radii=args.radii,
                                                           exclude=tuple(args.exclude))

        def error_mm(p, scene=scene, picks=picks):
            joints = np.asarray(forward_kinematics(scene.body.skeleton, jnp.asarray(p, jnp.float32)), np.float64)
            return 1000.0 * float(np.mean(np.linalg.norm(joints - scene.truth_joints[picks], axis=-1)))

        true_offset = truth[picks, GLOBAL_DOFS:].mean(0) - first[picks, GLOBAL_DOFS:].mean(0)
        found = poses[:, GLOBAL_DOFS:].mean(0) - first[picks, GLOBAL_DOFS:].mean(0)
        dof_names = scene.body.skeleton.dof_names[-len(offset):]
        largest = np.argsort(-np.abs(found))[:4]
        row = {"fold": fold.label, "renderer": args.renderer, "views": args.views, "size": list(args.size),
               "first": args.first, "frames": len(picks), "offset_sd": args.offset_sd, "frame_sd": args.frame_sd,
               "radii": args.radii, "exclude": args.exclude,
               "first_pass_mm": round(error_mm(first[picks]), 1), "fitted_mm": round(error_mm(poses), 1),
               "posture_error_rad": {"first_pass": round(float(np.sqrt(np.mean(true_offset ** 2))), 4),
                                     "fitted": round(float(np.sqrt(np.mean((found - true_offset) ** 2))), 4)},
               "correlation": round(float(np.corrcoef(found, true_offset)[0, 1]), 2),
               "largest_moves_rad": {dof_names[i]: [round(float(found[i]), 3), round(float(true_offset[i]), 3)] for i in largest},
               "objective": [round(before, 1), round(after, 1)],
               "radius_factors": None if factors is None else factors.round(3).tolist(),
               "offsets_rad": {"names": list(dof_names), "fitted": found.round(4).tolist(), "true": true_offset.round(4).tolist()}}
        rows.append(row)
        print(json.dumps(row), flush=True)
        if args.json:  # rewritten after every fold: an interruption keeps the folds done
            pathlib.Path(args.json).write_text(json.dumps(rows, indent=1), encoding="utf-8")
        jax.clear_caches()
    if args.plot:
        plot_offsets(rows, args.plot)


def plot_offsets(rows, path):
    """One panel per fold: each joint angle's fitted offset from the first pass against the
    truth's (radians)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, axes = plt.subplots(len(rows), 1, figsize=(11, 2.6 * len(rows)), sharex=True, squeeze=False)
    for ax, row in zip(axes[:, 0], rows):
        offsets = row["offsets_rad"]
        x = np.arange(len(offsets["names"]))
        ax.bar(x - 0.2, offsets["true"], 0.4, label="the truth's posture less the first pass's", color="tab:green")
        ax.bar(x + 0.2, offsets["fitted"], 0.4, label="fitted to the silhouettes", color="tab:red")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel("offset, rad")
        ax.set_title(f"{row['fold']}: first pass {row['first_pass_mm']} mm, fitted frames {row['fitted_mm']} mm", fontsize=10)
    axes[0, 0].legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xticks(x, offsets["names"], rotation=60, ha="right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
