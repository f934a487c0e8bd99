"""Colour conversions of (..., H, W, 3) RGB images: to floats in [0, 1], to grey (ITU-R BT.601
luma, what OpenCV and Pillow use), and to normalised chromaticity with intensity (r, g, I), the
space in which a shadow keeps its chromaticity and loses intensity (the shadow test of
background subtraction)."""

from __future__ import annotations

import jax.numpy as jnp

from .._custom_types import Array, Float

LUMA_WEIGHTS = (0.299, 0.587, 0.114)  # ITU-R BT.601


def _check_rgb(image):
    image = jnp.asarray(image)
    if image.ndim < 3 or image.shape[-1] != 3:
        raise ValueError(f"an RGB image must be (..., height, width, 3), got shape {image.shape}")
    return image


def to_float(image) -> Float[Array, ...]:
    """uint8 images as float32 in [0, 1]; floating images as they are."""
    image = jnp.asarray(image)
    if image.dtype == jnp.uint8:
        return image.astype(jnp.float32) / 255.0
    if not jnp.issubdtype(image.dtype, jnp.floating):
        raise ValueError(f"images must be uint8 or floating, got {image.dtype}")
    return image


def rgb_to_grey(image) -> Float[Array, "... H W"]:
    """(..., H, W, 3) RGB (uint8 or [0, 1]) -> (..., H, W) grey in [0, 1], BT.601 luma."""
    image = to_float(_check_rgb(image))
    return image @ jnp.asarray(LUMA_WEIGHTS, image.dtype)


def channels(image) -> tuple[Float[Array, "... H W"], Float[Array, "... H W"], Float[Array, "... H W"]]:
    """(..., H, W, 3) -> its three (..., H, W) planes. Per-pixel arithmetic on planes is what
    XLA's CPU backend vectorises; a reduction over the last axis of 3 (``jnp.linalg.norm(...,
    axis=-1)``) ran about 4 times slower on background subtraction's frames."""
    return image[..., 0], image[..., 1], image[..., 2]


def chromaticity(red, green, blue, eps: float = 1e-6):
    """``rgb_to_chromaticity`` on three (..., H, W) planes: the planes (r, g, I)."""
    total = red + green + blue
    safe = jnp.maximum(total, eps)
    r = jnp.where(total > eps, red / safe, 1.0 / 3.0)
    g = jnp.where(total > eps, green / safe, 1.0 / 3.0)
    return r, g, total / 3.0


def rgb_to_chromaticity(image, eps: float = 1e-6) -> Float[Array, "... H W 3"]:
    """(..., H, W, 3) RGB -> (..., H, W, 3) (r, g, I): r = R / (R + G + B), g = G / (R + G + B)
    and the intensity I = (R + G + B) / 3, in [0, 1]; black has r = g = 1/3."""
    return jnp.stack(chromaticity(*channels(to_float(_check_rgb(image))), eps), axis=-1)
