"""Binary morphology on (..., H, W) masks with a disk or a square of radius r: dilation, erosion,
opening and closing, as ``scipy.ndimage.binary_dilation`` and ``binary_erosion`` with that
structuring element (outside the image counts as background). A disk of radius up to
``SHIFTED_RADIUS`` is the OR of the mask shifted by every offset (dx, dy) with dx^2 + dy^2 <= r^2
(13 shifts for r = 2, fused by XLA into one pass); a larger one is exact through the distance
transform within r (a pixel is within the dilation iff its squared distance to the mask is at
most r^2); the square is a separable running maximum (``lax.reduce_window``)."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

from .._custom_types import Array, Bool
from ._distance import squared_distance_transform

SHAPES = ("disk", "square")
# Disks up to this radius are dilated by shifted copies: for background subtraction's opening (r 1)
# and closing (r 2) of 3 views of 320x240, 8 ms a frame through the distance transform, 2 ms shifted.
SHIFTED_RADIUS = 3


def _check(mask, radius: int, shape: str):
    mask = jnp.asarray(mask)
    if mask.ndim < 2:
        raise ValueError(f"mask must be (..., height, width), got shape {mask.shape}")
    if isinstance(radius, bool) or not isinstance(radius, int) or radius < 0:
        raise ValueError(f"radius must be a whole number of pixels >= 0, got {radius!r}")
    if shape not in SHAPES:
        raise ValueError(f"shape must be one of {SHAPES}, got {shape!r}")
    return mask.astype(bool)


def dilate(mask, radius: int = 1, shape: str = "disk") -> Bool[Array, "... H W"]:
    """Pixels within ``radius`` of the mask (a disk: Euclidean; a square: the (2r + 1)^2 box)."""
    return _dilate(_check(mask, radius, shape), radius, shape)


@functools.partial(jax.jit, static_argnums=(1, 2))
def _dilate(mask, radius: int, shape: str):
    if radius == 0:
        return mask
    if shape == "disk" and radius <= SHIFTED_RADIUS:
        padded = jnp.pad(mask, [(0, 0)] * (mask.ndim - 2) + [(radius, radius), (radius, radius)])
        height, width = mask.shape[-2:]
        grown = jnp.zeros_like(mask)
        for dy in range(-radius, radius + 1):
            for dx in range(-radius, radius + 1):
                if dx * dx + dy * dy <= radius * radius:
                    grown = grown | padded[..., radius + dy : radius + dy + height, radius + dx : radius + dx + width]
        return grown
    if shape == "disk":
        return squared_distance_transform(mask, max_distance=radius) <= radius * radius
    window = (1,) * (mask.ndim - 2) + (2 * radius + 1, 2 * radius + 1)
    pad = [(0, 0)] * (mask.ndim - 2) + [(radius, radius), (radius, radius)]
    return jax.lax.reduce_window(mask, False, jax.lax.bitwise_or, window, (1,) * mask.ndim, pad)


def erode(mask, radius: int = 1, shape: str = "disk") -> Bool[Array, "... H W"]:
    """Pixels whose whole neighbourhood (disk or square of ``radius``) is in the mask; the
    border of the image counts as background, so the mask shrinks from it too."""
    mask = _check(mask, radius, shape)
    if radius == 0:
        return mask
    pad = [(0, 0)] * (mask.ndim - 2) + [(1, 1), (1, 1)]
    outside = jnp.pad(~mask, pad, constant_values=True)  # a frame of background around the image
    return ~dilate(outside, radius, shape)[..., 1:-1, 1:-1]


def opening(mask, radius: int = 1, shape: str = "disk") -> Bool[Array, "... H W"]:
    """Erosion then dilation: removes specks smaller than the structuring element."""
    return dilate(erode(mask, radius, shape), radius, shape)


def closing(mask, radius: int = 1, shape: str = "disk") -> Bool[Array, "... H W"]:
    """Dilation then erosion: fills holes and gaps smaller than the structuring element (the
    image border, unlike SciPy's, does not erode what the dilation brought to it)."""
    return _closing(_check(mask, radius, shape), radius, shape)


@functools.partial(jax.jit, static_argnums=(1, 2))
def _closing(mask, radius: int, shape: str):
    pad = [(0, 0)] * (mask.ndim - 2) + [(radius, radius), (radius, radius)]
    padded = jnp.pad(mask, pad)
    closed = ~_dilate(~_dilate(padded, radius, shape), radius, shape)
    return closed[..., radius : radius + mask.shape[-2], radius : radius + mask.shape[-1]]
