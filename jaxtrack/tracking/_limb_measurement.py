"""Limb lengths measured from 2-D keypoints in calibrated views, over every frame, with the
detection noise's bias removed (docs/body.md, "Limb lengths measured over every frame").

The body calibration fits the limb lengths with the poses of a few frames free
(``likelihood.calibrate_body``). With detections a few pixels off, that has two faults:

- **variance**: four frames hold eight samples of a leg's bones, each off by the noise of two
  triangulated joints (5 px at 320x240 and 5 m is about 80 mm a joint): the calibrated legs
  came out 16-18 mm long on CMU 35, whose detections happened to stretch them;
- **bias**: a length fitted with a free pose per frame grows with the noise across the bone
  (the mean of |a + n| exceeds |a|), whatever the number of frames: the raw mean over 100
  frames was 9-20 mm long on the legs and 40-60 mm on the short bones.

So every frame with a joint seen by two views or more is triangulated (``triangulate``), and for
each bone (a, b)

    L^2 = mean_t |X_a - X_b|^2 - mean_t (tr Sigma_a + tr Sigma_b)

where ``Sigma`` is the triangulated point's covariance under isotropic pixel noise ``sigma``:
with ``P_c`` the projector across view c's ray and ``s_c = z_c / f_c`` the metres a pixel spans
at the point, the estimate ``X = A^-1 sum_c w_c P_c (centre_c)`` with ``A = sum_c w_c P_c``
has ``Sigma = sigma^2 A^-1 (sum_c w_c^2 s_c^2 P_c) A^-1``. ``sigma`` itself comes from the
points' residuals across the rays, in pixels: ``sum_c r_c^2`` has ``2 n - 3`` degrees of
freedom for a point seen in ``n`` views; a first estimate from the median point, then the points
whose residual is more than 3 ``sigma`` (a swapped or mistaken detection) are left out and
``sigma`` estimated again from the rest. The standard error of
``L`` is the spread of ``|X_a - X_b|^2`` over the samples, ``sd / sqrt(n) / (2 L)``; left and
right bones are pooled as the calibration ties them.

The measurement enters the calibration as a Gaussian observation of the log lengths beside the
prior (``calibrate_body``'s ``measured_lengths``): the short bones (the hips, the shoulders),
whose noise is as large as their length, keep the prior's value.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..body import HUMANEVA_JOINTS, LIMB_SEGMENTS
from ..camera import CameraRig
from ._start import camera_rays, triangulate

MIN_SAMPLES = 8  # bones (a frame's left or right one) seen for a limb to be measured
OUTLIER_SIGMAS = 3.0  # a point's RMS residual across its rays, in estimated noise sds, beyond which it is left out


class LimbMeasurement(NamedTuple):
    """Attributes:
        lengths: limb name -> bias-corrected length, metres (``body.LIMB_SEGMENTS``' names; a limb
            with too few samples is absent).
        standard_errors: limb name -> the length's standard error, metres.
        pixel_noise: the detections' estimated noise sd, pixels per axis.
        samples: limb name -> bones measured.
        points_left_out: triangulated points whose residual was beyond ``OUTLIER_SIGMAS``.
    """

    lengths: dict[str, float]
    standard_errors: dict[str, float]
    pixel_noise: float
    samples: dict[str, int]
    points_left_out: int

    def as_observation(self) -> dict[str, tuple[float, float]]:
        """limb -> (length, standard error), metres: ``calibrate_body``'s ``measured_lengths``."""
        return {limb: (self.lengths[limb], self.standard_errors[limb]) for limb in self.lengths}


