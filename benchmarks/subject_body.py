"""The subject's own body: tracking a person whose body is not the default, from files that
carry only joint positions, silhouettes and cameras (what HumanEva hands out).

The test subject's limb lengths are 10-14 % off the default, longer and shorter per limb
(spine +12 %, neck -10 %, shoulders +10 %, upper arms -13 %, forearms +13 %, hips -12 %, thighs
+12 %, shins -14 %), its capsules 20 % thicker. Its walk and jog are rendered twice: by the
library's capsules, and by a renderer that is not the tracker's (``data.SolidBody``: ellipsoids
with feet, hands and an elliptical torso, ray-cast exactly). The trackers are fitted once on the
demo's training and validation motion (subjects S1 and S2), then track each scene with the body

- ``default``: the default body, the start pose solved on it by inverse kinematics;
- ``joints``: the skeleton inverse kinematics fits to the file's joints (``body="auto"``), the
  capsule radii fitted to 12 frames spread over the scene at the joints' poses (``prepare_test``'s
  ``fit_radii``, on by default for such files since 2026-11-29);
- ``joints-default-radii``: the same skeleton with the default radii (``fit_radii=False``: the
  ``joints`` condition before 2026-11-29); ``joints-fitted-radii``: the radii fitted whatever the
  person's size in pixels (``fit_radii=True``);
- ``calibrated``: limb lengths and radii fitted to the first 4 frames' silhouettes from the
  default body (``likelihood.calibrate_body``), then frame 0's joints solved on the calibrated
  skeleton for the start (the file's joints are used for nothing else); a calibration that does
  not converge is reported and that scene not tracked;
- ``refined``: ``calibrated``, then one run of ``--refine-with`` (MRPF) tracks the scene and the
  body is calibrated again on tracked frames spread over the sequence (``tracking.refine_body``),
  the start re-solved on the refined skeleton; every tracker then tracks with that body;
- ``keypoints``: the file also carries 2-D keypoints (the true joints projected, N(0,
  ``--keypoint-noise`` px) added, 10 % missing: a good detector); the body is calibrated with
  ``likelihood="silhouette+keypoints"`` (``tracking.prepare_test``: the limb lengths from the
  keypoints, then the radii from both cues, ``likelihood.calibrate_body_from_keypoints``; both cues
  at once before 2026-12-06), then frame 0's joints solved on it for the start; the trackers track
  the silhouettes alone with that body, as in the other conditions;
- ``keypoints-refined``: ``keypoints``, then the second pass on a ``--refine-with`` run that
  tracks both cues (``tracking.refine_body``, its lengths from the keypoints as the first pass's);
- ``truth-calibrated``: the second pass (``tracking.refine_body``) run on the true body and the
  true poses, its prior centred on the truth: what a silhouette calibration gives when it starts
  at the right answer, the floor of every ``calibrated`` and ``refined`` run (docs/body.md, "The
  floor of a calibration from silhouettes");
- ``true``: the subject's own skeleton and capsule radii written into the file;
- ``true-shape``: the subject's own skeleton, and the radii fitted to ``--shape-frames``
  frames' silhouettes spread over the scene at the true poses (the lengths held:
  ``calibrate_body`` with tight priors): how much of a renderer's shape the capsules can take up.

    taskset -c 0,1 python benchmarks/subject_body.py --runs 5 --budget 500 --json subject_body.json

Prints per setting (views, image size) and renderer a table of each tracker's mean error (mm,
000 eq. 31, mean over runs and the two scenes), the start pose's error and the error at frame 0.
"""

from __future__ import annotations

import argparse
import time

from bench_output import add_output_arguments, pin_threads, write_json

LIMB_FACTORS = (("spine", 1.12), ("neck", 0.9), ("shoulder", 1.1), ("upper_arm", 0.87), ("forearm", 1.13), ("hip", 0.88),
                ("thigh", 1.12), ("shin", 0.86))
RADIUS_FACTOR = 1.2
CONDITIONS = ("default", "joints", "joints-default-radii", "joints-fitted-radii", "calibrated", "refined", "keypoints",
              "keypoints-refined", "truth-calibrated", "true", "true-shape")
