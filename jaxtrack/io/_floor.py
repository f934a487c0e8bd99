"""The floor under a recorded motion: its slope, as the stance foot traces it, and the motion
levelled onto it.

The library's world frame puts a level floor at z = 0 (``likelihood.GroundPlanePrior``, the
synthetic scenes, HumanEva). A motion capture whose vertical axis is not the floor's normal
breaks that: CMU subject 07's walks rise 18-20 mm a metre along the walk (1.1 degrees; 6-9 cm
over a take), so a test scene rendered from them shows a person walking up a ramp that the
calibrated floor says is level (docs/floor.md, "A tilted capture").

The fit: on each frame the lower ankle is the stance foot's, on the floor or lifting off it. A
plane ``z = g . (xy - c) + h`` is fitted to those points by iteratively reweighted least
squares, a point more than ``lift`` above the plane (a heel rising, both feet in the air) down-
weighted twentyfold. The plane is only fitted along the directions the path covers: along a
principal axis of the ankles' floor positions whose spread (sd) is under ``min_span`` the slope
is not seen and is taken as 0 (a straight walk says nothing about the floor across it).
Levelling rotates every joint about the horizontal axis through the plane's point at the
path's centre, so that the plane becomes horizontal and its height there is kept.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..body import HUMANEVA_JOINTS

MIN_SPAN_M = 0.3
"""The least spread (sd, metres) of the path along a direction for the slope to be fitted there."""
LIFT_M = 0.015
"""A stance ankle higher than this above the fitted plane counts as lifting off (down-weighted)."""
TILT_WORTH_LEVELLING_DEG = 0.5
"""A floor tilted more than this (degrees) is worth levelling: CMU 07's walks tilt 1.1, the
other walkers' of the shared data 0.02-0.25, HDM05's jogs 0.05-1.85."""
_LIFTED_WEIGHT = 0.05
_MIN_FRAMES = 10


@dataclasses.dataclass(frozen=True)
class FloorFit:
    """The floor under a motion's stance foot.

    Attributes:
        gradient: (2,) the plane's slope, dz/dx and dz/dy (metres a metre).
        pivot: (3,) the path's centre on the floor plane: the stance ankles' mean (x, y) and the
            plane's height there (metres).
        spans: (2,) the path's spread (sd, metres) along its two principal axes, widest first.
        heights: (T,) the plane's height under each frame's stance ankle (metres; NaN where the
            ankles are missing).
    """

    gradient: np.ndarray
    pivot: np.ndarray
    spans: np.ndarray
    heights: np.ndarray

    @property
    def slope(self) -> float:
        """The steepest rise, metres a metre."""
        return float(np.hypot(*self.gradient))

    @property
    def tilt_degrees(self) -> float:
        """The floor's tilt from level, degrees."""
        return float(np.degrees(np.arctan(self.slope)))

    @property
    def rise_m(self) -> float:
        """How far the floor rises over the path the motion covers, metres."""
        finite = self.heights[np.isfinite(self.heights)]
        return float(np.ptp(finite)) if finite.size else 0.0

    @property
    def seen(self) -> bool:
        """Whether the path spans any direction enough to see a slope."""
        return bool(np.any(self.spans >= MIN_SPAN_M))

    @property
    def worth_levelling(self) -> bool:
        """Whether the slope is seen and the floor tilts ``TILT_WORTH_LEVELLING_DEG`` or more."""
        return self.seen and self.tilt_degrees >= TILT_WORTH_LEVELLING_DEG

    def describe(self) -> str:
        if not self.seen:
            return f"the floor's slope is not seen: the path spreads {self.spans[0]:.2f} m at most (needs {MIN_SPAN_M:g})"
        return (f"the floor tilts {self.tilt_degrees:.2f} degrees ({1000 * self.slope:.1f} mm a metre), "
                f"rising {1000 * self.rise_m:.0f} mm over the path")


