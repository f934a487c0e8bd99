"""Reading maps at sub-pixel points: bilinear interpolation, differentiable in the points, zero
outside the image (so a model point that leaves the view reads no evidence)."""

from __future__ import annotations

import jax.numpy as jnp

from .._custom_types import Array, Float


def sample_bilinear(image, uv) -> Float[Array, ...]:
    """Values of an (H, W) map at (..., 2) points (u along the columns, v down the rows, pixel
    centres at whole numbers), bilinear; 0 outside the image."""
    image = jnp.asarray(image)
    if image.ndim != 2:
        raise ValueError(f"image must be (height, width), got shape {image.shape}")
    height, width = image.shape
    u, v = uv[..., 0], uv[..., 1]
    u0, v0 = jnp.floor(u), jnp.floor(v)
    fu, fv = u - u0, v - v0
    flat = image.reshape(-1)

    def at(du, dv):
        cu, cv = u0 + du, v0 + dv
        inside = (cu >= 0) & (cu <= width - 1) & (cv >= 0) & (cv <= height - 1)
        index = jnp.clip(cv, 0, height - 1).astype(jnp.int32) * width + jnp.clip(cu, 0, width - 1).astype(jnp.int32)
        return jnp.where(inside, flat[index], 0.0).astype(uv.dtype)

    return ((1 - fu) * (1 - fv) * at(0, 0) + fu * (1 - fv) * at(1, 0) + (1 - fu) * fv * at(0, 1) + fu * fv * at(1, 1))
