"""A film with what a real rig's recording has (issue #91), from the library's own renderer:
4 portrait cameras at 1088x1920 (the 272x480 film of ``jaxtrack scene --rgb --video`` upscaled 4
times: the renderer cannot film at 1088x1920 in 24 GB), a second person walking through C1 and C2
(a flat-coloured figure composited over the first, so not occluded by depth), C2 and C3 written 8
px narrower than the calibration says (an encoder's crop), no empty-scene video, and the
detector's keypoints scaled to 1088x1920: of the first person only (``keypoints.npz``), and as
OpenPose BODY_25B folders (``openpose/C1`` ...) with the second person's detections in C1 and C2,
listed first and more confident (docs/video.md, "A portrait HD rig").

    jaxtrack scene walk.npz --rgb --video film_lo --frames 100 --width 272 --height 480 --views 4
    python experiments/hd_rig_film.py film --low film_lo --other other.npz --out film_hd
    python experiments/hd_rig_film.py score --truth film_lo/truth.npz est.npz

``score``: an estimate's joint error against the truth (000 eq. 31), mean, frame 0 and per quarter
of the frames it holds.
"""

from __future__ import annotations

import argparse
import os

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.data import NO_NOISE, PhotoSettings, SolidBody, render_rgb, scene_from_sequence
from jaxtrack.io import MultiViewVideo, VideoWriter, load_keypoints, load_sequence, save_calibration, save_keypoints

SCALE = 4
CROPPED = (1, 2)  # C2 and C3: 8 px narrower
SECOND_PERSON_VIEWS = (0, 1)  # C1 and C2
SHIRT = np.array([40, 90, 160], np.uint8)


def _quarters(values) -> list[float]:
    return [float(np.median(q)) for q in np.array_split(values, 4)]


def score(args) -> None:
    """The estimate's joint error against the truth and against a triangulation of the same
    keypoints, per quarter; and its reprojection error onto the keypoints beside the
    triangulation's and the truth's (the floor the detector's noise sets), per camera and quarter
    (median px over the joints each camera sees)."""
    from jaxtrack.camera import project_points
    from jaxtrack.tracking import triangulate

    truth, estimate = load_sequence(args.truth), load_sequence(args.estimate)
    count = estimate.num_frames
    error = 1000.0 * np.linalg.norm(estimate.joints3d - truth.joints3d[:count], axis=-1).mean(axis=-1)
    quarters = [float(q.mean()) for q in np.array_split(error, 4)]
    print(f"{args.estimate}: {count} of {truth.num_frames} frames, {error.mean():.0f} mm, frame 0 {error[0]:.0f} mm, quarters "
          + " / ".join(f"{q:.0f}" for q in quarters) + f" mm (last over first {quarters[-1] / quarters[0]:.2f})")
    if estimate.keypoints2d is None:
        return
    rig = estimate.rig(dtype=np.float64)
    keypoints = np.asarray(estimate.keypoints2d[:, :count], np.float64)  # (C, T, 15, 3), the videos' pixels
    points, seen = triangulate(rig, keypoints[..., :2], keypoints[..., 2])  # (T, 15, 3)
    both = seen.all(axis=1)
    gap = 1000.0 * np.linalg.norm(points - truth.joints3d[:count], axis=-1).mean(axis=-1)
    apart = 1000.0 * np.linalg.norm(estimate.joints3d - points, axis=-1).mean(axis=-1)
    print("triangulation against the truth, per quarter: " + " / ".join(f"{q:.0f}" for q in _quarters(gap[both])) + " mm; "
          "the estimate against the triangulation: " + " / ".join(f"{q:.0f}" for q in _quarters(apart[both])) + " mm")
    for name, joints in (("estimate", estimate.joints3d), ("triangulation", points), ("the truth", truth.joints3d[:count])):
        pixels = np.moveaxis(np.asarray(project_points(rig, jnp.asarray(joints, jnp.float32))[0], np.float64), 2, 0)  # (C, T, 15, 2)
        off = np.linalg.norm(pixels - keypoints[..., :2], axis=-1)
        off = np.where(keypoints[..., 2] > 0, off, np.nan)
        per_camera = [[float(np.nanmedian(q)) for q in np.array_split(off[c], 4)] for c in range(len(rig.names))]
        print(f"{name} onto the keypoints, median px per quarter: "
              + "; ".join(f"{n} " + "/".join(f"{v:.0f}" for v in row) for n, row in zip(rig.names, per_camera)))


# BODY_25B's points from the 15 HumanEva joints: the head's five at the head (so the reader tells
# the layout from their spread), the upper neck between thorax and head, the feet undetected.
_BODY25B_FROM = (("head",),) * 5 + tuple((n,) for n in ("lshoulder", "rshoulder", "lelbow", "relbow", "lwrist", "rwrist", "lhip",
                                                         "rhip", "lknee", "rknee", "lankle", "rankle")) + (("thorax", "head"), ("head",))
_BODY25B_FEET = 6


