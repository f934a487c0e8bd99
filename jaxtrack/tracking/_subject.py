"""The subject's body: which skeleton and capsules a sequence's poses are rendered, scored and
evaluated with, and where they came from.

A sequence file may carry its subject's skeleton (``skeleton_offsets``), only 3-D joint
positions (``joints3d``, what HumanEva hands out), or neither (video only). ``subject_body``
resolves, in this order:

1. ``"file"``: the file's ``skeleton_offsets`` (checked against its ``joints3d`` when it has both:
   a skeleton whose bones cannot span its own joints is refused);
2. ``"fitted to joints"``: the skeleton inverse kinematics fits to the file's ``joints3d``
   (``body.inverse_kinematics``: each limb's median length over the frames, left and right tied),
   its poses solved on that same skeleton;
3. ``"training take"``: the body of another file of the same ``subject`` (a training or
   validation take) that has one of the two above;
4. ``"default"``: the default body (``body.humaneva_body``), said out loud; a tracker can then
   calibrate it from the images (``likelihood.calibrate_body``, source ``"calibrated"``).

The inverse kinematics' residual per joint is kept for every file with joints, so a score against
a ground truth the skeleton cannot reach (a head below the thorax, a swapped marker) shows as such.
"""

from __future__ import annotations

import dataclasses
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._tree import cast_floating
from ..body import (
    HUMANEVA_JOINTS,
    LIMB_SEGMENTS,
    BodyModel,
    ResidualReport,
    check_joint_names,
    fit_limb_lengths,
    forward_kinematics,
    humaneva_body,
    inverse_kinematics,
    residual_report,
    with_offsets,
)
from ..errors import SequenceFileError
from ..io import Sequence

BODY_SOURCES = ("file", "fitted to joints", "training take", "calibrated", "default")
BODY_CHOICES = ("auto", "joints", "default", "calibrate")
"""What a caller may ask for: ``"auto"`` (the order above), ``"joints"`` (fit to the joints even
when the file has a skeleton), ``"default"`` (the default body, poses solved on it) or
``"calibrate"`` (the default body or a stated height, its limb lengths and radii then fitted to
the first frames' images: ``likelihood.calibrate_body``)."""

CALIBRATION_PRIORS = ("default", "proportions", "motion")
"""What centres a body calibration's prior (``prepare_test``, ``TrackingSpec.body_prior``): the default
body's proportions (the default), the motion model's subjects' proportions (the clavicles at rest), or
their proportions and clavicle posture (``motion_subjects_prior``; docs/body.md, "The motion model's
subject": the last best for the model's own subject, worse for other people)."""

# A file's skeleton contradicts its joints when a limb's length differs from the joints' median
# segment length by more than both of these (the IK residual of real motion capture is 5-30 mm).
CONTRADICTION_M = 0.03
POSE_CONTRADICTION_MM = 50.0  # a file's pose and joints disagree: more than this, mean over joints and frames
CONTRADICTION_FRACTION = 0.10
# The IK residual (mean over frames, per joint) above which a ground truth is flagged as one the
# skeleton cannot reach: twice the worst joint of a clean CMU or Bandai conversion (about 25 mm).
UNREACHABLE_MM = 50.0


