"""How near a manifold can get to poses of a take it was not trained on, by each way of
encoding a pose (issue #13): the test take's joint angles are encoded, decoded and scored by
forward kinematics in mm, for the GPDM the manifold trackers run on, on the protocols of
``real_motion.py``. Encoders:

- ``projection``: ``encode``'s default, the nearest point of the mean surface in joint angles;
- ``likelihood``: 003 eq. 5, ``encode(..., method="likelihood")``, what the trackers used to
  start from (and GPAPF to project its estimates with);
- ``nearest``: the latent point of the training pose nearest in joint angles, decoded.

    taskset -c 0,1 python experiments/encode_floor.py --cmu /tmp/cmu --bandai /tmp/bandai --json floor.json

Prints one row per (sequence, latent dimension): the mean over the test frames and the error at
frame 0, where every tracker starts.
"""

from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "benchmarks"))  # bench_output, real_motion
from bench_output import write_json
from real_motion import PROTOCOLS, add_protocol_arguments, load_protocol_takes, protocol_names


def joint_error_mm(skeleton, truth, angles):
    """(T,) mean joint error (mm) of the truth poses (T, D) with their joint angles replaced."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack.body import GLOBAL_DOFS, forward_kinematics

    poses = np.concatenate([truth[:, :GLOBAL_DOFS], np.asarray(angles)], axis=1)
    with jax.enable_x64(True):
        joints = forward_kinematics(skeleton, jnp.asarray(poses))
        expected = forward_kinematics(skeleton, jnp.asarray(truth))
    return 1000 * np.linalg.norm(np.asarray(joints) - np.asarray(expected), axis=-1).mean(axis=-1)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_protocol_arguments(parser)
    parser.add_argument("--latent-dim", type=int, nargs="+", default=[2, 3])
    parser.add_argument("--kind", default="gpdm", choices=["gpdm", "bc-gplvm"])
    parser.add_argument("--fit-steps", type=int, default=200)
    parser.add_argument("--json", help="also write the results to this JSON file")
    args = parser.parse_args()
    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack.body import GLOBAL_DOFS
    from jaxtrack.tracking import fit_manifold, sequence_poses

    folders = {"cmu": args.cmu, "bandai": args.bandai}
    rows = []
    print("| sequence | latent dim | projection: mean, frame 0 | 003 eq. 5: mean, frame 0 | nearest training pose: mean, frame 0 |")
    print("|---|---:|---|---|---|")
    for name in protocol_names(args.sequences):
        _dataset, train_takes, _validation, test_take, frames = PROTOCOLS[name]
        key = jax.random.key(0)
        sequences = load_protocol_takes(parser, folders, name, [*train_takes, test_take])
        train = [sequence_poses(sequences[t], t, key=key) for t in train_takes]
        test = sequence_poses(sequences[test_take], test_take, key=key)[:frames]
        skeleton = sequences[test_take].body(jnp.float64).skeleton
        for latent_dim in args.latent_dim:
            model, _info, _starts = fit_manifold(train, latent_dim, args.fit_steps, kind=args.kind)
            with jax.enable_x64(True):
                angles = jnp.asarray(test[:, GLOBAL_DOFS:])
                training = np.asarray(model.mean + model.scale * model.data)
                nearest = np.argmin(((np.asarray(angles)[:, None] - training[None]) ** 2).sum(-1), axis=1)
                decoded = {
                    "projection": model.decode(model.encode(angles))[0],
                    "likelihood": model.decode(model.encode(angles, method="likelihood"))[0],
                    "nearest": model.decode(model.training_latent()[nearest])[0],
                }
            errors = {k: joint_error_mm(skeleton, test, v) for k, v in decoded.items()}
            cells = " | ".join(f"{e.mean():.1f}, {e[0]:.1f}" for e in errors.values())
            print(f"| {name} | {latent_dim} | {cells} |", flush=True)
            rows.append({"sequence": name, "latent_dim": latent_dim, "kind": args.kind, "frames": len(test),
                         **{f"{k}_mm_mean": float(e.mean()) for k, e in errors.items()},
                         **{f"{k}_mm_frame0": float(e[0]) for k, e in errors.items()}})
            write_json(rows, args.json)


if __name__ == "__main__":
    main()
