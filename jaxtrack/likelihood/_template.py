"""Paper 003's template likelihood (003 eq. 7): ``p(z | y)`` proportional to the normalised
correlation coefficient between the image patches around each projected joint ("marker") and
the joint's template patch,

    NCC(a, b) = sum (a - mean a)(b - mean b) / sqrt(sum (a - mean a)^2 sum (b - mean b)^2),

here ``ln p = scale * mean over joints and views of NCC`` (in [-scale, scale]). A patch is a
``size`` x ``size`` grid of grey values at ``spacing`` pixels around the projected joint, read by
bilinear sampling (``image.sample_bilinear``), so the likelihood is differentiable in the pose.
The templates are the patches at a known pose on one frame (``with_reference``: the start pose
on the first frame, set by ``tracking.prepare_test`` through ``set_references``). 003 tracks 2-D markers in one view; this
is the same term summed over the calibrated views of the 3-D body.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ..body import BodyModel, forward_kinematics
from ..camera import CameraRig, project_points
from ..errors import ConfigurationError
from ..image import rgb_to_grey, sample_bilinear
from ._base import AbstractLikelihood


def normalised_correlation(a: Float[Array, "... n"], b: Float[Array, "... n"]) -> Float[Array, ...]:
    """The normalised correlation coefficient of patches flattened along the last axis, in
    [-1, 1]; 0 where either patch is flat."""
    a = a - jnp.mean(a, axis=-1, keepdims=True)
    b = b - jnp.mean(b, axis=-1, keepdims=True)
    return jnp.sum(a * b, axis=-1) / jnp.sqrt(jnp.sum(a * a, axis=-1) * jnp.sum(b * b, axis=-1) + 1e-12)


def _grey(observation):
    images = observation["images"] if isinstance(observation, dict) else observation
    images = jnp.asarray(images)
    return rgb_to_grey(images) if images.shape[-1] == 3 else images


class TemplateLikelihood(AbstractLikelihood):
    """Attributes:
        body: the body whose joints are the markers.
        rig: the cameras (C views).
        scale: ``ln p = scale * mean NCC``.
        templates: (C, J, size * size) the joints' template patches per view.
        size: patch width in samples (odd).
        spacing: pixels between samples.

    A frame's observation is ``{"images": (C, H, W, 3)}`` (or the (C, H, W, 3) array itself),
    colours in [0, 1].
    """

    body: BodyModel
    rig: CameraRig
    scale: Float[Array, ""]
    templates: Float[Array, "views joints n"]
    size: int = eqx.field(static=True, default=7)
    spacing: float = eqx.field(static=True, default=1.0)

    def __check_init__(self):
        if self.size < 3 or self.size % 2 == 0:
            raise ConfigurationError(f"size must be an odd number >= 3, got {self.size}")
        if not (np.isfinite(self.spacing) and self.spacing > 0):
            raise ConfigurationError(f"spacing must be a positive number of pixels, got {self.spacing!r}")

    def patches(self, pose, grey) -> Float[Array, "views joints n"]:
        """(C, J, size * size) grey patches around each joint of ``pose`` (D,) projected into
        (C, H, W) grey images."""
        pose = jnp.asarray(pose)
        uv, _, _ = project_points(self.rig, forward_kinematics(self.body.skeleton, pose))  # (J, C, 2)
        offsets = (jnp.arange(self.size, dtype=pose.dtype) - self.size // 2) * self.spacing
        dv, du = jnp.meshgrid(offsets, offsets, indexing="ij")
        grid = jnp.swapaxes(uv, 0, 1)[:, :, None, :] + jnp.stack([du.ravel(), dv.ravel()], axis=-1)  # (C, J, n, 2)
        return jax.vmap(sample_bilinear)(jnp.asarray(grey, pose.dtype), grid)

    def log_likelihood(self, poses, observation):
        grey = _grey(observation)
        _, _, in_front = project_points(self.rig, forward_kinematics(self.body.skeleton, poses))  # (N, J, C)

        def one(pose, front):
            score = normalised_correlation(self.patches(pose, grey), self.templates.astype(pose.dtype))  # (C, J)
            return jnp.mean(jnp.where(front.T, score, -1.0))

        return self.scale * jax.vmap(one)(poses, in_front)

    def with_reference(self, pose, images) -> TemplateLikelihood:
        """This likelihood with its templates the patches at ``pose`` in ``images`` (C, H, W, 3),
        or a frame's observation dict holding them."""
        return eqx.tree_at(lambda m: m.templates, self, self.patches(jnp.asarray(pose, self.scale.dtype), _grey(images)))


def make_template_likelihood(body: BodyModel, rig: CameraRig, *, scale: float = 100.0, size: int = 7, spacing: float = 1.0,
                             dtype=jnp.float32) -> TemplateLikelihood:
    """003 eq. 7's template term with flat templates (set them with ``with_reference``)."""
    if not (np.isfinite(scale) and scale > 0):
        raise ConfigurationError(f"scale must be a positive number, got {scale!r}")
    templates = jnp.zeros((rig.num_views, body.skeleton.num_joints, size * size), dtype)
    return TemplateLikelihood(body=body, rig=rig, scale=jnp.asarray(scale, dtype), templates=templates, size=size, spacing=spacing)
