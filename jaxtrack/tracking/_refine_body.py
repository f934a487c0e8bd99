"""A second body calibration pass on tracked frames spread over the sequence.

The first calibration (``prepare_test(body="calibrate")``, ``likelihood.calibrate_body``) fits
the first few frames, where a walk holds the knees and elbows nearly straight and the limbs'
lengths trade against each other along each chain; what it leaves is the proportions' prior
pulling every limb toward the default's (docs/body.md, "The limb lengths are the whole gap").
Once a tracker has run, its estimates give poses over the whole sequence, where the knees bend
and the arms swing: ``refine_body`` calibrates again on frames spread evenly from frame 0 to the
last (12 at 4 views of 160x120, more for smaller images: ``refine_frame_count``), each started at
its tracked pose (free, as in the first pass), the first pass's body the prior's centre, with a
wider prior on each limb's proportion (sd ``REFINE_PROPORTION_SD``, the first pass's 0.06 having
already pulled the limbs toward the population's proportions).
The scene comes back with the refined body; the caller tracks again.
"""

from __future__ import annotations

import dataclasses
import sys

import jax
import jax.numpy as jnp
import numpy as np

from ..body import forward_kinematics, inverse_kinematics
from ..camera import CameraRig
from ..errors import ConfigurationError
from ..filters import run_filter
from ..likelihood import body_of, calibrate_body, calibrate_body_from_keypoints, keypoint_terms, make_ground_prior, with_body

REFINE_FRAMES = 12  # frames of the second pass at 4 views of 160x120 or more (8 measured worse: docs/body.md)
MAX_REFINE_FRAMES = 40  # the most frames a second pass fits (its cost grows with them)
# The pixels per frame (summed over the views) at which REFINE_FRAMES frames carry enough: 4 views of 160x120.
# Smaller images get proportionally more frames (docs/body.md, "The limb lengths are the whole gap").
REFINE_REFERENCE_PIXELS = 4 * 160 * 120
# Prior sd of each limb's log proportion around the first pass's body: the first pass already held
# the limbs to the population's proportions (sd 0.06), and holding them there again a second time
# kept the split along a straight arm or leg where the first frames left it (docs/body.md).
REFINE_PROPORTION_SD = 0.15
REFINE_TAG = 2**31 - 4  # fold_in tag of the first tracking pass's key (a tracker's runs use tags 0, 1, ...)


def spread_frames(num_frames: int, count: int) -> np.ndarray:
    """``count`` frame indices spread evenly over ``num_frames`` frames, frame 0 first (fewer when
    the sequence is shorter)."""
    if num_frames < 1 or count < 1:
        raise ValueError(f"spread_frames needs at least one frame and one pick, got {num_frames} frames, {count} picks")
    return np.unique(np.round(np.linspace(0, num_frames - 1, min(count, num_frames))).astype(int))


def refine_frame_count(scene) -> int:
    """Frames of the second pass for ``scene``: ``REFINE_FRAMES`` at 4 views of 160x120 or more
    pixels per frame, proportionally more for smaller images (the evidence on a limb's length
    grows with the pixels along its edges), at most ``MAX_REFINE_FRAMES`` and the sequence's
    length. A likelihood without cameras gets ``REFINE_FRAMES``."""
    rigs = [x for x in jax.tree.leaves(scene.likelihood, is_leaf=lambda x: isinstance(x, CameraRig)) if isinstance(x, CameraRig)]
    count = REFINE_FRAMES
    if rigs:
        pixels = sum(w * h for w, h in rigs[0].image_size)
        count = int(np.clip(np.ceil(REFINE_FRAMES * REFINE_REFERENCE_PIXELS / pixels), REFINE_FRAMES, MAX_REFINE_FRAMES))
    return min(count, scene.num_frames)