@dataclasses.dataclass(frozen=True)
class SubjectBody:
    """A sequence's body and poses.

    Attributes:
        body: the ``BodyModel`` (float64) that renders and scores the sequence's poses.
        source: one of ``BODY_SOURCES``.
        detail: where exactly (the donor take's name, the calibration's frames), or "".
        poses: (T, D) float64 poses of the sequence on ``body`` (the file's ``pose``, or inverse
            kinematics on ``joints3d``), or None for a file without ground truth.
        residual_mm: (T, J) distance between ``body``'s joints at ``poses`` and the file's
            ``joints3d``, millimetres, or None when the file has no joints.
    """

    body: BodyModel
    source: str
    detail: str = ""
    poses: np.ndarray | None = None
    residual_mm: np.ndarray | None = None

    def __post_init__(self):
        if self.source not in BODY_SOURCES:
            raise ValueError(f"body source must be one of {BODY_SOURCES}, got {self.source!r}")

    @property
    def limb_lengths(self) -> dict[str, float]:
        """The skeleton's limb lengths (metres), keys of ``body.DEFAULT_LIMB_LENGTHS`` (left and right
        averaged)."""
        return limb_lengths_of(self.body)

    def residual_per_joint_mm(self) -> dict[str, float] | None:
        """Mean inverse-kinematics residual of each joint over the frames (None without joints)."""
        if self.residual_mm is None:
            return None
        return {name: float(v) for name, v in zip(HUMANEVA_JOINTS, np.mean(self.residual_mm, axis=0))}

    def residual_report(self) -> ResidualReport | None:
        """The residual read per frame (``body.residual_report``), or None without joints."""
        return None if self.residual_mm is None else residual_report(self.residual_mm)

    def unreachable(self, threshold_mm: float = UNREACHABLE_MM) -> list[str]:
        """The joints the skeleton cannot reach (mean residual over ``threshold_mm``), each with
        its residual and worst frame, for a warning."""
        if self.residual_mm is None:
            return []
        mean = np.mean(self.residual_mm, axis=0)
        return [f"{HUMANEVA_JOINTS[j]} {mean[j]:.0f} mm (worst frame {int(np.argmax(self.residual_mm[:, j]))})"
                for j in np.flatnonzero(mean > threshold_mm)]

    def summary(self) -> dict:
        """What results.json records: source, limb lengths (mm), radii and the IK residual."""
        out = {"source": self.source, "detail": self.detail,
               "limb_lengths_mm": {k: round(1000 * v, 1) for k, v in self.limb_lengths.items()},
               "capsule_radii_mm": dict(zip(self.body.capsule_names, np.round(1000 * np.asarray(self.body.radii, np.float64), 1).tolist()))}
        if self.residual_mm is not None:
            per_joint = self.residual_per_joint_mm()
            out["ik_residual_mm"] = {"mean": float(np.mean(self.residual_mm)), "max": float(np.max(self.residual_mm)),
                                     "frame0_mean": float(np.mean(self.residual_mm[0])),
                                     "per_joint": {k: round(v, 2) for k, v in per_joint.items()},
                                     **self.residual_report().summary()}
            out["unreachable_joints"] = self.unreachable()
        return out


OWN_BODY_SOURCES = ("file", "fitted to joints", "training take")  # the person's own skeleton, not a guess


def limb_lengths_of(body: BodyModel) -> dict[str, float]:
    """Limb lengths (metres) of a body's skeleton, left and right averaged."""
    lengths = np.linalg.norm(np.asarray(body.skeleton.offsets, np.float64), axis=1)
    index = {n: i for i, n in enumerate(body.skeleton.joint_names)}
    return {limb: float(np.mean([lengths[index[b]] for _, b in pairs])) for limb, pairs in LIMB_SEGMENTS.items()}


def leg_length(body: BodyModel) -> float:
    """Thigh plus shin (metres, left and right averaged): what a walker's root height scales with
    (the CMU walkers' mean root height is 1.02-1.05 times it)."""
    lengths = limb_lengths_of(body)
    return lengths["thigh"] + lengths["shin"]


def motion_subjects_prior(donors) -> tuple[dict[str, float] | None, np.ndarray | None]:
    """What the motion model's subjects say about a body calibrated from images: their limb
    lengths (the geometric mean over the ``donors`` with a skeleton of their own: file or fitted
    to joints), and their mean pose (over every frame of those with poses), whose clavicles
    ``likelihood.calibrate_body`` holds near (``neutral_pose``). ``(None, None)`` without such a
    donor.

    Why (docs/body.md, "The motion model's subject"): where a joint sits is a convention of the
    motion capture (the thorax of the CMU and HDM05 conversions 51-55 mm below the shoulders, their
    forearms 170-212 mm against the default's 260), and the tracker's poses come from the motion
    model's takes, so the body can be calibrated in their convention: the default proportions and
    a rest clavicle put the spine 41 mm long and the forearm 48 mm long on CMU subject 35's
    keypoints, its own proportions and posture within 7 mm except the legs. Used where
    ``prepare_test``'s ``calibration_prior`` asks for it (not by default: across people the
    tracks were no better, docs/body.md).

    Args:
        donors: ``(name, SubjectBody, subject)`` of the training and validation takes, as
            ``subject_body`` takes them.
    """
    own = [donor for _, donor, _ in donors if donor.source in ("file", "fitted to joints")]
    if not own:
        return None, None
    logs = np.array([[np.log(donor.limb_lengths[limb]) for limb in LIMB_SEGMENTS] for donor in own])
    lengths = dict(zip(LIMB_SEGMENTS, np.exp(logs.mean(axis=0)).tolist()))
    poses = [np.asarray(donor.poses, np.float64) for donor in own if donor.poses is not None]
    return lengths, (np.concatenate(poses).mean(axis=0) if poses else None)


