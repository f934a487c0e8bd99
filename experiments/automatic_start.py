"""How often the automatic start lands near the truth (docs/video.md).

    jaxtrack scene MOTION.npz --rgb --video DIR ...      # a filmed scene with truth.npz
    jaxtrack fit TRAIN.npz ... --out walk.eqx
    python experiments/automatic_start.py DIR walk.eqx VALIDATION.npz [--likelihood silhouette+keypoints]
        [--starts 10] [--keys 2] [--body default] [--silhouettes true|video] [--height-spread M] [--json PATH]

Starts the search at ``--starts`` frames spread over the take (each as if it were the first),
with ``--keys`` search keys each, on the renderer's true silhouettes (``truth.npz``) or, with
``--silhouettes video``, on those background subtraction gives from the film's videos (with a
keypoint likelihood, ``keypoints.npz`` too), the root's height held (``--height-spread 0``, the
default) or searched with that spread (metres; 0.03 before 2026-12-02), and prints the mean joint error of each start, the
shares within 50 mm and 100 mm, and the floor: the same body given the true joints.
"""

import argparse
import json
import os

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.body import forward_kinematics
from jaxtrack.io import load_keypoints, load_sequence
from jaxtrack.manifold import load_model
from jaxtrack.tracking import StartSearch, automatic_start, prepare_test, sequence_from_video, subject_body


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("folder")
    parser.add_argument("model")
    parser.add_argument("validation")
    parser.add_argument("--likelihood", default="silhouette")
    parser.add_argument("--starts", type=int, default=10)
    parser.add_argument("--keys", type=int, default=2)
    parser.add_argument("--body", default="default")
    parser.add_argument("--silhouettes", choices=("true", "video"), default="true")
    parser.add_argument("--height-spread", type=float, default=0.0)
    parser.add_argument("--json")
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    sequence = load_sequence(os.path.join(args.folder, "truth.npz"))
    if "keypoints" in args.likelihood:
        sequence = sequence.replace(keypoints2d=load_keypoints(os.path.join(args.folder, "keypoints.npz"))[0])
    if args.silhouettes == "video":
        cameras = [c["name"] for c in json.load(open(os.path.join(args.folder, "calibration.json"), encoding="utf-8"))["cameras"]]
        filmed = sequence_from_video([os.path.join(args.folder, f"{c}.mp4") for c in cameras], sequence.rig(),
                                     background=[os.path.join(args.folder, "background", f"{c}.mp4") for c in cameras])
        sequence = sequence.replace(silhouettes=filmed.sequence.silhouettes)
    search = StartSearch(height_spread=args.height_spread)
    model, _ = load_model(args.model)
    validation = subject_body(load_sequence(args.validation), "validation", key=jax.random.key(0))
    layout = [str(n) for n in validation.body.skeleton.pose_layout]
    height = float(np.mean(validation.poses[:, layout.index("root_z")]))
    rows = []
    for first in np.linspace(0, sequence.num_frames - 2, args.starts).round().astype(int):
        cut = sequence.replace(**{k: getattr(sequence, k)[:, first:] for k in ("silhouettes", "keypoints2d")
                                  if getattr(sequence, k) is not None},
                               joints3d=sequence.joints3d[first:], pose=sequence.pose[first:])
        scene = prepare_test(cut, f"frame {first}", key=jax.random.key(0), body=args.body, likelihood=args.likelihood, frames=2,
                             pixel_samples=None)
        rig = cut.rig(dtype=jnp.float32)
        for key in range(args.keys):
            pose, info = automatic_start(
                jax.random.key(key), scene.likelihood, scene.observations, model, rig, scene.body.skeleton, root_height=height,
                search=search, silhouettes=cut.silhouettes[:, 0],
                keypoints=None if cut.keypoints2d is None else cut.keypoints2d[:, 0])
            joints = np.asarray(forward_kinematics(scene.body.skeleton, jnp.asarray(pose, jnp.float32)), np.float64)
            error = 1000 * float(np.mean(np.linalg.norm(joints - scene.truth_joints[0], axis=-1)))
            rows.append({"frame": int(first), "key": key, "error_mm": error, "floor_mm": scene.start_error_mm,
                         "placed_by": info["placed_by"]})
            print(f"frame {first:3d} key {key}: {error:6.1f} mm (the body's floor {scene.start_error_mm:.1f} mm; "
                  f"placed by the {info['placed_by']})", flush=True)
    errors = np.array([r["error_mm"] for r in rows])
    print(f"{args.likelihood} on the {args.silhouettes} silhouettes, height spread {args.height_spread:g} m: "
          f"{len(errors)} starts: within 50 mm {np.mean(errors < 50):.0%}, within 100 mm "
          f"{np.mean(errors < 100):.0%}; median {np.median(errors):.1f} mm, worst {errors.max():.1f} mm")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(rows, handle, indent=1)


if __name__ == "__main__":
    main()