SETTINGS = {"4x160x120": (4, 160, 120), "3x80x60": (3, 80, 60)}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--methods", nargs="+", default=["sir", "apf", "mrpf", "gpapf", "latentpf", "glegbpf"])
    parser.add_argument("--budget", type=int, default=500)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=list(SETTINGS))
    parser.add_argument("--renderers", nargs="+", default=["capsules", "solid"], choices=["capsules", "solid"])
    parser.add_argument("--conditions", nargs="+", default=list(CONDITIONS), choices=list(CONDITIONS))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--keypoint-noise", type=float, default=1.0, help="the keypoints condition's detection noise, pixels (sd)")
    parser.add_argument("--refine-with", default="mrpf", help="the tracker whose run the refined condition calibrates on")
    parser.add_argument("--shape-frames", type=int, default=12, help="frames the true-shape condition fits the radii on")
    parser.add_argument("--refine-frames", type=int, default=None,
                        help="frames of the refined condition's second pass (default: tracking.refine_frame_count, 12 at 4x160x120)")
    parser.add_argument("--refine-passes", type=int, default=1,
                        help="the refined condition's passes on tracked frames, each on a run with the last pass's body (default 1)")
    add_output_arguments(parser, plot="draw frame 0 of the walk in the first setting's views, rendered by both renderers, "
                                      "to this PNG (docs/figures/solid_body.png) before the runs")
    parser.add_argument("--plot-only", action="store_true", help="draw the figure and stop")
    args = parser.parse_args()
    pin_threads(args.threads)
    import dataclasses

    import jax
    import numpy as np

    from jaxtrack.body import forward_kinematics, inverse_kinematics
    from jaxtrack.camera import default_rig
    from jaxtrack.data import DetectorNoise, SilhouetteNoise, SolidBody, SubjectStyle, build_scene, detect_keypoints, generate_motion
    from jaxtrack.demo import demo_sequences
    from jaxtrack.errors import ConfigurationError
    from jaxtrack.evaluation import mean_joint_error_mm, per_frame_error_mm
    from jaxtrack.experiment import ExperimentConfig, shared_window
    from jaxtrack.likelihood import body_of, calibrate_body, with_body
    from jaxtrack.tracking import (
        add_ground_prior,
        build_tracker,
        fit_manifold,
        fit_tracker,
        get_tracker,
        limb_lengths_of,
        motion_clearance,
        motion_data,
        prepare_test,
        refine_body,
        sequence_poses,
        track_runs,
        tracker_keys,
    )

    key = jax.random.key(args.seed)
    subject = SubjectStyle("X", limb_lengths=LIMB_FACTORS, radius_scale=RADIUS_FACTOR)
    motions_x = [generate_motion(gait, subject, num_frames=args.frames, fps=60.0, key=jax.random.fold_in(key, 500 + i))
                 for i, gait in enumerate(("walk", "jog"))]
    if args.plot:
        plot_renderers(motions_x[0], SETTINGS[args.settings[0]], args.plot)
        if args.plot_only:
            return
    train, validation, _, _ = demo_sequences(key)
    refining = any(c.endswith("refined") for c in args.conditions)
    fitted_methods = list(dict.fromkeys([*args.methods, *([args.refine_with] if refining else [])]))
    config = ExperimentConfig(methods=tuple(fitted_methods), budget=args.budget, runs=args.runs, fit_steps=100, seed=args.seed)
    train_poses = [sequence_poses(s, "train", key=key) for s in train]
    validation_poses = [sequence_poses(s, "validation", key=key) for s in validation]
    motions = {None: motion_data(train_poses, validation_poses)}
    for kind, latent_dim in config.manifold_specs:
        model, _, starts = fit_manifold(train_poses, latent_dim, config.fit_steps, kind=kind)
        motions[kind, latent_dim] = motion_data(train_poses, validation_poses, model, starts)
    fitted, roots = {}, {}
    for method in fitted_methods:
        fit_key, roots[method] = tracker_keys(args.seed, method)
        fitted[method] = fit_tracker(get_tracker(method), fit_key, motions[config.manifold_spec_of(method)])
    clearance = motion_clearance(validation, validation_poses)

    def make_tracker(method, scene):
        return build_tracker(get_tracker(method), fitted[method], scene.likelihood, config.tracking_budget,
                             velocity_from=validation_poses if config.velocity_of(method) else None,
                             residual_from=validation_poses, residual_scale=config.residual_of(method),
                             residual_decay=config.residual_decay_of(method))

    def keypoint_body(scene, test, gait, refine):
        """``scene`` with the body calibrated from its silhouettes and keypoints (or the keypoints
        alone), with ``refine`` calibrated again on a ``--refine-with`` run with both cues, the start
        solved on it from frame 0's joints."""
        noise = DetectorNoise(noise_px=args.keypoint_noise)
        rig = scene.likelihood.rig
        detected = test.replace(keypoints2d=detect_keypoints(jax.random.fold_in(key, 700), test.joints3d, rig, noise))
        calibrated = prepare_test(detected, f"X {gait}", key=key, body="calibrate", likelihood="silhouette+keypoints",
                                  likelihood_options={"sigma_px": max(args.keypoint_noise, 1.0)}, ground_clearance=clearance,
                                  window=window)
        if refine:
            calibrated = add_ground_prior(calibrated, clearance)
            tracker = make_tracker(args.refine_with, calibrated)
            first, _, _ = track_runs(tracker, jax.random.fold_in(roots[args.refine_with], 10_000)[None], calibrated)
            calibrated = refine_body(calibrated, first[0], key=key, frames=args.refine_frames, start_joints=calibrated.truth_joints[0])
        body = calibrated.body
        start = inverse_kinematics(np.asarray(scene.truth_joints[0], np.float64)[None], skeleton=body.skeleton, key=key,
                                   dtype=jax.numpy.float64).pose[0]
        start = jax.numpy.asarray(start, scene.initial_pose.dtype)
        error = 1000.0 * float(np.mean(np.linalg.norm(np.asarray(forward_kinematics(body.skeleton, start), np.float64)
                                                      - scene.truth_joints[0], axis=-1)))
        return dataclasses.replace(scene, likelihood=with_body(scene.likelihood, body), body=body, initial_pose=start,
                                   body_calibration=calibrated.body_calibration, start_error_mm=error)

    def fitted_shape(scene):
        """``scene`` (its body the subject's skeleton) with the radii fitted at the true poses of
        ``--shape-frames`` frames, the limb lengths held."""
        frames = np.round(np.linspace(0, scene.num_frames - 1, args.shape_frames)).astype(int)
        observations = jax.tree.map(lambda x: x[frames], scene.observations)
        fitted, _, report = calibrate_body(scene.likelihood, np.asarray(scene.truth_poses, np.float64)[frames], observations,
                                           prior_lengths=limb_lengths_of(scene.body), scale_sd=1e-4, proportion_sd=1e-4,
                                           pose_sd_m=0.005, pose_sd_rad=0.01, neutral_dofs=())
        return dataclasses.replace(scene, likelihood=with_body(scene.likelihood, body_of(fitted)), body=body_of(fitted),
                                   body_calibration=report)

    rows = []
    for setting in args.settings:
        views, width, height = SETTINGS[setting]
        rig = default_rig(width, height, num_views=views)
        for renderer in args.renderers:
            scenes = []
            for i, motion in enumerate(motions_x):
                solid = SolidBody(motion.body.skeleton) if renderer == "solid" else None
                scenes.append(build_scene(jax.random.fold_in(key, 600 + i), motion, rig, SilhouetteNoise(), solid=solid))
            window = shared_window(scenes, None)  # one window shape: each tracker compiles once per setting
            for condition in args.conditions:
                start = time.perf_counter()
                row = {"setting": setting, "renderer": renderer, "condition": condition, "methods": {}, "scenes": {}}
                if condition == "refined":
                    row["refine_passes"] = args.refine_passes
                for scene_seq, gait in zip(scenes, ("walk", "jog")):
                    keep = ("skeleton_offsets", "capsule_radii") if condition.startswith("true") or condition == "truth-calibrated" else ()
                    drop = {k: None for k in ("pose", "pose_layout", "skeleton_offsets", "capsule_radii") if k not in keep}
                    test = scene_seq.replace(**drop)
                    body = {"default": "default", "joints": "auto", "calibrated": "calibrate", "refined": "calibrate",
                            "keypoints": "default", "keypoints-refined": "default"}.get(condition, "auto")
                    fit_radii = {"joints-default-radii": False, "joints-fitted-radii": True}.get(condition)
                    try:
                        scene = prepare_test(test, f"X {gait}", key=key, body=body, window=window, ground_clearance=clearance,
                                             fit_radii=fit_radii)
                        if condition.startswith("keypoints"):
                            scene = keypoint_body(scene, test, gait, refine=condition == "keypoints-refined")
                    except ConfigurationError as err:  # a calibration that did not converge: reported, not tracked
                        row["scenes"][gait] = {"refused": str(err)}
                        print(f"{setting} {renderer} {condition} {gait}: refused: {err}", flush=True)
                        continue
                    scene = add_ground_prior(scene, clearance)
                    if condition == "true-shape":
                        scene = fitted_shape(scene)
                    try:
                        if condition == "truth-calibrated":  # the second pass from the right answer: its floor
                            scene = refine_body(scene, np.asarray(motions_x[gait == "jog"].pose), key=key, frames=args.refine_frames,
                                                start_joints=scene.truth_joints[0])
                        for _ in range(args.refine_passes if condition == "refined" else 0):
                            tracker = make_tracker(args.refine_with, scene)
                            first, _, _ = track_runs(tracker, jax.random.fold_in(roots[args.refine_with], 10_000)[None], scene)
                            scene = refine_body(scene, first[0], key=key, frames=args.refine_frames, start_joints=scene.truth_joints[0])
                    except ConfigurationError as err:
                        row["scenes"][gait] = {"refused": str(err)}
                        print(f"{setting} {renderer} {condition} {gait}: refused: {err}", flush=True)
                        continue
                    info = {"body": scene.body_source, "start_error_mm": scene.start_error_mm}
                    if scene.body_calibration is not None:
                        info["calibration"] = scene.body_calibration.summary()
                    if scene.subject is not None and scene.subject.residual_mm is not None:
                        info["ik_residual_frame0_mm"] = float(np.mean(scene.subject.residual_mm[0]))
                    row["scenes"][gait] = info
                    for method in args.methods:
                        tracker = make_tracker(method, scene)
                        keys = jax.numpy.stack([jax.random.fold_in(roots[method], r) for r in range(args.runs)])
                        _, joints, _ = track_runs(tracker, keys, scene)
                        errors = [float(mean_joint_error_mm(j, scene.truth_joints)) for j in joints]
                        frame0 = [float(per_frame_error_mm(j, scene.truth_joints)[0]) for j in joints]
                        entry = row["methods"].setdefault(method, {"error_mm_per_run": {}, "frame0_mm": {}})
                        entry["error_mm_per_run"][gait] = errors
                        entry["frame0_mm"][gait] = float(np.mean(frame0))
                if not row["methods"]:
                    rows.append(row)
                    continue
                for entry in row["methods"].values():
                    entry["error_mm_mean"] = float(np.mean([np.mean(v) for v in entry["error_mm_per_run"].values()]))
                row["seconds"] = time.perf_counter() - start
                rows.append(row)
                write_json(rows, args.json)
                starts = ", ".join(f"{g} start {v['start_error_mm']:.1f} mm" for g, v in row["scenes"].items() if "refused" not in v)
                cells = "  ".join(f"{get_tracker(m).label} {e['error_mm_mean']:.1f} (f0 {np.mean(list(e['frame0_mm'].values())):.1f})"
                                  for m, e in row["methods"].items())
                print(f"{setting} {renderer:>8} {condition:>10}: {starts}; {cells} [{row['seconds']:.0f} s]", flush=True)
    print()
    for setting in args.settings:
        for renderer in args.renderers:
            print(f"\n{setting}, rendered by {renderer}: mean error (mm) over {args.runs} runs and both scenes\n")
            print("| body | start | " + " | ".join(get_tracker(m).label for m in args.methods) + " |")
            print("|---|---:|" + "---:|" * len(args.methods))
            for row in rows:
                if row["setting"] == setting and row["renderer"] == renderer and row["methods"]:
                    start = np.mean([v["start_error_mm"] for v in row["scenes"].values() if "refused" not in v])
                    print(f"| {row['condition']} | {start:.1f} | " + " | ".join(f"{row['methods'][m]['error_mm_mean']:.1f}"
                                                                          for m in args.methods) + " |")