def _stance_points(joints: np.ndarray, joint_names) -> np.ndarray:
    names = list(joint_names)
    missing = [a for a in ("lankle", "rankle") if a not in names]
    if missing:
        raise ValueError(f"the floor is fitted under the ankles: the joints have no {', '.join(missing)}")
    ankles = joints[:, [names.index("lankle"), names.index("rankle")]]  # (T, 2, 3)
    heights = np.where(np.isfinite(ankles[..., 2]), ankles[..., 2], np.inf)
    lower = np.argmin(heights, axis=1)
    return ankles[np.arange(len(joints)), lower]  # (T, 3); NaN rows where both are missing


def fit_floor(joints, joint_names=HUMANEVA_JOINTS, *, min_span: float = MIN_SPAN_M, lift: float = LIFT_M,
              iterations: int = 20) -> FloorFit:
    """The floor plane under a motion's stance ankles (module docstring).

    Args:
        joints: (T, J, 3) joint positions, metres, world frame, Z up.
        joint_names: the J names; must include "lankle" and "rankle".
        min_span: the least spread of the path along a direction for its slope to be fitted.
        lift: how far above the plane a stance ankle counts as lifting off (metres).

    Returns:
        a ``FloorFit``; a path too short to span ``min_span`` anywhere, or with fewer than 10
        frames that see an ankle, gives a level plane at the stance ankles' median height.
    """
    joints = np.asarray(joints, np.float64)
    if joints.ndim != 3 or joints.shape[-1] != 3 or joints.shape[1] != len(joint_names):
        raise ValueError(f"joints must be (T, {len(joint_names)}, 3), got {joints.shape}")
    points = _stance_points(joints, joint_names)
    finite = np.all(np.isfinite(points), axis=1)
    heights = np.full(len(joints), np.nan)
    if finite.sum() < _MIN_FRAMES:
        level = float(np.median(points[finite, 2])) if finite.any() else 0.0
        heights[finite] = level
        return FloorFit(np.zeros(2), np.array([0.0, 0.0, level]), np.zeros(2), heights)
    p = points[finite]
    centre = p[:, :2].mean(axis=0)
    _, singular, axes = np.linalg.svd(p[:, :2] - centre, full_matrices=False)
    spans = singular / np.sqrt(len(p))
    spanned = axes[spans >= min_span]  # (k, 2) directions the path covers
    design = np.concatenate([(p[:, :2] - centre) @ spanned.T, np.ones((len(p), 1))], axis=1)
    weights = np.ones(len(p))
    for _ in range(iterations):
        coefficients = np.linalg.lstsq(design * weights[:, None], p[:, 2] * weights, rcond=None)[0]
        weights = np.where(p[:, 2] - design @ coefficients > lift, _LIFTED_WEIGHT, 1.0)
    gradient = spanned.T @ coefficients[:-1] if len(spanned) else np.zeros(2)
    heights[finite] = design @ coefficients
    return FloorFit(gradient, np.array([*centre, coefficients[-1]]), spans, heights)


def levelling_rotation(gradient) -> np.ndarray:
    """(3, 3) the smallest rotation taking the plane of ``gradient`` (dz/dx, dz/dy) to level."""
    normal = np.array([-gradient[0], -gradient[1], 1.0])
    normal /= np.linalg.norm(normal)
    up = np.array([0.0, 0.0, 1.0])
    axis = np.cross(normal, up)
    sine, cosine = np.linalg.norm(axis), float(normal @ up)
    if sine < 1e-15:
        return np.eye(3)
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + k + k @ k * ((1.0 - cosine) / sine**2)


def level_joints(joints, floor: FloorFit) -> np.ndarray:
    """(T, J, 3) the joints rotated about the floor's pivot so that its plane is level (the
    plane's height at the pivot kept)."""
    joints = np.asarray(joints, np.float64)
    rotation = levelling_rotation(floor.gradient)
    return (joints - floor.pivot) @ rotation.T + floor.pivot
