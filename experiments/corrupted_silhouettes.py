"""Paper 001's edge and foreground terms where the silhouettes are corrupted (docs/likelihood.md).

    bash experiments/video_tracking.sh                      # the films and the model (/tmp/video_study)
    python experiments/corrupted_silhouettes.py /tmp/video_study/film_160x120_4 /tmp/video_study/walk.eqx \\
        /tmp/cmu/35_03.npz [--seeds 0 1 2] [--json PATH]

Reads the film's videos and background videos, makes the silhouettes by background subtraction
(``image.subtract_background``, its defaults) and corrupts them two ways a simpler subtraction
would: cast shadows kept (the shadow test off), holes (``--holes`` disks a view and frame of
a radius in ``--hole-radius``, 1-1.5 pixels by default, cut out of each silhouette at random
pixels of it) and, with ``--thresholds``, parts missed (the subtraction's thresholds raised, so
that the parts whose colours are near the background's are lost, view after view and frame
after frame). ``--sets`` keeps some of the first three sets; ``--variant`` adds runs with
other options of the combined likelihood. Then MRPF (budget 500, the
default body or another ``--body``, the automatic start: no ground truth read, the truth only scores) tracks each set
with the silhouettes alone and with 001's edge and foreground terms added (the foreground at 001's
equal weight and at the registered 0.1, unless ``--variant`` says otherwise), the edges from the
videos' frames (Canny), and prints the mean joint error (mm) of each seed (``--save-joints DIR``
keeps each run's estimated joints).
"""

import argparse
import json
import os

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.image import fit_background, subtract_background
from jaxtrack.io import MultiViewVideo, load_keypoints, load_sequence
from jaxtrack.manifold import load_model
from jaxtrack.tracking import CALIBRATION_PRIORS, TrackingSpec, motion_clearance, prepare_test, subject_body, track_sequence

BASELINE = ("silhouette", {})
DEFAULT_VARIANTS = {"+ edge + foreground (001's equal weights)": {"foreground_weight": 1.0},
                    "+ edge + foreground x0.1 (the default)": {}}


def read(paths) -> np.ndarray:
    with MultiViewVideo(paths) as video:
        return np.concatenate([c for _, c in video.chunks(32)], axis=1)  # (C, T, H, W, 3)


def punch_holes(rng, masks, count: float, radius: tuple[float, float]):
    """``masks`` (C, T, H, W) with Poisson(``count``) disks of a radius in ``radius`` (pixels)
    cut out of each, centred at random pixels of it."""
    out = masks.copy()
    rows, cols = np.mgrid[: masks.shape[2], : masks.shape[3]]
    for c, t in np.ndindex(masks.shape[:2]):
        inside = np.argwhere(masks[c, t])
        for _ in range(rng.poisson(count)):
            y, x = inside[rng.integers(len(inside))]
            out[c, t] &= (rows - y) ** 2 + (cols - x) ** 2 > rng.uniform(*radius) ** 2
    return out