def plot_renderers(motion, setting, path):
    """Frame 0 of ``motion`` in every view: the capsules (top) and the solid body (bottom)."""
    import jax
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from jaxtrack.camera import default_rig
    from jaxtrack.data import NO_NOISE, SolidBody, build_scene

    views, width, height = setting
    rig = default_rig(width, height, num_views=views)
    rows = [build_scene(jax.random.key(0), motion, rig, NO_NOISE, solid=solid).silhouettes[:, 0]
            for solid in (None, SolidBody(motion.body.skeleton))]
    fig, axes = plt.subplots(2, views, figsize=(2.2 * views, 4.2), squeeze=False)
    for r, (masks, label) in enumerate(zip(rows, ("capsules (the tracker's body)", "SolidBody (ray-cast ellipsoids)"))):
        for c in range(views):
            ax = axes[r, c]
            ax.imshow(masks[c], cmap="gray", interpolation="nearest")
            ys, xs = (masks[c] > 0).nonzero()
            pad = 6
            ax.set_xlim(max(xs.min() - pad, 0), min(xs.max() + pad, width - 1))
            ax.set_ylim(min(ys.max() + pad, height - 1), max(ys.min() - pad, 0))
            ax.set_xticks([])
            ax.set_yticks([])
            if c == 0:
                ax.set_ylabel(label, fontsize=8)
    fig.suptitle("the test subject's walk, frame 0, clean silhouettes (cropped)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
