"""Edges and the edge-proximity map of paper 001.

``canny_edges`` follows Canny's recipe: a Gaussian blur, the Sobel gradient, non-maximum
suppression across the edge (the gradient direction quantised to 0, 45, 90 or 135 degrees),
and hysteresis (weak edges kept where they connect to strong ones, grown to convergence in a
``lax.while_loop``). Thresholds are fractions of each image's largest gradient magnitude, so
one setting serves silhouettes, grey images and frames of any contrast.

``edge_proximity`` is the map 001 eq. 12 reads at the model's edge points (after Deutscher and
Reid): each pixel's value falls off with its distance d to the nearest edge,
``p_e = exp(-d^2 / (2 s^2))``, d from the exact distance transform within 4 s (0 beyond); 1 on
an edge, about 0.14 at 2 s.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Bool, Float
from . import _bitmask
from ._distance import squared_distance_transform
from ._filters import _check_image, gaussian_blur, sobel


def _neighbour(x, dy: int, dx: int):
    """x shifted so that out[i, j] = x[i + dy, j + dx] (zero outside)."""
    pad = [(0, 0)] * (x.ndim - 2) + [(1, 1), (1, 1)]
    padded = jnp.pad(x, pad)
    height, width = x.shape[-2:]
    return padded[..., 1 + dy : 1 + dy + height, 1 + dx : 1 + dx + width]


def non_maximum_suppression(dx, dy) -> Float[Array, "... H W"]:
    """The gradient magnitude where it is a maximum across the edge (along the gradient,
    quantised to 4 directions), else 0; of two equal neighbours the second is kept."""
    magnitude = jnp.sqrt(dx**2 + dy**2)
    angle = jnp.mod(jnp.arctan2(dy, dx), np.pi)  # [0, pi): a direction, not a sense
    sector = jnp.mod(jnp.round(angle / (np.pi / 4)), 4).astype(jnp.int32)  # 0: x, 1: 45 deg, 2: y, 3: 135 deg
    steps = ((0, 1), (1, 1), (1, 0), (1, -1))  # (dy, dx) along each sector's gradient direction
    keep = jnp.zeros(magnitude.shape, bool)
    for s, (sy, sx) in enumerate(steps):
        # strictly above the next pixel along the gradient, at least the previous one: a ridge two
        # pixels wide (a step between pixels) keeps one of them
        peak = (magnitude > _neighbour(magnitude, sy, sx)) & (magnitude >= _neighbour(magnitude, -sy, -sx))
        keep = keep | ((sector == s) & peak)
    return jnp.where(keep, magnitude, 0.0)


def hysteresis(strong, weak) -> Bool[Array, "... H W"]:
    """The ``weak`` pixels 8-connected, through weak pixels, to a ``strong`` one (``strong``
    must lie within ``weak``)."""
    return _hysteresis(jnp.asarray(strong, bool), jnp.asarray(weak, bool))


GROWTHS_PER_CHECK = 8  # 8-neighbour growths between two tests of the fixed point


@jax.jit
def _hysteresis(strong, weak):
    """Grown on masks packed 32 pixels to a word (``_bitmask``): for background subtraction of
    3 views of 320x240 about 5 ms a frame as boolean shifted slices, 4 growths a test, and
    about 0.5 ms packed (2 cores)."""
    width = weak.shape[-1]
    weak = _bitmask.pack(weak)

    def grow(state):
        edges, _ = state
        # growing past the fixed point leaves it where it is; a loop, not unrolled: XLA fused 16
        # unrolled growths into a program 15 times slower than 16 passes of one
        grown = jax.lax.fori_loop(0, GROWTHS_PER_CHECK, lambda _, grown: _bitmask.grow(grown) & weak, edges)
        return grown, jnp.any(grown != edges)

    edges, _ = jax.lax.while_loop(lambda state: state[1], grow, (_bitmask.pack(strong) & weak, jnp.array(True)))
    return _bitmask.unpack(edges, width)


def canny_edges(image, sigma: float = 1.0, low: float = 0.1, high: float = 0.2, *, region=None) -> Bool[Array, "... H W"]:
    """Canny edges of (..., H, W) images: blur by ``sigma`` pixels, Sobel, non-maximum
    suppression, hysteresis between ``low`` and ``high`` (fractions of each image's largest
    gradient magnitude, 0 <= low <= high <= 1). An image without contrast has no edges.

    ``region`` (..., H, W) bool, if given: only edges inside it, the thresholds fractions of the
    largest gradient inside it (a person's edges against the clutter of the rest of the frame)."""
    image = _check_image(image)
    return _canny(image, _region(region, image.shape), *_thresholds(sigma, low, high))


def colour_canny_edges(image, sigma: float = 1.0, low: float = 0.1, high: float = 0.2, *,
                       region=None) -> Bool[Array, "... H W"]:
    """Canny edges of (..., H, W, 3) colour images (floats): each pixel's gradient is that of the
    channel where it is largest (as OpenCV's Canny does for colour), so an edge between two
    colours of the same brightness is found; otherwise as ``canny_edges``."""
    image = jnp.asarray(image)
    if image.ndim < 3 or image.shape[-1] != 3:
        raise ValueError(f"a colour image must be (..., height, width, 3), got shape {image.shape}")
    channels = _check_image(jnp.moveaxis(image, -1, -3))  # (..., 3, H, W)
    return _colour_canny(channels, _region(region, channels.shape[:-3] + channels.shape[-2:]), *_thresholds(sigma, low, high))


def _thresholds(sigma, low, high):
    if not (0 <= low <= high <= 1):
        raise ValueError(f"thresholds must satisfy 0 <= low <= high <= 1 (fractions of the largest gradient), got {low}, {high}")
    return float(sigma), float(low), float(high)


def _region(region, shape):
    if region is None:
        return jnp.ones(shape, bool)
    region = jnp.asarray(region, bool)
    if region.shape != shape:
        raise ValueError(f"region must have the image's shape {shape}, got {region.shape}")
    return region


@functools.partial(jax.jit, static_argnums=(2, 3, 4))
def _canny(image, region, sigma: float, low: float, high: float):
    dx, dy = sobel(gaussian_blur(image, sigma))
    return _thin_and_link(dx, dy, region, jnp.max(jnp.abs(image), axis=(-2, -1), keepdims=True), low, high)


@functools.partial(jax.jit, static_argnums=(2, 3, 4))
def _colour_canny(channels, region, sigma: float, low: float, high: float):
    dx, dy = sobel(gaussian_blur(channels, sigma))  # (..., 3, H, W)
    best = jnp.argmax(dx**2 + dy**2, axis=-3, keepdims=True)
    dx, dy = (jnp.take_along_axis(d, best, axis=-3)[..., 0, :, :] for d in (dx, dy))
    return _thin_and_link(dx, dy, region, jnp.max(jnp.abs(channels), axis=(-3, -2, -1))[..., None, None], low, high)


def _thin_and_link(dx, dy, region, brightest, low: float, high: float):
    thin = jnp.where(region, non_maximum_suppression(dx, dy), 0.0)
    scale = jnp.max(jnp.where(region, jnp.sqrt(dx**2 + dy**2), 0.0), axis=(-2, -1), keepdims=True)
    live = scale > 1e-6 * jnp.maximum(1.0, brightest)
    strong = live & (thin >= high * scale) & (thin > 0)
    weak = live & (thin >= low * scale) & (thin > 0)
    return hysteresis(strong, weak)


def edge_proximity(edges, scale: float = 2.0) -> Float[Array, "... H W"]:
    """(..., H, W) map in [0, 1] that falls off with the distance d (pixels) to the nearest edge
    pixel: ``exp(-d^2 / (2 scale^2))`` (001's edge map), 0 beyond 4 scales and everywhere in an
    image without edges."""
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a positive number of pixels, got {scale!r}")
    return _proximity(jnp.asarray(edges, bool), float(scale))


@functools.partial(jax.jit, static_argnums=1)
def _proximity(edges, scale: float):
    reach = int(np.ceil(4.0 * scale))  # beyond 4 scales the map is below 3.4e-4: 0
    squared = squared_distance_transform(edges, max_distance=reach)
    return jnp.where(jnp.isfinite(squared), jnp.exp(-squared / (2.0 * scale * scale)), 0.0)