def measure_limb_lengths(rig: CameraRig, keypoints) -> LimbMeasurement | None:
    """The limb lengths of ``keypoints`` (C, T, 15, 3): pixels u, v and a confidence (0: not
    seen) in the HumanEva joint order, as ``Sequence.keypoints2d`` holds them (module docstring).
    None where fewer than two views see joints, or no limb has ``MIN_SAMPLES`` bones."""
    keypoints = np.asarray(keypoints, np.float64)
    if keypoints.ndim != 4 or keypoints.shape[0] != rig.num_views or keypoints.shape[2:] != (len(HUMANEVA_JOINTS), 3):
        raise ValueError(f"keypoints must be ({rig.num_views}, frames, {len(HUMANEVA_JOINTS)}, 3), got {keypoints.shape}")
    if rig.num_views < 2:
        return None
    pixels, weights = keypoints[..., :2], (keypoints[..., 2] > 0).astype(np.float64)
    points, seen = triangulate(rig, pixels, weights)  # (T, J, 3), (T, J)
    centres, directions = camera_rays(rig, pixels)  # (C, 3), (C, T, J, 3)
    across = np.eye(3) - directions[..., :, None] * directions[..., None, :]  # (C, T, J, 3, 3)
    R, t = np.asarray(rig.R, np.float64), np.asarray(rig.t, np.float64)
    depth = np.einsum("cj,tkj->ctk", R[:, 2], points) + t[:, 2][:, None, None]
    focal = 0.5 * (np.asarray(rig.K, np.float64)[:, 0, 0] + np.asarray(rig.K, np.float64)[:, 1, 1])
    span = np.maximum(depth, 1e-6) / focal[:, None, None]  # metres per pixel at the point (C, T, J)
    offsets = np.einsum("ctkij,ctkj->ctki", across, points[None] - centres[:, None, None])
    residual = np.sum(weights * (np.linalg.norm(offsets, axis=-1) / span) ** 2, axis=0)  # pixels^2 (T, J)
    dof = 2 * weights.sum(axis=0) - 3  # (T, J); 1 or more where seen
    usable = seen & (dof >= 1)
    if not usable.any():
        return None
    # a first noise estimate from the median point (a swapped view's points would inflate a mean): the
    # median of chi^2_k / k is about (1 - 2 / (9 k))^3 (Wilson and Hilferty)
    typical_dof = np.median(dof[usable])
    variance = np.median(residual[usable] / dof[usable]) / (1 - 2 / (9 * typical_dof)) ** 3
    outliers = usable & (residual > OUTLIER_SIGMAS ** 2 * variance * dof)
    usable &= ~outliers
    if not usable.any():
        return None
    variance = residual[usable].sum() / dof[usable].sum()
    information = np.sum(weights[..., None, None] * across, axis=0)
    information = np.where(usable[..., None, None], information, np.eye(3))
    inverse = np.linalg.inv(information)
    noise = np.sum((weights ** 2 * variance * span ** 2)[..., None, None] * across, axis=0)
    spread = np.trace(inverse @ noise @ inverse, axis1=-2, axis2=-1)  # (T, J) metres^2
    index = {name: i for i, name in enumerate(HUMANEVA_JOINTS)}
    lengths, errors, samples = {}, {}, {}
    for limb, bones in LIMB_SEGMENTS.items():
        squares, corrections = [], []
        for a, b in bones:
            both = usable[:, index[a]] & usable[:, index[b]]
            squares.append(np.sum((points[both, index[a]] - points[both, index[b]]) ** 2, axis=-1))
            corrections.append(spread[both, index[a]] + spread[both, index[b]])
        squares, corrections = np.concatenate(squares), np.concatenate(corrections)
        if squares.size < MIN_SAMPLES:
            continue
        square = squares.mean() - corrections.mean()
        length = float(np.sqrt(max(square, 1e-6)))
        lengths[limb] = length
        errors[limb] = float(max(squares.std(ddof=1) / np.sqrt(squares.size) / (2 * length), 1e-4))
        samples[limb] = int(squares.size)
    if not lengths:
        return None
    return LimbMeasurement(lengths, errors, float(np.sqrt(variance)), samples, int(outliers.sum()))
