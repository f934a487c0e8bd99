"""The reprojection likelihood of 2-D keypoint detections: each view's detected joints against
the pose's joints projected into that view, robust, confidence-weighted, missing joints
allowed.

For poses ``x`` with joints ``X_j(x)`` projected into view ``c`` as ``u_cj(x)``, and a frame's
detections ``k_cj`` (pixels) with confidences ``w_cj`` in [0, 1] (0: missing),

    ln p(k | x) = - sum_{c, j} w_cj rho(||u_cj(x) - k_cj||^2 / sigma_j^2),

with ``rho(s) = ln(1 + s / 2)`` (Cauchy; ``robust="cauchy"``, the default: a wrong detection
costs a logarithm, not its square, so one swapped left and right does not outweigh the rest)
or ``rho(s) = s / 2`` (Gaussian). ``sigma_j`` is ``sigma_px`` for the joints every detector
marks and ``APPROXIMATE_SCALE`` times it for the approximate correspondences (thorax and
head, ``io.KeypointLayout.approximate``). A joint behind a camera costs as if it were the
image's diagonal away. The term is smooth in the pose, so gradient-refined moves and the body
calibration (``calibrate_body``) work with it.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ..body import HUMANEVA_JOINTS, BodyModel, forward_kinematics
from ..camera import CameraRig, project_points
from ..errors import ConfigurationError
from ._base import AbstractLikelihood, ObservationPart, SumLikelihood

ROBUST_LOSSES = ("cauchy", "gaussian")
APPROXIMATE_JOINTS = ("thorax", "head")
APPROXIMATE_SCALE = 2.0  # sigma of a joint no detector marks (its centre estimated from other points), relative


def joint_sigmas(sigma_px: float, approximate_scale: float = APPROXIMATE_SCALE) -> np.ndarray:
    """(15,) per-joint pixel scales: ``sigma_px``, times ``approximate_scale`` for the thorax
    and the head."""
    return np.asarray([sigma_px * (approximate_scale if j in APPROXIMATE_JOINTS else 1.0) for j in HUMANEVA_JOINTS])


class KeypointLikelihood(AbstractLikelihood):
    """Attributes:
        body: the body whose skeleton places the joints (its capsules are not used).
        rig: the cameras (C views).
        sigmas: (15,) pixel scale of each joint's residual (``joint_sigmas``).
        robust: "cauchy" (default) or "gaussian" (module docstring).
        weight: an exponent on the likelihood (1: as the module docstring says); e.g.
            ``1 / data_weight`` to sum it untempered into ``calibrate_body``, whose
            ``data_weight`` undoes the silhouettes' tempering.

    A frame's observation is its (C, 15, 3) keypoints (pixels u, v and confidence); summed with
    a silhouette likelihood, wrap each in ``ObservationPart`` to read its entry of a dict.
    """

    body: BodyModel
    rig: CameraRig
    sigmas: Float[Array, " joints"]
    robust: str = eqx.field(static=True, default="cauchy")
    weight: float = eqx.field(static=True, default=1.0)

    def __check_init__(self):
        if not (np.isfinite(self.weight) and self.weight > 0):
            raise ConfigurationError(f"weight must be a positive number, got {self.weight!r}")
        if self.robust not in ROBUST_LOSSES:
            raise ConfigurationError(f"robust must be one of {ROBUST_LOSSES}, got {self.robust!r}")
        if self.body.skeleton.joint_names != HUMANEVA_JOINTS:
            raise ConfigurationError("the keypoint likelihood scores the 15 HumanEva joints; this body's skeleton has other joints")
        if jnp.shape(self.sigmas) != (len(HUMANEVA_JOINTS),):
            raise ConfigurationError(f"sigmas must be ({len(HUMANEVA_JOINTS)},), got {jnp.shape(self.sigmas)}")

    def log_likelihood(self, poses, observation):
        keypoints = observation
        positions = forward_kinematics(self.body.skeleton, poses)  # (N, 15, 3)
        uv, _, in_front = project_points(self.rig, positions)  # (N, 15, C, 2), (N, 15, C)
        uv = jnp.swapaxes(uv, -3, -2)  # (N, C, 15, 2)
        in_front = jnp.swapaxes(in_front, -2, -1)  # (N, C, 15)
        target = keypoints[..., :2].astype(uv.dtype)
        weight = keypoints[..., 2].astype(uv.dtype)
        squared = jnp.sum((uv - target) ** 2, axis=-1) / self.sigmas.astype(uv.dtype) ** 2
        diagonal2 = jnp.asarray([float(w) ** 2 + float(h) ** 2 for w, h in self.rig.image_size], uv.dtype)  # (C,)
        far = diagonal2[:, None] / self.sigmas.astype(uv.dtype) ** 2  # (C, 15)
        squared = jnp.where(in_front, squared, far)
        cost = jnp.log1p(0.5 * squared) if self.robust == "cauchy" else 0.5 * squared
        return -self.weight * jnp.sum(weight * cost, axis=(-2, -1))


def make_keypoint_likelihood(body: BodyModel, rig: CameraRig, *, sigma_px: float = 4.0, robust: str = "cauchy",
                             weight: float = 1.0, dtype=jnp.float32) -> KeypointLikelihood:
    """A ``KeypointLikelihood`` with joint scales ``joint_sigmas(sigma_px)`` (pixels)."""
    if not (np.isfinite(sigma_px) and sigma_px > 0):
        raise ConfigurationError(f"sigma_px must be a positive number of pixels, got {sigma_px!r}")
    return KeypointLikelihood(body, rig, jnp.asarray(joint_sigmas(sigma_px), dtype), robust, float(weight))


def keypoint_terms(likelihood: AbstractLikelihood) -> AbstractLikelihood | None:
    """The 2-D keypoint terms of a likelihood that also observes other cues (``silhouette+keypoints``;
    nested sums are looked into, priors left out), summed, or None (no keypoints, or no other cue).
    What ``tracking.prepare_test`` calibrates the body from when the whole likelihood's calibration
    is refused: the keypoints mark the joints themselves, so a body whose shape is not the capsules'
    is still measured (docs/body.md)."""
    terms = _flat_terms(likelihood)
    kept = tuple(t for t in terms if isinstance(t, KeypointLikelihood)
                 or (isinstance(t, ObservationPart) and isinstance(t.term, KeypointLikelihood)))
    if not kept or len(kept) == sum(t.reads_observation for t in terms):
        return None
    return kept[0] if len(kept) == 1 else SumLikelihood(kept)


def _flat_terms(likelihood: AbstractLikelihood) -> tuple[AbstractLikelihood, ...]:
    if isinstance(likelihood, SumLikelihood):
        return tuple(t for term in likelihood.terms for t in _flat_terms(term))
    return (likelihood,)
