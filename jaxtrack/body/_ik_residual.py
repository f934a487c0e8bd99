"""What an inverse-kinematics residual says about a motion file: at its floor, the same on every
frame (the skeleton), or confined to some frames (those frames).

A sound file converts at its floor on every frame: a few millimetres for joints that came from a
rigid skeleton, about 10 mm for joints from markers (soft tissue, a joint centre placed per
frame). A residual well above that on every frame, and nearly the same on each, is the skeleton
failing these joints: a limb length, or a joint set whose layout the skeleton cannot take (a
pelvis far off the hips' line). A residual confined to some frames points at those frames: a
marker swap, a gap filled badly, a jump.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ._skeleton import HUMANEVA_JOINTS

HIGH_MM = 20.0
"""A frame whose mean residual over the joints exceeds this is above the floor of any sound file
(markers' floor about 10 mm)."""
EVERY_FRAME_FRACTION = 0.9
"""A residual above ``HIGH_MM`` on at least this fraction of the frames is high "on every frame"."""
STEADY_FRACTION = 0.5
"""A residual high on every frame is "nearly the same on each" when its 10th percentile over the
frames is at least this fraction of its median."""
PATTERNS = ("floor", "every frame", "some frames")


@dataclasses.dataclass(frozen=True)
class ResidualReport:
    """The inverse kinematics' residual of one take, read per frame.

    Attributes:
        per_frame_mm: (T,) mean residual over the joints of each frame, millimetres.
        per_joint_mm: (J,) mean residual over the frames of each joint, millimetres.
        pattern: one of ``PATTERNS``.
        frames: the frames above ``HIGH_MM`` (pattern "some frames"), else ().
        joint_names: the J joints' names.
    """

    per_frame_mm: np.ndarray
    per_joint_mm: np.ndarray
    pattern: str
    frames: tuple[int, ...] = ()
    joint_names: tuple[str, ...] = HUMANEVA_JOINTS

    def worst_joints(self, count: int = 3) -> list[str]:
        order = np.argsort(self.per_joint_mm)[::-1][:count]
        return [f"{self.joint_names[j]} {self.per_joint_mm[j]:.0f}" for j in order]

    def describe(self) -> str:
        """One line: the per-frame residual's spread and what its pattern points at."""
        low, median, high = np.percentile(self.per_frame_mm, [10, 50, 90])
        spread = (f"inverse-kinematics residual per frame {low:.1f}-{high:.1f} mm (10th-90th percentile; median {median:.1f}, "
                  f"worst frame {int(np.argmax(self.per_frame_mm))} at {self.per_frame_mm.max():.1f})")
        if self.pattern == "every frame":
            low_share = np.percentile(self.per_frame_mm, 10) / np.median(self.per_frame_mm)
            how = "nearly the same on each" if low_share >= STEADY_FRACTION else "varying from frame to frame"
            return (f"{spread}: high on every frame, {how} (most at {', '.join(self.worst_joints())} mm), which points at "
                    "the skeleton or at the file's joints as a whole (a limb length, joints placed where this skeleton's "
                    "cannot be, the sides swapped), not at some frames")
        if self.pattern == "some frames":
            return (f"{spread}: above {HIGH_MM:.0f} mm only at frames {frame_ranges(self.frames)}; look at those frames "
                    "(a marker swap, a gap filled badly, a jump)")
        return f"{spread}: at the floor"

    def summary(self) -> dict:
        """What results record: the per-frame residual (0.1 mm) and the pattern."""
        return {"per_frame": np.round(self.per_frame_mm, 1).tolist(), "pattern": self.pattern,
                "frames": list(self.frames), "describe": self.describe()}


def residual_report(residual_mm, joint_names=HUMANEVA_JOINTS) -> ResidualReport:
    """Read a (T, J) residual in millimetres (``IKResult.residual_mm``) per frame."""
    residual = np.asarray(residual_mm, np.float64)
    if residual.ndim != 2 or residual.shape[0] < 1:
        raise ValueError(f"residual_mm must be (frames, joints) with at least one frame, got {residual.shape}")
    per_frame = residual.mean(axis=1)
    per_joint = residual.mean(axis=0)
    high = per_frame > HIGH_MM
    if np.mean(high) >= EVERY_FRAME_FRACTION:
        pattern, frames = "every frame", ()
    elif high.any():
        pattern, frames = "some frames", tuple(int(t) for t in np.flatnonzero(high))
    else:
        pattern, frames = "floor", ()
    return ResidualReport(per_frame, per_joint, pattern, frames, tuple(joint_names))


def frame_ranges(frames, limit: int = 8) -> str:
    """``(3, 4, 5, 9)`` -> ``"3-5, 9"`` (the first ``limit`` runs, then how many more)."""
    runs = []
    for t in frames:
        if runs and t == runs[-1][1] + 1:
            runs[-1][1] = t
        else:
            runs.append([t, t])
    text = [f"{a}-{b}" if b > a else f"{a}" for a, b in runs[:limit]]
    if len(runs) > limit:
        text.append(f"and {len(runs) - limit} more runs")
    return ", ".join(text)