def keypoint_body(film: str, truth, manifold, validation, frames: int = 4, prior: str = "motion", silhouettes=None):
    """The body calibrated (``body="calibrate"``) on the first ``frames`` frames of the film's
    2-D keypoints (``keypoints.npz``: a detector's, noisy, some dropped), started automatically,
    as ``track_sequence`` prepares a scene, the validation take the donor whose proportions and
    clavicles centre the calibration's prior as ``prior`` says (``tracking.CALIBRATION_PRIORS``),
    the prior narrowed by the limbs measured on every frame's keypoints
    (``tracking.measure_limb_lengths``, as ``prepare_test`` does): no ground truth read. From the
    keypoints alone, or with ``silhouettes`` (C, T, H, W) as ``jaxtrack track --video --keypoints``
    does (``likelihood.calibrate_body_from_keypoints``): the limb lengths from the keypoints, then
    the radii from the silhouettes and keypoints together."""
    key = jax.random.key(0)
    validation_subject = subject_body(validation, "the validation sequence", key=key)
    layout = [str(n) for n in validation_subject.body.skeleton.pose_layout]
    clearance = motion_clearance([validation], [validation_subject.poses], skeletons=[validation_subject.body.skeleton])
    likelihood = "keypoints" if silhouettes is None else "silhouette+keypoints"
    extra = {} if silhouettes is None else {"silhouettes": silhouettes.astype(np.uint8)}
    sequence = truth.replace(keypoints2d=load_keypoints(os.path.join(film, "keypoints.npz"))[0], skeleton_offsets=None,
                             capsule_radii=None, pose=None, pose_layout=None, joints3d=None, **extra)
    options = TrackingSpec(likelihood=likelihood, body="calibrate", start="auto", body_prior=prior).scene_options()
    scene = prepare_test(sequence, likelihood, key=key, calibration_frames=frames, say=say_body, start="auto",
                         start_model=manifold,
                         root_height=float(np.mean(validation_subject.poses[:, layout.index("root_z")])),
                         ground_clearance=clearance, donors=[("the validation sequence", validation_subject, validation.subject)],
                         **options)
    return np.asarray(scene.body.skeleton.offsets, np.float64), np.asarray(scene.body.radii, np.float64)


