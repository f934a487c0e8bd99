"""Paper 001's colour-histogram term (001 eqs. 17-18): per body part and view, the squared
Bhattacharyya distance between a reference colour histogram of the part and the histogram of
the image under the hypothesised part,

    d^2_ij = 1 - sum_b sqrt(p_ref_ij(b) p_ij(b)),     Sigma_h = 1/(N_cv N_parts) sum_ij d^2_ij,

and ``ln p = -scale Sigma_h``. A part's pixels are a grid of ``points`` x ``across`` sample
points spread over its projected capsule (along the axis, and across it within 0.7 of the
projected radius), read by bilinear sampling (``image.sample_bilinear``), so the term is
differentiable in the pose. Each colour falls into ``bins`` bins per RGB channel by a triangular
(linear) kernel, a soft histogram whose value moves smoothly with the colours.

The reference histograms are the parts' at a known pose on one frame (``with_reference``: the
start pose on the first frame, set by ``tracking.prepare_test`` through ``set_references``). 001 updates them as a running
weighted average of the estimates' histograms (eq. 18); ``with_reference(..., previous=old,
rate=r)`` computes that update, but the filters' scan keeps the likelihood fixed, so tracking
uses the start frame's reference throughout.

Parts that another part hides read the hider's colours; 001 weighs the edge term by visibility
(eq. 13) but not this one, and neither does this.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ..body import BodyModel
from ..camera import CameraRig, focal_lengths, project_points
from ..errors import ConfigurationError
from ..image import sample_bilinear
from ._base import AbstractLikelihood

_ACROSS_FRACTION = 0.7  # of the projected radius: the samples stay off the outline's mixed pixels


def soft_histogram(colours: Float[Array, "... n 3"], bins: int) -> Float[Array, "... bins3"]:
    """(..., bins**3) normalised soft histograms of (..., n, 3) colours in [0, 1]: each channel
    falls into its two nearest bin centres ``(k + 0.5) / bins`` by a triangular kernel."""
    centres = (jnp.arange(bins, dtype=colours.dtype) + 0.5) / bins
    weights = jnp.maximum(0.0, 1.0 - jnp.abs(colours[..., None] * bins - centres * bins))  # (..., n, 3, bins)
    # the edge bins take the mass beyond their centres
    low = colours[..., None] * bins < 0.5
    high = colours[..., None] * bins > bins - 0.5
    first, last = jnp.arange(bins) == 0, jnp.arange(bins) == bins - 1
    weights = jnp.where(low & first, 1.0, jnp.where(low & ~first, 0.0, weights))
    weights = jnp.where(high & last, 1.0, jnp.where(high & ~last, 0.0, weights))
    r, g, b = weights[..., 0, :], weights[..., 1, :], weights[..., 2, :]
    joint = r[..., :, None, None] * g[..., None, :, None] * b[..., None, None, :]  # (..., n, bins, bins, bins)
    histogram = jnp.sum(joint.reshape(joint.shape[:-3] + (-1,)), axis=-2)
    return histogram / jnp.maximum(jnp.sum(histogram, axis=-1, keepdims=True), 1e-12)


def bhattacharyya_distance(p: Float[Array, "... bins"], q: Float[Array, "... bins"]) -> Float[Array, ...]:
    """``1 - sum_b sqrt(p q)`` (001 eq. 17), the squared Bhattacharyya distance of two
    normalised histograms, in [0, 1]."""
    return 1.0 - jnp.sum(jnp.sqrt(p * q + 1e-12), axis=-1)


class ColourHistogramLikelihood(AbstractLikelihood):
    """Attributes:
        body: the capsule body whose parts are sampled.
        rig: the cameras (C views).
        scale: the temperature, ``ln p = -scale Sigma_h``.
        reference: (C, K, bins**3) the parts' reference histograms per view.
        bins: bins per colour channel.
        points, across: sample points along and across each part.

    A frame's observation is ``{"images": (C, H, W, 3)}`` (or that array itself), colours in [0, 1].
    """

    body: BodyModel
    rig: CameraRig
    scale: Float[Array, ""]
    reference: Float[Array, "views parts bins"]
    bins: int = eqx.field(static=True, default=4)
    points: int = eqx.field(static=True, default=5)
    across: int = eqx.field(static=True, default=3)

    def __check_init__(self):
        if self.bins < 2 or self.points < 2 or self.across < 1:
            raise ConfigurationError(f"bins and points must be at least 2 and across at least 1, got {self.bins}, {self.points}, "
                                     f"{self.across}")

    def sample_points(self, pose) -> tuple[Float[Array, "views parts n 2"], Array]:
        """Pixel positions (C, K, points * across, 2) inside each projected part, and (C,)
        whether the whole body is in front of each camera."""
        pose = jnp.asarray(pose)
        dtype = pose.dtype
        a3, b3 = self.body.capsules(pose)
        ua, za, fa = project_points(self.rig, a3)  # (K, C, 2)
        ub, zb, fb = project_points(self.rig, b3)
        a, b = jnp.swapaxes(ua, 0, 1), jnp.swapaxes(ub, 0, 1)  # (C, K, 2)
        depth = jnp.maximum(0.5 * (za + zb), 1e-2).T
        radius = focal_lengths(self.rig).astype(dtype)[:, None] * self.body.radii.astype(dtype)[None, :] / depth
        axis = b - a
        normal = jnp.stack([-axis[..., 1], axis[..., 0]], axis=-1) / jnp.linalg.norm(axis + 1e-12, axis=-1, keepdims=True)
        s = jnp.linspace(0.0, 1.0, self.points, dtype=dtype)
        t = jnp.linspace(-_ACROSS_FRACTION, _ACROSS_FRACTION, self.across, dtype=dtype) if self.across > 1 else jnp.zeros(1, dtype)
        along = a[:, :, None, None] + s[:, None, None] * axis[:, :, None, None]  # (C, K, P, 1, 2)
        offset = t[None, None, None, :, None] * radius[:, :, None, None, None] * normal[:, :, None, None]  # (C, K, 1, A, 2)
        grid = (along + offset).reshape(a.shape[:2] + (-1, 2))
        return grid, jnp.all(fa & fb, axis=0)

    def part_histograms(self, pose, images) -> Float[Array, "views parts bins"]:
        """(C, K, bins**3) soft colour histograms of each part at ``pose`` (D,) in (C, H, W, 3) images."""
        pose = jnp.asarray(pose)
        grid, _ = self.sample_points(pose)
        images = jnp.asarray(images, pose.dtype)

        def view(image, points):  # (H, W, 3), (K, n, 2) -> (K, n, 3)
            return jnp.stack([sample_bilinear(image[..., c], points) for c in range(3)], axis=-1)

        colours = jax.vmap(view)(images, grid)
        return soft_histogram(colours, self.bins)

    def cost(self, pose, observation) -> Float[Array, ""]:
        """Sigma_h of one pose (D,) on one frame (001 eqs. 17-18); a view with part of the body
        behind its camera costs 1, the most."""
        pose = jnp.asarray(pose)
        histograms = self.part_histograms(pose, observation["images"] if isinstance(observation, dict) else observation)
        distance = bhattacharyya_distance(self.reference.astype(pose.dtype), histograms)  # (C, K)
        _, in_front = self.sample_points(pose)
        return jnp.mean(jnp.where(in_front[:, None], distance, 1.0))

    def log_likelihood(self, poses, observation):
        return -self.scale * jax.vmap(lambda p: self.cost(p, observation))(poses)

    def with_reference(self, pose, images, *, previous=None, rate: float | None = None) -> ColourHistogramLikelihood:
        """This likelihood with its references the parts' histograms at ``pose`` in ``images``
        (C, H, W, 3), or a frame's observation dict holding them; with ``previous`` (C, K,
        bins**3) and ``rate``, 001 eq. 18's running average ``(1 - rate) previous + rate new``."""
        images = images["images"] if isinstance(images, dict) else images
        if previous is not None and (rate is None or not 0 <= rate <= 1):
            raise ValueError(f"a running reference needs a rate in [0, 1], got {rate!r}")
        new = self.part_histograms(jnp.asarray(pose, self.scale.dtype), images)
        if previous is not None:
            new = (1.0 - rate) * jnp.asarray(previous, new.dtype) + rate * new
        return eqx.tree_at(lambda m: m.reference, self, new)


def make_histogram_likelihood(body: BodyModel, rig: CameraRig, *, scale: float = 100.0, bins: int = 4, points: int = 5,
                              across: int = 3, dtype=jnp.float32) -> ColourHistogramLikelihood:
    """001's colour-histogram term with uniform references (set them with ``with_reference``)."""
    if not (np.isfinite(scale) and scale > 0):
        raise ConfigurationError(f"scale must be a positive number, got {scale!r}")
    size = bins**3
    reference = jnp.full((rig.num_views, body.radii.shape[0], size), 1.0 / size, dtype)
    return ColourHistogramLikelihood(body=body, rig=rig, scale=jnp.asarray(scale, dtype), reference=reference, bins=bins,
                                     points=points, across=across)

