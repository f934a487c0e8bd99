"""What every motion-capture loader returns, and the error it raises on malformed files."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ..errors import MotionFileError as MotionFileError

# Y-up (ASF/AMC, BVH) to the project's Z-up world: a +90 degree turn about x, (x, y, z) -> (x, -z, y).
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


@dataclasses.dataclass(frozen=True, eq=False)
class MotionCapture:
    """Joint positions and angles read from a motion file, in the project's frame.

    Attributes:
        joint_names: (J,) source joint names, root first; parents precede children.
        parents: (J,) parent index of each joint, -1 for the root.
        positions: (T, J, 3) joint positions, metres, world frame, Z up. For ASF/AMC a bone's
            position is its end point; for BVH a joint's position is its origin.
        fps: frames per second.
        channels: source channel names, e.g. ``("root", "TX")`` or ``("lfemur", "rx")``.
        values: (T, len(channels)) the source channel values, angles in radians, lengths
            in metres (the file's own axes, before the Y-up to Z-up turn).
        source: the file (or files) it came from.
    """

    joint_names: tuple[str, ...]
    parents: tuple[int, ...]
    positions: np.ndarray
    fps: float
    channels: tuple[tuple[str, str], ...]
    values: np.ndarray
    source: str

    def __post_init__(self):
        for name in ("positions", "values"):
            if not np.all(np.isfinite(getattr(self, name))):
                what = "joint positions" if name == "positions" else "channel values"
                raise MotionFileError(self.source, None, f"its numbers are too large: the {what} overflow to infinity "
                                                         "(a length, offset or angle far out of range?)")

    @property
    def num_frames(self) -> int:
        return int(self.positions.shape[0])

    def joint(self, name: str) -> np.ndarray:
        """(T, 3) trajectory of one source joint."""
        try:
            return self.positions[:, self.joint_names.index(name)]
        except ValueError:
            raise ValueError(f"{self.source}: no joint named {name!r}; joints are {self.joint_names}") from None

    def bone_lengths(self) -> np.ndarray:
        """(T, J) distance of every joint from its parent (0 for the root), metres."""
        parents = np.array(self.parents)
        lengths = np.zeros(self.positions.shape[:2])
        child = parents >= 0
        lengths[:, child] = np.linalg.norm(self.positions[:, child] - self.positions[:, parents[child]], axis=-1)
        return lengths


def euler_matrix(angles: np.ndarray, order: str) -> np.ndarray:
    """Rotation matrices (..., 3, 3) from angles (..., len(order)) in radians.

    ``order`` lists fixed (static) axes in the order they are applied, e.g. ``"XYZ"`` gives
    ``Rz @ Ry @ Rx`` (the ASF convention); call with the reversed order for the intrinsic
    (BVH) convention ``R_first @ R_second @ ...``.
    """
    angles = np.asarray(angles, np.float64)
    out = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for i, axis in enumerate(order.upper()):
        c, s = np.cos(angles[..., i]), np.sin(angles[..., i])
        R = np.zeros(angles.shape[:-1] + (3, 3))
        a = "XYZ".index(axis)
        b, d = [k for k in range(3) if k != a]
        R[..., a, a] = 1.0
        R[..., b, b] = c
        R[..., d, d] = c
        sign = 1.0 if axis != "Y" else -1.0
        R[..., b, d] = -sign * s
        R[..., d, b] = sign * s
        out = R @ out
    return out


def overflow_checked(loader):
    """Run a loader's kinematics with NumPy's overflow warnings off: ``MotionCapture`` refuses
    any non-finite result itself, naming the file, instead of a warning and infinite joints."""

    @functools.wraps(loader)
    def wrapped(*args, **kwargs):
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return loader(*args, **kwargs)

    return wrapped
