"""Soft (differentiable) and hard silhouettes of the capsule body.

Each capsule is drawn as the 2-D capsule spanned by its projected axis end points, with the
radius projected at the depth of the axis midpoint, ``r_px = f r / z_mid`` (a close
approximation of the true conic outline for limbs far from the camera compared to their
length). For a pixel at squared distance ``d2`` from the projected axis the occupancy is

    o = smoothstep(clip((r_px^2 - d2) / (4 r_px w) + 1/2, 0, 1)),   smoothstep(z) = z^2 (3 - 2 z)

i.e. a C^1 ramp of half-width about ``w`` pixels (the *edge width*, 1 / sharpness) centred
on the outline ``d = r_px`` (using ``d - r ~ (d^2 - r^2) / 2r``, which avoids a square root).
Unlike a sigmoid it has compact support: a pixel farther than ``sqrt(r^2 + 2 r w)`` from
every axis is exactly 0. This lets the fast likelihood evaluate a window around the body and
still equal the dense image sum. Capsules are combined as a probabilistic union,
``S = 1 - prod_k (1 - o_k)``. As ``w -> 0`` the soft silhouette tends to the hard one,
``S = [min_k (d2_k - r_k^2) <= 0]``. The ramp reaches 1 on the axis only when
``r_px >= 2 w``: thinner capsules (distant forearms at low resolution) stay partly
transparent, which is the soft model's intended blur, not an error.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from .._custom_types import Array, Bool, Float
from ..body import BodyModel
from ..camera import CameraRig, focal_lengths, image_shape, pixel_grid, project_points


class ProjectedCapsules(NamedTuple):
    """Capsules of one or more poses projected into every view (pixels).

    Attributes:
        start: (*batch, views, capsules, 2) projected axis start (u, v).
        end: (*batch, views, capsules, 2) projected axis end (u, v).
        radius: (*batch, views, capsules) projected radius, pixels.
        in_front: (*batch, views) whether every capsule end point is in front of the camera.
    """

    start: Float[Array, "*batch views capsules 2"]
    end: Float[Array, "*batch views capsules 2"]
    radius: Float[Array, "*batch views capsules"]
    in_front: Bool[Array, "*batch views"]


def project_capsules(body: BodyModel, rig: CameraRig, pose: Float[Array, "*batch dofs"]) -> ProjectedCapsules:
    """Project the posed capsule body into every camera of ``rig``."""
    a3, b3 = body.capsules(pose)  # (*batch, K, 3)
    ua, za, fa = project_points(rig, a3)  # (*batch, K, C, ...)
    ub, zb, fb = project_points(rig, b3)
    depth = jnp.maximum(0.5 * (za + zb), 1e-2)
    radius = focal_lengths(rig).astype(pose.dtype) * body.radii.astype(pose.dtype)[:, None] / depth
    in_front = jnp.all(fa & fb, axis=-2)  # (*batch, C)
    return ProjectedCapsules(
        start=jnp.swapaxes(ua, -3, -2),
        end=jnp.swapaxes(ub, -3, -2),
        radius=jnp.swapaxes(radius, -2, -1),
        in_front=in_front,
    )


def _capsule_terms(caps: ProjectedCapsules, edge_width):
    """Per-capsule constants, each (*batch, views, capsules, 1), ready to broadcast over pixels."""
    a, b, r = caps.start, caps.end, caps.radius
    u = b - a
    length2 = jnp.sum(u * u, axis=-1)
    inv_length2 = 1.0 / jnp.maximum(length2, 1e-12)
    ex = lambda x: x[..., None]  # noqa: E731
    return (
        ex(a[..., 0]),
        ex(a[..., 1]),
        ex(u[..., 0]),
        ex(u[..., 1]),
        ex(u[..., 0] * inv_length2),
        ex(u[..., 1] * inv_length2),
        ex(r * r),
        ex(1.0 / (4.0 * jnp.maximum(r, 1e-6) * edge_width)),
    )


def _squared_distance(px, py, ax, ay, ux, uy, vx, vy):
    """Squared distance of pixels (px, py) to the segment a -> a + u."""
    qx, qy = px - ax, py - ay
    t = jnp.clip(qx * vx + qy * vy, 0.0, 1.0)
    ex, ey = qx - t * ux, qy - t * uy
    return ex * ex + ey * ey


def capsule_union(
    caps: ProjectedCapsules,
    px: Float[Array, "*#batch pixels"],
    py: Float[Array, "*#batch pixels"],
    edge_width,
) -> Float[Array, "*batch pixels"]:
    """Soft silhouette value in [0, 1] at arbitrary pixel positions (u = px, v = py).

    ``px`` and ``py`` broadcast against the capsules' batch and view axes (pass one (pixels,)
    grid for every view, or per-view grids).

    The capsule loop is unrolled so XLA fuses it into one pass over the pixels.
    """
    terms = _capsule_terms(caps, edge_width)
    empty = None
    for k in range(caps.radius.shape[-1]):
        miss = _capsule_miss([x[..., k, :] for x in terms], px, py)
        empty = miss if empty is None else empty * miss
    return 1.0 - empty


def _capsule_miss(terms_k, px, py):
    """``1 - o_k`` of one capsule at the pixels, from its ``_capsule_terms`` (module docstring)."""
    ax, ay, ux, uy, vx, vy, r2, inv = terms_k
    d2 = _squared_distance(px, py, ax, ay, ux, uy, vx, vy)
    z = jnp.clip((r2 - d2) * inv + 0.5, 0.0, 1.0)
    return 1.0 - z * z * (3.0 - 2.0 * z)


def _one_capsule_miss(start, end, radius, px, py, edge_width):
    """``_capsule_miss`` of capsule arrays without the capsule axis: (*batch, 2), (*batch)."""
    caps = ProjectedCapsules(start[..., None, :], end[..., None, :], radius[..., None], None)
    return _capsule_miss([x[..., 0, :] for x in _capsule_terms(caps, edge_width)], px, py)


def union_statistics(
    start: Float[Array, "*batch capsules 2"],
    end: Float[Array, "*batch capsules 2"],
    radius: Float[Array, "*batch capsules"],
    px: Float[Array, "*#batch pixels"],
    py: Float[Array, "*#batch pixels"],
    observed: Float[Array, "*#batch pixels"],
    edge_width,
) -> tuple[Float[Array, " *batch"], Float[Array, " *batch"]]:
    """Area ``A = sum_p S_p`` and overlap ``B = sum_p S_p O_p`` of the soft union silhouette
    ``S`` of the capsules at the given pixels, against the observed values ``O``.

    Differentiable (reverse mode) in ``start``, ``end`` and ``radius``: see
    ``weighted_union_statistics``, of which this is the case of unit pixel weights.
    """
    one = jnp.ones((1,), radius.dtype)
    return weighted_union_statistics(start, end, radius, px, py, one, observed, edge_width)


@jax.custom_vjp
def weighted_union_statistics(
    start: Float[Array, "*batch capsules 2"],
    end: Float[Array, "*batch capsules 2"],
    radius: Float[Array, "*batch capsules"],
    px: Float[Array, "*#batch pixels"],
    py: Float[Array, "*#batch pixels"],
    area_weight: Float[Array, "*#batch #pixels"],
    overlap_weight: Float[Array, "*#batch pixels"],
    edge_width,
) -> tuple[Float[Array, " *batch"], Float[Array, " *batch"]]:
    """Weighted sums ``A = sum_p a_p S_p`` and ``B = sum_p b_p S_p`` of the soft union
    silhouette ``S`` of the capsules at the given pixels (e.g. ``a_p`` a sampled pixel's
    inverse inclusion probability and ``b_p = a_p O_p`` with ``O`` the observation).

    Differentiable (reverse mode) in ``start``, ``end`` and ``radius``, with a backward pass
    that recomputes the silhouette instead of storing it: per capsule, the pixel weights
    ``dL/dS_p`` times ``prod_{j != k} (1 - o_j)`` pulled back by autodiff through that
    capsule's occupancy alone, reduced over the pixels as it goes. Differentiating the unrolled
    product directly keeps every partial product of every pixel for the backward pass, about
    30 times the cost of the evaluation on CPU; this is a few times it. The pixel positions,
    the weights and the edge width get zero cotangents (they are data here).
    """
    caps = ProjectedCapsules(start, end, radius, None)
    silhouette = capsule_union(caps, px, py, edge_width)
    return jnp.sum(silhouette * area_weight, axis=-1), jnp.sum(silhouette * overlap_weight, axis=-1)


def _weighted_union_statistics_fwd(start, end, radius, px, py, area_weight, overlap_weight, edge_width):
    residuals = (start, end, radius, px, py, area_weight, overlap_weight, edge_width)
    return weighted_union_statistics(*residuals), residuals


def _weighted_union_statistics_bwd(residuals, cotangents):
    start, end, radius, px, py, area_weight, overlap_weight, edge_width = residuals
    area_bar, overlap_bar = cotangents
    weight = area_bar[..., None] * area_weight + overlap_bar[..., None] * overlap_weight  # dL/dS per pixel
    num = radius.shape[-1]
    misses = [_one_capsule_miss(start[..., k, :], end[..., k, :], radius[..., k], px, py, edge_width) for k in range(num)]
    # prod_{j != k} miss_j without dividing by zero: count the exact zeros (pixels deep inside a capsule).
    zeros = [m == 0 for m in misses]
    zero_count = sum(z.astype(jnp.int32) for z in zeros)
    nonzero_product = misses[0] * 0 + 1
    for m, z in zip(misses, zeros):
        nonzero_product = nonzero_product * jnp.where(z, 1.0, m)
    grads = []
    for k, (m, z) in enumerate(zip(misses, zeros)):
        others = jnp.where(z, jnp.where(zero_count == 1, nonzero_product, 0.0),
                           jnp.where(zero_count == 0, nonzero_product / jnp.where(z, 1.0, m), 0.0))
        _, pullback = jax.vjp(lambda a, b, r: _one_capsule_miss(a, b, r, px, py, edge_width), start[..., k, :], end[..., k, :],
                              radius[..., k])
        grads.append(pullback(-weight * others))  # S = 1 - prod miss: dS/dmiss_k = -prod_{j != k} miss_j
    start_bar = jnp.stack([g[0] for g in grads], axis=-2)
    end_bar = jnp.stack([g[1] for g in grads], axis=-2)
    radius_bar = jnp.stack([g[2] for g in grads], axis=-1)
    return (start_bar, end_bar, radius_bar, jnp.zeros_like(px), jnp.zeros_like(py), jnp.zeros_like(area_weight),
            jnp.zeros_like(overlap_weight), jnp.zeros_like(edge_width))


weighted_union_statistics.defvjp(_weighted_union_statistics_fwd, _weighted_union_statistics_bwd)


def capsule_support(caps: ProjectedCapsules, edge_width) -> Float[Array, "*batch views capsules"]:
    """Distance (pixels) from each capsule axis beyond which its soft occupancy is exactly 0."""
    r = caps.radius
    return jnp.sqrt(r * r + 2.0 * r * edge_width)


def _pixel_batch(caps: ProjectedCapsules, height: int, width: int):
    v, u = pixel_grid(height, width, caps.radius.dtype)
    return u.ravel(), v.ravel(), caps.radius.shape[:-1]


def soft_from_capsules(
    caps: ProjectedCapsules, height: int, width: int, edge_width=1.0
) -> Float[Array, "*batch views height width"]:
    """Dense soft silhouettes in [0, 1] from already projected capsules."""
    px, py, batch = _pixel_batch(caps, height, width)
    sil = capsule_union(caps, px, py, jnp.asarray(edge_width, caps.radius.dtype))
    return sil.reshape(batch + (height, width))


def hard_from_capsules(caps: ProjectedCapsules, height: int, width: int) -> Bool[Array, "*batch views height width"]:
    """Binary silhouettes from projected capsules: pixel centres inside some capsule."""
    px, py, batch = _pixel_batch(caps, height, width)
    terms = _capsule_terms(caps, 1.0)
    inside = None
    for k in range(caps.radius.shape[-1]):
        ax, ay, ux, uy, vx, vy, r2, _ = (x[..., k, :] for x in terms)
        hit = (_squared_distance(px, py, ax, ay, ux, uy, vx, vy) <= r2) & (r2 > 0)
        inside = hit if inside is None else inside | hit
    return inside.reshape(batch + (height, width))


def soft_silhouettes(
    body: BodyModel, rig: CameraRig, pose: Float[Array, "*batch dofs"], edge_width=1.0
) -> Float[Array, "*batch views height width"]:
    """Dense soft silhouettes in [0, 1] of a pose (or a batch) in every view.

    Differentiable with respect to the pose, the body (limb lengths, radii) and the cameras.
    Views where part of the body is behind the camera are returned as computed from clamped
    depths: mask them with ``project_capsules(...).in_front``.

    Args:
        edge_width: half-width ``w`` of the soft edge in pixels (sharpness = 1 / w), > 0.
    """
    height, width = image_shape(rig)
    return soft_from_capsules(project_capsules(body, rig, pose), height, width, edge_width)


def hard_silhouettes(
    body: BodyModel, rig: CameraRig, pose: Float[Array, "*batch dofs"]
) -> Bool[Array, "*batch views height width"]:
    """Binary silhouettes: a pixel is on when its centre lies inside some projected capsule."""
    height, width = image_shape(rig)
    return hard_from_capsules(project_capsules(body, rig, pose), height, width)