def _radii(sequence: Sequence, body: BodyModel) -> BodyModel:
    """The body with the file's ``capsule_radii`` (when it has them)."""
    if sequence.capsule_radii is None:
        return body
    if sequence.capsule_radii.shape != body.radii.shape:
        raise SequenceFileError(f"key 'capsule_radii': has {sequence.capsule_radii.shape[0]} radii, "
                                f"the body has {body.num_capsules} capsules")
    return eqx.tree_at(lambda b: b.radii, body, jnp.asarray(sequence.capsule_radii, body.radii.dtype))


def _with_offsets(body: BodyModel, offsets) -> BodyModel:
    return eqx.tree_at(lambda b: b.skeleton, body, with_offsets(body.skeleton, np.asarray(offsets, np.float64)))


def check_offsets_match_joints(offsets, joints, name: str) -> None:
    """Refuse a file whose ``skeleton_offsets`` cannot span its ``joints3d``: a limb whose
    length differs from the joints' median segment length by more than 3 cm and 10 %."""
    fitted = fit_limb_lengths(joints)
    lengths = np.linalg.norm(np.asarray(offsets, np.float64), axis=1)
    index = {n: i for i, n in enumerate(HUMANEVA_JOINTS)}
    for limb, pairs in LIMB_SEGMENTS.items():
        for a, b in pairs:
            bone = float(lengths[index[b]])
            gap = bone - fitted[limb]
            if abs(gap) > CONTRADICTION_M and abs(gap) > CONTRADICTION_FRACTION * fitted[limb]:
                raise SequenceFileError(
                    f"{name}: key 'skeleton_offsets' contradicts 'joints3d': the bone {a} -> {b} is {1000 * bone:.0f} mm in the "
                    f"skeleton but {1000 * fitted[limb]:.0f} mm between the joints (median over the frames); drop one of the two "
                    f"keys, or pass body='joints' to fit the skeleton to the joints")


def check_pose_matches_joints(resolved: SubjectBody, name: str) -> None:
    """Refuse a file whose ``pose`` on its own skeleton puts the joints more than
    ``POSE_CONTRADICTION_MM`` (mean over joints and frames) from its ``joints3d``: one of the two
    is not the motion (a truncated or rescaled pose, another take's joints)."""
    if resolved.residual_mm is None or resolved.source != "file":
        return
    per_frame = resolved.residual_mm.mean(axis=1)
    if float(per_frame.mean()) > POSE_CONTRADICTION_MM:
        worst = int(np.argmax(per_frame))
        raise SequenceFileError(
            f"{name}: key 'pose' contradicts 'joints3d': on the file's skeleton the pose puts the joints "
            f"{float(per_frame.mean()):.0f} mm from the file's joints on average (frame {worst}: {per_frame[worst]:.0f} mm); "
            "drop one of the two keys, or pass body='joints' to solve the poses from the joints")


