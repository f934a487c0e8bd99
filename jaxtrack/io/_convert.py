"""``jaxtrack convert``: motion capture (ASF/AMC, BVH, 3-D joint arrays) -> a sequence file
with HumanEva ``joints3d``, fitted ``pose`` vectors and ``fps``."""

from __future__ import annotations

import dataclasses
import glob
import os

import jax
import numpy as np

from ..body import ResidualReport, inverse_kinematics, residual_report, retarget_positions
from ..errors import ConfigurationError
from ._asf_amc import load_asf_amc
from ._bvh import load_bvh
from ._floor import FloorFit, fit_floor, level_joints
from ._joints import load_joints3d, resample
from ._mocap import MotionCapture
from ._sequence import Sequence, save_sequence


@dataclasses.dataclass
class ConversionReport:
    """What ``convert_motion`` produced."""

    sequence: Sequence
    source_fps: float
    num_frames: int
    mean_residual_mm: float
    max_residual_mm: float
    residual_per_joint_mm: np.ndarray
    limb_lengths: dict
    floor: FloorFit | None = None
    levelled: bool = False
    residual: ResidualReport | None = None
    """The residual per frame and what its pattern points at (``body.residual_report``)."""


def load_motion(source: str, *, asf: str | None = None, source_fps: float | None = None):
    """Load any supported motion file as a ``MotionCapture`` (chosen by extension)."""
    extension = os.path.splitext(source)[1].lower()
    if extension == ".amc":
        if asf is None:
            candidates = glob.glob(os.path.join(os.path.dirname(source) or ".", "*.asf"))
            if len(candidates) != 1:
                raise ValueError(f"{source}: an AMC file needs its skeleton; pass --asf (found {len(candidates)} .asf files beside it)")
            asf = candidates[0]
        if source_fps is None:
            raise ValueError(f"{source}: AMC files do not store their frame rate; pass --source-fps (CMU: 120)")
        return load_asf_amc(asf, source, fps=source_fps)
    if extension == ".bvh":
        motion = load_bvh(source)
        return motion if source_fps is None else dataclasses.replace(motion, fps=float(source_fps))
    if extension == ".npz":
        motion = load_joints3d(source)
        return motion if source_fps is None else dataclasses.replace(motion, fps=float(source_fps))
    raise ValueError(f"{source}: unsupported motion format {extension!r} (use .amc with .asf, .bvh or .npz)")


LEG_LENGTH_M = (0.25, 1.5)
"""Plausible hip-to-ankle lengths of a person, metres: a motion file outside them is in other
units (or is not a person) and is refused before the inverse kinematics."""


def check_motion_units(joints: np.ndarray, source: str) -> float:
    """The median hip-to-ankle length (m) of (T, 15, 3) HumanEva joints, or ``ConfigurationError``
    naming the file and the units it looks like when no person's legs are that long."""
    from ..body import HUMANEVA_JOINTS

    index = HUMANEVA_JOINTS.index

    def segment(a, b):
        return np.linalg.norm(joints[:, index(a)] - joints[:, index(b)], axis=-1)

    lengths = [segment(h, k) + segment(k, a) for h, k, a in (("lhip", "lknee", "lankle"), ("rhip", "rknee", "rankle"))]
    leg = float(np.nanmedian(np.concatenate(lengths)))
    low, high = LEG_LENGTH_M
    if low <= leg <= high:
        return leg
    guesses = [(name, factor) for name, factor in (("centimetres", 100.0), ("millimetres", 1000.0), ("inches", 1 / 0.0254))
               if low <= leg / factor <= high]
    hint = f": it looks like {guesses[0][0]} (lengths are read as metres)" if guesses else ""
    raise ConfigurationError(f"{source}: the legs (hip to ankle) are {leg:.4g} m long, no person's are ({low:g}-{high:g} m){hint}; "
                             "check the file's units (an ASF's ':units length', a BVH's offsets)")


def convert_motion(
    source: str | MotionCapture,
    out: str | None,
    *,
    fps: float | None = None,
    asf: str | None = None,
    source_fps: float | None = None,
    mapping: dict | None = None,
    seed: int = 0,
    level_floor: bool = False,
    verbose: bool = False,
) -> ConversionReport:
    """Convert a motion file (or a loaded ``MotionCapture``) to a sequence file (``out``; not
    written when None).

    Args:
        fps: output frame rate (default: the source's).
        asf: the ASF skeleton of an AMC file (default: the only .asf beside it).
        source_fps: the source frame rate (required for AMC).
        mapping: HumanEva joint -> source joint(s); guessed for CMU and Bandai skeletons.
        seed: PRNG seed of the inverse kinematics' first-frame restarts.
        level_floor: rotate the motion so that the floor under its stance foot is level
            (``fit_floor``, ``level_joints``; docs/floor.md, "A tilted capture"). The floor's
            fit is reported either way (``ConversionReport.floor``, of the source).
    """
    if isinstance(source, MotionCapture):
        motion = source if source_fps is None else dataclasses.replace(source, fps=float(source_fps))
        source = motion.source
    else:
        motion = load_motion(source, asf=asf, source_fps=source_fps)
    try:
        joints = retarget_positions(motion.positions, motion.joint_names, mapping)
    except ValueError as err:  # the mapping does not fit this file's skeleton: say which file
        raise ConfigurationError(f"{source}: {err}") from err
    check_motion_units(joints, str(source))
    target_fps = float(fps) if fps is not None else motion.fps
    joints = resample(joints, motion.fps, target_fps)
    floor = fit_floor(joints)
    levelled = bool(level_floor and floor.seen and floor.slope > 0.0)
    if levelled:
        joints = level_joints(joints, floor)
    if verbose:
        print(f"{source}: {floor.describe()}" + ("; levelled" if levelled else ""))
        print(f"{source}: {motion.num_frames} frames at {motion.fps:g} Hz -> {joints.shape[0]} at {target_fps:g} Hz; fitting poses")
    result = inverse_kinematics(joints, key=jax.random.key(seed))
    skeleton = result.skeleton
    sequence = Sequence.create(
        fps=target_fps,
        joint_names=np.array(skeleton.joint_names),
        parents=np.array(skeleton.parents),
        joints3d=joints,
        pose=np.asarray(result.pose, np.float64),
        pose_layout=np.array(skeleton.pose_layout),
        skeleton_offsets=np.asarray(skeleton.offsets, np.float64),
    )
    if out is not None:
        save_sequence(out, sequence)
    residual = np.asarray(result.residual_mm)
    lengths = {k: float(np.linalg.norm(v)) for k, v in zip(skeleton.joint_names, np.asarray(skeleton.offsets))}
    return ConversionReport(
        sequence=sequence,
        source_fps=motion.fps,
        num_frames=joints.shape[0],
        mean_residual_mm=float(residual.mean()),
        max_residual_mm=float(residual.max()),
        residual_per_joint_mm=residual.mean(axis=0),
        limb_lengths=lengths,
        floor=floor,
        levelled=levelled,
        residual=residual_report(residual),
    )