def refine_body(scene, tracked_poses, *, key, frames: int | None = None, start_joints=None,
                ground_clearance: float = 0.06, **calibration_options):
    """The scene with its body calibrated again on tracked frames spread over the sequence.

    Args:
        scene: a prepared scene (``prepare_test``), usually with a calibrated body; with or without
            its ground prior (``add_ground_prior``).
        tracked_poses: (T, D) one tracker run's estimates on ``scene`` (``track`` or one run of
            ``track_runs``), on the scene's skeleton.
        key: for the start pose's inverse kinematics.
        frames: frames of the second pass, spread evenly from frame 0 (``spread_frames``); None:
            ``refine_frame_count(scene)`` (more for small images).
        start_joints: (J, 3) frame 0's joint positions (metres) when the start is given as joints
            (HumanEva's protocol): the new start pose is solved on the refined skeleton; None: the
            second pass's own fit of frame 0 (silhouettes alone).
        ground_clearance: the floor prior's clearance (metres) during the pass when the scene has no
            ground prior (``tracking.CALIBRATION_CLEARANCE``); a scene's own prior is used as it is.
        **calibration_options: passed to ``likelihood.calibrate_body`` (``proportion_sd``
            defaults to ``REFINE_PROPORTION_SD`` here).

    Returns:
        the scene with the refined body in its likelihood, the new start pose, the second pass's
        ``BodyCalibration`` and the start error against frame 0's ground truth.

    Raises:
        ValueError: tracked poses that do not match the scene (shape, non-finite).
        ConfigurationError: a second pass that does not converge (``calibrate_body``).
    """
    poses = np.asarray(tracked_poses, np.float64)
    T, D = scene.num_frames, int(scene.initial_pose.shape[-1])
    if poses.shape != (T, D):
        raise ValueError(f"tracked_poses must be one run's ({T}, {D}) estimates on this scene, got {poses.shape}")
    if not np.all(np.isfinite(poses)):
        raise ValueError("tracked_poses contain NaN or infinite values")
    picks = spread_frames(T, refine_frame_count(scene) if frames is None else frames)
    likelihood = scene.likelihood
    keypoints_alone = scene.body_calibration is not None and scene.body_calibration.cues == "keypoints"
    if keypoints_alone:  # as the first pass, whose radii's fit was refused (tracking.prepare_test)
        likelihood = keypoint_terms(likelihood) or likelihood
        if scene.ground_prior is not None:
            likelihood = likelihood + scene.ground_prior
    if scene.ground_prior is None:  # the floor holds the ankles while the band hides the feet
        likelihood = likelihood + make_ground_prior(scene.body.skeleton, ground_clearance)
    observations = jax.tree.map(lambda x: jnp.asarray(x)[jnp.asarray(picks)], scene.observations)
    calibration_options.setdefault("proportion_sd", REFINE_PROPORTION_SD)
    if scene.limb_measurement is not None:  # as the first pass narrowed its prior (measure_limb_lengths)
        calibration_options.setdefault("measured_lengths", scene.limb_measurement.as_observation())
    if scene.body_calibration is not None and scene.body_calibration.neutral_pose is not None:
        calibration_options.setdefault("neutral_pose", scene.body_calibration.neutral_pose)  # as the first pass held them
    split = scene.body_calibration is not None and scene.body_calibration.cues == "keypoint lengths"
    calibrate = calibrate_body_from_keypoints if split else calibrate_body  # the lengths from the keypoints again
    fitted, fitted_poses, report = calibrate(likelihood, poses[picks], observations, **calibration_options)
    if keypoints_alone:
        report = report._replace(cues="keypoints")
    body = body_of(fitted)
    if start_joints is None:
        start = fitted_poses[0]
    else:
        start = np.asarray(inverse_kinematics(np.asarray(start_joints, np.float64)[None], skeleton=body.skeleton, key=key,
                                              dtype=jnp.float64).pose[0])
    start = jnp.asarray(start, scene.initial_pose.dtype)
    error = float("nan") if scene.truth_joints is None else 1000.0 * float(np.mean(np.linalg.norm(
        np.asarray(forward_kinematics(body.skeleton, start), np.float64) - scene.truth_joints[0], axis=-1)))
    ground = None if scene.ground_prior is None else with_body(scene.ground_prior, body)
    return dataclasses.replace(scene, likelihood=with_body(scene.likelihood, body), body=body, initial_pose=start,
                               body_calibration=report, start_error_mm=error, ground_prior=ground)


def track_and_refine_body(scene, tracker, key, *, start_from_truth: bool = True, ground_clearance: float = 0.06,
                          frames: int | None = None, name: str = "test"):
    """One run of ``tracker`` on ``scene`` (key ``fold_in(key, REFINE_TAG)``), then ``refine_body``
    on its estimates; the start re-solved on the refined skeleton from frame 0's ground-truth joints
    when ``start_from_truth`` and the scene has them, else the second pass's own fit of frame 0.
    The caller builds its trackers again on the returned scene's likelihood. A second pass that does
    not converge (a first run that lost the person) keeps the first pass's body, with a warning
    naming ``name``."""
    _, info = run_filter(tracker, jax.random.fold_in(key, REFINE_TAG), scene.initial_pose, scene.observations)
    poses = np.asarray(jax.block_until_ready(info.estimate), np.float64)
    joints = scene.truth_joints[0] if start_from_truth and scene.truth_joints is not None else None
    try:
        return refine_body(scene, poses, key=key, frames=frames, start_joints=joints, ground_clearance=ground_clearance)
    except ConfigurationError as err:  # a first run that lost the person: the first pass's body is kept
        print(f"warning: {name}: the second body calibration on the tracked frames did not converge ({err}); tracking with "
              "the first pass's body", file=sys.stderr)
        return scene