def say_body(*message, **_) -> None:
    """Print the pipeline's lines about the body (where it came from, a calibration's lengths)."""
    if message and "body" in str(message[0]):
        print("   ", *message, flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("film")
    parser.add_argument("model")
    parser.add_argument("validation")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--holes", type=float, default=3.0, help="mean holes a view and frame")
    parser.add_argument("--hole-radius", type=float, nargs=2, default=(1.0, 1.5), help="(min, max) pixels")
    parser.add_argument("--thresholds", type=float, nargs=2, action="append", metavar=("LOW", "HIGH"),
                        help="one more set: the subtraction's hysteresis thresholds raised to these noise units "
                             "(parts whose colours are near the background's are lost; repeatable)")
    parser.add_argument("--sets", nargs="+", help="only these sets (default: all)")
    parser.add_argument("--variant", nargs=2, action="append", metavar=("LABEL", "JSON"),
                        help="a silhouette+edge+foreground run with these likelihood options, e.g. "
                             "'gated' '{\"edges_near\": 3}' (repeatable; default: its defaults)")
    parser.add_argument("--body", default="default", choices=("default", "joints", "keypoints", "video"),
                        help="the tracker's body: the default proportions; the skeleton fitted to the film's true joints, "
                             "radii withheld (a subject whose skeleton is known: an oracle for the limb lengths); or limb "
                             "lengths and radii calibrated on the first 4 frames of the film's 2-D keypoints alone "
                             "(``keypoint_body``: no ground truth read); or, ``video``, the limb lengths from those "
                             "keypoints and the radii from them and each set's own silhouettes, as ``jaxtrack track "
                             "--video --keypoints`` calibrates")
    parser.add_argument("--body-prior", default="motion", choices=CALIBRATION_PRIORS,
                        help="with --body keypoints or video: what centres the calibration's prior (default: %(default)s, the "
                             "validation take's proportions and clavicle posture: the films' subject is the model's)")
    parser.add_argument("--json")
    parser.add_argument("--no-baseline", action="store_true",
                        help="skip the silhouettes-alone runs (already made with the same seeds: they are deterministic)")
    parser.add_argument("--save-joints", metavar="DIR", help="write each run's estimated joints (T, J, 3), metres, to DIR")
    args = parser.parse_args()
    truth = load_sequence(os.path.join(args.film, "truth.npz"))
    names = [str(n) for n in truth.camera_names]
    frames = read([os.path.join(args.film, f"{n}.mp4") for n in names])
    empty = read([os.path.join(args.film, "background", f"{n}.mp4") for n in names])
    model = fit_background(np.moveaxis(empty, 1, 0))
    moving = jnp.asarray(np.moveaxis(frames, 1, 0))
    true = truth.silhouettes.astype(bool)
    sets = {
        "as made": np.asarray(subtract_background(model, moving).mask).swapaxes(0, 1),
        "shadows kept": np.asarray(subtract_background(model, moving, shadow_chroma=0.0).mask).swapaxes(0, 1),
    }
    sets["shadows kept, holes"] = punch_holes(np.random.default_rng(0), sets["shadows kept"], args.holes, args.hole_radius)
    for low, high in args.thresholds or ():
        sets[f"parts missed ({low:g}, {high:g})"] = np.asarray(subtract_background(model, moving, low=low, high=high).mask).swapaxes(0, 1)
    sets = {k: v for k, v in sets.items() if args.sets is None or k in args.sets or k.startswith("parts missed")}
    manifold, header = load_model(args.model)
    validation = load_sequence(args.validation)
    body, withheld = args.body, {}
    if args.body == "keypoints":  # the calibrated body as the file's own, the truth's joints and poses withheld
        offsets, radii = keypoint_body(args.film, truth, manifold, validation, prior=args.body_prior)
        body, withheld = "auto", {"skeleton_offsets": offsets, "capsule_radii": radii, "joints3d": None, "pose": None,
                                  "pose_layout": None}
    variants = {} if args.no_baseline else {"silhouettes alone": BASELINE}
    variants.update({k: ("silhouette+edge+foreground", json.loads(v) if isinstance(v, str) else v)
                     for k, v in (args.variant or DEFAULT_VARIANTS.items())})
    rows = []
    for label, masks in sets.items():
        iou = float(np.mean((masks & true).sum(axis=(2, 3)) / (masks | true).sum(axis=(2, 3))))
        if args.body == "video":  # calibrated on this set's silhouettes, shared by every variant
            offsets, radii = keypoint_body(args.film, truth, manifold, validation, prior=args.body_prior, silhouettes=masks)
            body, withheld = "auto", {"skeleton_offsets": offsets, "capsule_radii": radii, "joints3d": None, "pose": None,
                                      "pose_layout": None}
            print(f"{label}: radii (mm) {np.round(1000 * radii).astype(int).tolist()}", flush=True)
        sequence = truth.replace(silhouettes=masks.astype(np.uint8), images=frames, **withheld)
        for name, (likelihood, options) in variants.items():
            spec = TrackingSpec(likelihood=likelihood, likelihood_options=options, body=body, start="auto")
            for seed in args.seeds:
                _, joints, _ = track_sequence(sequence, manifold, header, "mrpf", validation, spec, seed=seed,
                                              say=say_body)
                if args.save_joints:
                    os.makedirs(args.save_joints, exist_ok=True)
                    tag = "".join(ch if ch.isalnum() else "_" for ch in f"{label}_{name}_s{seed}")
                    np.save(os.path.join(args.save_joints, tag + ".npy"), np.asarray(joints))
                error = 1000 * float(np.mean(np.linalg.norm(np.asarray(joints) - truth.joints3d[: len(joints)], axis=-1)))
                rows.append({"silhouettes": label, "iou": iou, "run": name, "likelihood": likelihood, "options": options,
                             "seed": seed, "error_mm": error})
                print(f"{label} (IoU {iou:.3f}), {name}, seed {seed}: {error:.1f} mm", flush=True)
    print()
    print("| silhouettes | " + " | ".join(variants) + " |")
    print("|---|" + "---:|" * len(variants))
    for label in sets:
        cells = [np.mean([r["error_mm"] for r in rows if r["silhouettes"] == label and r["run"] == k]) for k in variants]
        print(f"| {label} | " + " | ".join(f"{c:.1f}" for c in cells) + " |")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(rows, handle, indent=1)
    jax.clear_caches()


if __name__ == "__main__":
    main()