def _body25b(joints) -> np.ndarray:
    """(..., 15, 3) HumanEva keypoints -> (..., 25, 3) BODY_25B points (the feet at confidence 0)."""
    from jaxtrack.body import HUMANEVA_JOINTS

    out = np.zeros(joints.shape[:-2] + (len(_BODY25B_FROM) + _BODY25B_FEET, 3))
    for k, names in enumerate(_BODY25B_FROM):
        index = [HUMANEVA_JOINTS.index(n) for n in names]
        confidence = joints[..., index, 2].min(axis=-1)
        out[..., k, :2] = np.where(confidence[..., None] > 0, joints[..., index, :2].mean(axis=-2), 0.0)
        out[..., k, 2] = confidence
    return out


def write_openpose(folder, keypoints, bystander, rig_hd, names) -> None:
    """One OpenPose BODY_25B folder per camera, as OpenPose writes them: the tracked person's
    detections, and in the second person's views that person's too, listed first and more
    confident (the detector's 20 px noise at 1088x1920, 10 % dropped, confidence 0.95 against
    0.9), so that each camera's most confident detection is the wrong person there."""
    import json

    from jaxtrack.data import DetectorNoise, detect_keypoints

    other = detect_keypoints(jax.random.key(11), bystander, rig_hd, DetectorNoise(noise_px=5.0 * SCALE, confidence=0.95))
    for c, name in enumerate(names):
        os.makedirs(os.path.join(folder, name), exist_ok=True)
        for t in range(keypoints.shape[1]):
            people = ([other[c, t]] if c in SECOND_PERSON_VIEWS and other[c, t, :, 2].any() else []) + [keypoints[c, t]]
            entries = [{"person_id": [-1], "pose_keypoints_2d": np.round(_body25b(p), 3).ravel().tolist()} for p in people]
            with open(os.path.join(folder, name, f"{name}_{t:012d}_keypoints.json"), "w") as handle:
                json.dump({"version": 1.3, "people": entries}, handle)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    film_ = sub.add_parser("film")
    film_.add_argument("--low", required=True, help="the folder jaxtrack scene --rgb --video wrote")
    film_.add_argument("--other", required=True, help="the second person's motion (a sequence file)")
    film_.add_argument("--out", required=True)
    score_ = sub.add_parser("score")
    score_.add_argument("--truth", required=True)
    score_.add_argument("estimate")
    args = parser.parse_args()
    (film if args.command == "film" else score)(args)


def film(args) -> None:
    os.makedirs(args.out, exist_ok=True)
    truth = load_sequence(os.path.join(args.low, "truth.npz"))
    rig = truth.rig(dtype=np.float64)
    names = [str(n) for n in rig.names]
    with MultiViewVideo([os.path.join(args.low, f"{n}.mp4") for n in names]) as video:
        frames = np.concatenate([block for _, block in video.chunks(50)], axis=1)  # (C, T, h, w, 3)
    count = frames.shape[1]
    other = scene_from_sequence(jax.random.key(9), load_sequence(args.other), rig, NO_NOISE, frames=count, progress=False)
    pose = np.asarray(other.pose).copy()
    pose[:, :2] += [1.6, 1.2]  # beside the first person's path
    quiet = PhotoSettings(sensor_noise=0.0, lighting_change=0.0, shadow_strength=0.0)
    _, masks = render_rgb(jax.random.key(3), SolidBody(other.body().skeleton), rig, pose, settings=quiet, chunk=10)
    masks = np.asarray(masks)
    for c in SECOND_PERSON_VIEWS:
        frames[c][masks[c]] = SHIRT
    for c, name in enumerate(names):
        view = np.repeat(np.repeat(frames[c], SCALE, axis=1), SCALE, axis=2)  # (T, H, W, 3)
        if c in CROPPED:
            view = view[:, :, :-8]
        with VideoWriter([os.path.join(args.out, f"{name}.mp4")], truth.fps) as writer:
            for start in range(0, count, 25):
                writer.write(view[None, start:start + 25])
    width, height = (int(v) for v in rig.image_size[0])
    save_calibration(os.path.join(args.out, "calibration.json"), rig.resized(SCALE * width, SCALE * height))
    keypoints, camera_names = load_keypoints(os.path.join(args.low, "keypoints.npz"))
    keypoints = keypoints.copy()  # pixel centres at integer coordinates, as the intrinsics
    keypoints[..., :2] = np.where(keypoints[..., 2:] > 0, (keypoints[..., :2] + 0.5) * SCALE - 0.5, keypoints[..., :2])
    save_keypoints(os.path.join(args.out, "keypoints.npz"), keypoints, camera_names)
    bystander = np.asarray(other.joints3d) + np.array([1.6, 1.2, 0.0])  # as its pose was moved
    write_openpose(os.path.join(args.out, "openpose"), keypoints, bystander, rig.resized(SCALE * width, SCALE * height), names)
    print(f"wrote {count} frames of {len(names)} {SCALE * width}x{SCALE * height} cameras into {args.out} "
          f"({', '.join(names[c] for c in CROPPED)} 8 px narrower; a second person in {', '.join(names[c] for c in SECOND_PERSON_VIEWS)})")


if __name__ == "__main__":
    main()
