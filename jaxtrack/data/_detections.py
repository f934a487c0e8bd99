"""Synthetic 2-D keypoint detections: the true joints projected into every view with the errors a
pose detector makes (pixel noise, missed joints, left and right swapped, nothing outside the
image), for scenes whose keypoint files are made rather than detected."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from ..body import HUMANEVA_JOINTS
from ..camera import CameraRig, project_points


@dataclasses.dataclass(frozen=True)
class DetectorNoise:
    """How synthetic detections differ from the truth.

    Attributes:
        noise_px: standard deviation of the Gaussian pixel noise on u and v.
        dropped: probability that a joint is missing (confidence 0) in a view and frame.
        swapped: probability that a view's frame has every left and right joint exchanged (a
            detector's commonest gross error, seen from behind).
        confidence: the confidence a detected joint is given.
    """

    noise_px: float = 5.0
    dropped: float = 0.1
    swapped: float = 0.0
    confidence: float = 0.9

    def __post_init__(self):
        if not (np.isfinite(self.noise_px) and self.noise_px >= 0):
            raise ValueError(f"DetectorNoise.noise_px must be >= 0 pixels, got {self.noise_px!r}")
        for name in ("dropped", "swapped"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"DetectorNoise.{name} is a probability, got {getattr(self, name)!r}")
        if not 0 < self.confidence <= 1:
            raise ValueError(f"DetectorNoise.confidence must lie in (0, 1], got {self.confidence!r}")


def _mirror_order() -> np.ndarray:
    """Index of each HumanEva joint's left-right counterpart (itself on the midline)."""
    names = list(HUMANEVA_JOINTS)
    swap = {"l": "r", "r": "l"}
    return np.asarray([names.index(swap[n[0]] + n[1:]) if n[0] in swap and swap[n[0]] + n[1:] in names else i
                       for i, n in enumerate(names)])


def detect_keypoints(key, joints3d, rig: CameraRig, noise: DetectorNoise = DetectorNoise()) -> np.ndarray:
    """(C, T, 15, 3) keypoints (pixels u, v and confidence) of (T, 15, 3) world joints in metres
    (the HumanEva joints, in ``HUMANEVA_JOINTS`` order), as ``Sequence.keypoints2d`` stores them.

    A joint behind a camera or outside its image is missing (confidence 0, at (0, 0)). The same
    key gives the same detections.
    """
    joints = np.asarray(joints3d, np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (len(HUMANEVA_JOINTS), 3):
        raise ValueError(f"joints3d must be (frames, {len(HUMANEVA_JOINTS)}, 3), got {joints.shape}")
    if not np.all(np.isfinite(joints)):
        raise ValueError("joints3d contains NaN or infinite values")
    uv, _, in_front = project_points(rig, jnp.asarray(joints, rig.K.dtype))  # (T, 15, C, 2), (T, 15, C)
    uv = np.moveaxis(np.asarray(uv, np.float64), 2, 0)  # (C, T, 15, 2)
    seen = np.moveaxis(np.asarray(in_front), 2, 0)  # (C, T, 15)
    k_noise, k_drop, k_swap = jax.random.split(key, 3)
    uv = uv + noise.noise_px * np.asarray(jax.random.normal(k_noise, uv.shape, jnp.float32), np.float64)
    swap = np.asarray(jax.random.uniform(k_swap, uv.shape[:2])) < noise.swapped  # (C, T)
    uv = np.where(swap[..., None, None], uv[:, :, _mirror_order()], uv)
    size = np.asarray(rig.image_size, np.float64)[:, None, None, :]  # (C, 1, 1, 2) width, height
    inside = np.all((uv >= -0.5) & (uv <= size - 0.5), axis=-1)
    kept = seen & inside & (np.asarray(jax.random.uniform(k_drop, seen.shape)) >= noise.dropped)
    confidence = np.where(kept, noise.confidence, 0.0)
    return np.concatenate([np.where(kept[..., None], uv, 0.0), confidence[..., None]], axis=-1)