def subject_body(sequence: Sequence, name: str, *, key, choice: str = "auto", donors=(), dtype=jnp.float32) -> SubjectBody:
    """Resolve a sequence's body and poses (see the module docstring).

    Args:
        sequence: the sequence.
        name: its name in messages.
        key: PRNG key of the inverse kinematics' restarts.
        choice: one of ``BODY_CHOICES``; ``"calibrate"`` resolves like ``"default"`` here (the
            calibration needs the likelihood: ``likelihood.calibrate_body``).
        donors: ``(name, SubjectBody, subject)`` of other files (training, validation) whose body
            a file without skeleton or joints may take when its ``subject`` is the same.
        dtype: floating dtype of the body (the poses and residuals are float64 NumPy arrays
            whatever it is; inverse kinematics runs in float64).

    Raises:
        SequenceFileError: a skeleton that contradicts the file's joints, or joint names that are
            not HumanEva's.
    """
    if choice not in BODY_CHOICES:
        raise ValueError(f"body must be one of {BODY_CHOICES}, got {choice!r}")
    if sequence.joint_names is not None:
        check_joint_names([str(n) for n in sequence.joint_names], HUMANEVA_JOINTS, f"{name} joint_names")
    joints = None if sequence.joints3d is None else np.asarray(sequence.joints3d, np.float64)
    with jax.enable_x64(True):
        default = _radii(sequence, humaneva_body(dtype=jnp.float64))
        if choice in ("default", "calibrate"):
            return _solved(default, sequence, joints, key, "default", "", dtype, fit=False)
        if sequence.skeleton_offsets is not None and choice == "auto":
            if joints is not None:
                check_offsets_match_joints(sequence.skeleton_offsets, joints, name)
            resolved = _solved(_with_offsets(default, sequence.skeleton_offsets), sequence, joints, key, "file", "", dtype, fit=False)
            check_pose_matches_joints(resolved, name)
            return resolved
        if joints is not None:
            return _solved(default, sequence, joints, key, "fitted to joints", "", dtype, fit=True)
        for donor_name, donor, subject in donors:
            if sequence.subject is not None and subject == sequence.subject and donor.source in ("file", "fitted to joints"):
                body = _radii(sequence, cast_floating(donor.body, jnp.float64))
                return _solved(body, sequence, None, key, "training take", donor_name, dtype, fit=False)
        return _solved(default, sequence, None, key, "default", "", dtype, fit=False)


def _solved(body: BodyModel, sequence: Sequence, joints, key, source: str, detail: str, dtype, *, fit: bool) -> SubjectBody:
    """The body with the sequence's poses on it: the file's ``pose`` when its skeleton is the
    body's (``source`` "file", or a file without joints), else inverse kinematics on the joints
    (fitting the skeleton too when ``fit``)."""
    poses, residual = None, None
    if joints is not None and (fit or sequence.pose is None or source != "file"):
        result = inverse_kinematics(joints, skeleton=None if fit else body.skeleton, key=key, dtype=jnp.float64)
        if fit:
            body = _with_offsets(body, np.asarray(result.skeleton.offsets, np.float64))
        poses, residual = np.asarray(result.pose, np.float64), np.asarray(result.residual_mm, np.float64)
    elif sequence.pose is not None:
        poses = np.asarray(sequence.pose, np.float64)
        if joints is not None:
            fk = np.asarray(forward_kinematics(body.skeleton, jnp.asarray(poses, jnp.float64)))
            residual = 1000.0 * np.linalg.norm(fk - joints, axis=-1)
    return SubjectBody(body=_in_dtype(body, dtype), source=source, detail=detail, poses=poses, residual_mm=residual)


def _in_dtype(body: BodyModel, dtype) -> BodyModel:
    """The same body built in ``dtype`` (its joint limits stay infinite where they are)."""
    out = humaneva_body(dtype=dtype)
    out = eqx.tree_at(lambda b: b.skeleton.offsets, out, jnp.asarray(np.asarray(body.skeleton.offsets, np.float64), dtype))
    return eqx.tree_at(lambda b: b.radii, out, jnp.asarray(np.asarray(body.radii, np.float64), dtype))


def warn_unreachable(resolved: SubjectBody, name: str) -> None:
    """Warn (``UserWarning``) where the skeleton cannot reach a file's joints."""
    bad = resolved.unreachable()
    if bad:
        warnings.warn(f"{name}: the skeleton cannot reach the file's joints ({', '.join(bad)}): a score against this ground "
                      "truth measures the file as much as the tracker", stacklevel=2)
