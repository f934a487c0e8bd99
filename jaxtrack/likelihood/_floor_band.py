"""The silhouette likelihood with the floor around the feet left out: a capsule body has no feet,
and background subtraction segments the feet's shadows on the floor as foreground, so a body
calibrated on whole silhouettes stretches its shins down into them (docs/body.md, "The floor
band").

A pixel belongs to the *floor band* of a pose when its viewing ray meets the floor (the plane
``z = floor_height``) within ``radius`` metres of the ground point under either ankle. Such
pixels hold the floor around the feet, the feet themselves and the lowest 10-15 cm of the shins
(a ray through a point ``h`` above the floor meets it ``d h / (H - h)`` behind the point, seen
from a camera ``H`` above the floor and ``d`` away), and the shadows the feet cast. Paper 000
eq. 12's sums are taken over the other pixels only, for the model and the observation alike:

    A = sum_p w_p S(x)_p,   B = sum_p w_p S(x)_p O_p,   N = sum_p w_p O_p,   w_p = 0 in the band, 1 elsewhere

so neither the model's shins nor the observed shadows are scored there. The band follows the
ankles of each pose (without a gradient through the mask: it is where the pixels are scored,
not a term of the fit). Rays are cast through the cameras' pinhole model without their lens
distortion: the band is a coarse region, metres wide.

The body calibration (``calibrate_body``) fits with it; the tracker scores whole silhouettes.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._custom_types import Array, Bool, Float
from ..body import forward_kinematics
from ..camera import CameraRig, image_shape, pixel_grid
from ..render import project_capsules, weighted_union_statistics
from ._base import AbstractLikelihood
from ._sampled import PixelSample, SampledSilhouetteLikelihood
from ._silhouette import SilhouetteLikelihood, bidirectional_silhouette_cost

FOOT_JOINTS = ("lankle", "rankle")


def floor_points(rig: CameraRig, u: Float[Array, "views pixels"], v: Float[Array, "views pixels"], floor_height
                 ) -> tuple[Float[Array, "views pixels 2"], Bool[Array, "views pixels"]]:
    """Where each pixel's viewing ray meets the floor: ``(x, y)`` in metres, and whether it does
    (in front of the camera). Pinhole model, lens distortion ignored."""
    dtype = u.dtype
    rays_camera = jnp.einsum("vij,vpj->vpi", jnp.linalg.inv(rig.K.astype(dtype)), jnp.stack([u, v, jnp.ones_like(u)], axis=-1))
    rays = jnp.einsum("vji,vpj->vpi", rig.R.astype(dtype), rays_camera)  # R^T d: world directions
    centres = -jnp.einsum("vji,vj->vi", rig.R.astype(dtype), rig.t.astype(dtype))  # (views, 3)
    dz = rays[..., 2]
    safe_dz = jnp.where(jnp.abs(dz) > 1e-12, dz, 1e-12)
    along = (floor_height - centres[:, None, 2]) / safe_dz
    points = centres[:, None, :2] + along[..., None] * rays[..., :2]
    return points, along > 0


def floor_band_weights(rig: CameraRig, feet: Float[Array, "*batch feet 2"], u, v, radius, floor_height
                       ) -> Float[Array, "*batch views pixels"]:
    """``w_p`` of the module docstring: 0 for the pixels (u, v: (views, pixels)) whose ray meets
    the floor within ``radius`` metres of a foot's ground point ``feet`` (x, y), else 1."""
    points, hits = floor_points(rig, u, v, floor_height)
    gaps = jnp.linalg.norm(points[..., None, :] - feet[..., None, None, :, :], axis=-1)  # (*batch, views, pixels, feet)
    return jnp.where(hits & (jnp.min(gaps, axis=-1) < radius), 0.0, 1.0).astype(u.dtype)


class FloorBandSilhouette(AbstractLikelihood):
    """Paper 000 eq. 12 (``silhouette``'s, dense images or a ``PixelSample``) without the floor
    band of each pose (module docstring).

    Attributes:
        silhouette: the ``SilhouetteLikelihood`` (scored densely here, whatever its window) or
            ``SampledSilhouetteLikelihood`` whose body, cameras, edge and temperature are used.
        radius: the band's reach on the floor around each ankle's ground point, metres.
        floor_height: the floor's world z, metres.
    """

    silhouette: SilhouetteLikelihood | SampledSilhouetteLikelihood
    radius: Float[Array, ""]
    floor_height: Float[Array, ""]

    def __check_init__(self):
        if not isinstance(self.silhouette, (SilhouetteLikelihood, SampledSilhouetteLikelihood)):
            raise TypeError(f"FloorBandSilhouette wraps a silhouette likelihood, got {type(self.silhouette).__name__}")
        missing = [n for n in FOOT_JOINTS if n not in self.silhouette.body.skeleton.joint_names]
        if missing:
            raise ValueError(f"the floor band needs the ankles; the skeleton has no joint {', '.join(missing)}")

    def log_likelihood(self, poses: Float[Array, "particles dofs"], observation) -> Float[Array, " particles"]:
        body, rig, dtype = self.silhouette.body, self.silhouette.rig, poses.dtype
        if isinstance(observation, PixelSample):
            sample = PixelSample(*(jnp.asarray(x, dtype) for x in observation))
            u, v, counts, observed, observed_area = sample.u, sample.v, sample.weight, sample.observed, sample.observed_area
        else:
            observed = self.silhouette._observation(observation).astype(dtype)
            views, height, width = observed.shape
            rows, cols = pixel_grid(*image_shape(rig), dtype)
            u, v = jnp.broadcast_to(cols.ravel(), (views, height * width)), jnp.broadcast_to(rows.ravel(), (views, height * width))
            counts, observed = jnp.ones_like(u), observed.reshape(views, height * width)
            observed_area = jnp.sum(observed, axis=-1)
        ankles = [body.skeleton.joint_index(n) for n in FOOT_JOINTS]
        feet = jax.lax.stop_gradient(forward_kinematics(body.skeleton, poses)[:, jnp.asarray(ankles), :2])
        weight = counts * floor_band_weights(rig, feet, u, v, self.radius.astype(dtype), self.floor_height.astype(dtype))
        caps = project_capsules(body, rig, poses)
        area, overlap = weighted_union_statistics(caps.start, caps.end, caps.radius, u, v, weight, weight * observed,
                                                  self.silhouette.edge_width.astype(dtype))
        # N outside the band: the exact observed area less the band's (counted, or estimated from the sample).
        outside = observed_area - jnp.sum((counts - weight) * observed, axis=-1)
        cost = bidirectional_silhouette_cost(area, overlap, jnp.maximum(outside, 1.0))
        loglik = -self.silhouette.scale.astype(dtype) * jnp.mean(cost, axis=-1)
        return jnp.where(jnp.all(caps.in_front, axis=-1), loglik, -jnp.inf)
