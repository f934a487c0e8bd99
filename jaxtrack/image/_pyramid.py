"""Resizing and Gaussian pyramids of (..., H, W) images. ``resize`` is ``jax.image.resize``
(bilinear or cubic, antialiased when shrinking) over the last two axes; ``pyramid`` blurs by one
pixel and keeps every second row and column, level after level (Burt and Adelson's reduce)."""

from __future__ import annotations

import jax

from .._custom_types import Array, Float
from ._filters import _check_image, gaussian_blur

METHODS = ("linear", "cubic", "nearest")


def resize(image, height: int, width: int, method: str = "linear") -> Float[Array, "... height width"]:
    """(..., H, W) images resampled to (..., height, width) with pixel centres aligned (a pixel's
    centre at integer coordinates maps to ``(i + 0.5) * scale - 0.5``, as ``CameraRig.resized``)."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if min(int(height), int(width)) < 1:
        raise ValueError(f"the size must be positive, got {width}x{height}")
    image = _check_image(image)
    return jax.image.resize(image, image.shape[:-2] + (int(height), int(width)), method=method)


def pyramid(image, levels: int, sigma: float = 1.0) -> list[Float[Array, ...]]:
    """[image, reduced once, ...]: ``levels`` images, each the previous blurred by ``sigma``
    pixels and decimated by 2 (its size (H + 1) // 2 x (W + 1) // 2)."""
    if isinstance(levels, bool) or not isinstance(levels, int) or levels < 1:
        raise ValueError(f"levels must be a whole number >= 1, got {levels!r}")
    image = _check_image(image)
    out = [image]
    for _ in range(levels - 1):
        if min(out[-1].shape[-2:]) < 2:
            raise ValueError(f"{levels} levels reduce a {image.shape[-1]}x{image.shape[-2]} image below one pixel")
        out.append(gaussian_blur(out[-1], sigma)[..., ::2, ::2])
    return out

