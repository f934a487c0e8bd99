"""3-D joint arrays written by other tools, and resampling of joint trajectories in time."""

from __future__ import annotations

import os

import numpy as np

from ._mocap import MotionCapture
from ._sequence import SequenceFileError, load_sequence


def load_joints3d(path: str | os.PathLike) -> MotionCapture:
    """Read (T, J, 3) joint positions with their names from a sequence file (``.npz``).

    The file needs ``fps``, ``joints3d`` (metres, Z up) and ``joint_names``; ``parents`` is
    optional. Any joint set works; map it onto the HumanEva joints with a mapping (the
    15-joint HumanEva names map onto themselves).
    """
    sequence = load_sequence(path)
    if sequence.joints3d is None:
        raise SequenceFileError(f"{os.fspath(path)}: key 'joints3d': missing (3-D joint positions are required)")
    if sequence.joint_names is None:
        raise SequenceFileError(f"{os.fspath(path)}: key 'joint_names': missing (needed to map the joints)")
    names = tuple(str(n) for n in sequence.joint_names)
    parents = tuple(int(p) for p in sequence.parents) if sequence.parents is not None else (-1,) + (0,) * (len(names) - 1)
    return MotionCapture(
        joint_names=names,
        parents=parents,
        positions=np.asarray(sequence.joints3d, np.float64),
        fps=sequence.fps,
        channels=(),
        values=np.zeros((sequence.joints3d.shape[0], 0)),
        source=os.fspath(path),
    )


def resample(values: np.ndarray, fps_in: float, fps_out: float) -> np.ndarray:
    """Linearly resample (T, ...) trajectories from ``fps_in`` to ``fps_out`` frames per second.

    Output frames sit at ``k / fps_out`` seconds for every ``k`` that stays inside the input's
    time span (the first frame is kept).
    """
    if not (fps_in > 0 and fps_out > 0):
        raise ValueError(f"frame rates must be positive, got {fps_in} and {fps_out}")
    values = np.asarray(values, np.float64)
    T = values.shape[0]
    if T < 2 or fps_in == fps_out:
        return values.copy()
    duration = (T - 1) / fps_in
    times = np.arange(int(np.floor(duration * fps_out + 1e-9)) + 1) / fps_out
    position = times * fps_in
    lower = np.minimum(np.floor(position).astype(int), T - 2)
    weight = (position - lower).reshape((-1,) + (1,) * (values.ndim - 1))
    return (1 - weight) * values[lower] + weight * values[lower + 1]
