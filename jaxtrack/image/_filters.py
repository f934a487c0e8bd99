"""Linear filters on (..., H, W) images, any leading axes (views, frames): the Gaussian blur and
the Sobel derivatives, with SciPy's default border (``mode="reflect"``: the image mirrored about
its edge, ``d c b a | a b c d``), so that ``scipy.ndimage`` is their reference. Separable, so a
blur of standard deviation s costs 2 (2 ceil(4 s) + 1) products per pixel. Pure JAX: jit, vmap
and grad apply."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float

TRUNCATE = 4.0  # the Gaussian kernel's radius in standard deviations (SciPy's default)


def _check_image(image, name: str = "image") -> jnp.ndarray:
    image = jnp.asarray(image)
    if image.ndim < 2:
        raise ValueError(f"{name} must be (..., height, width), got shape {image.shape}")
    if not jnp.issubdtype(image.dtype, jnp.floating):
        image = image.astype(jnp.float32)
    return image


def gaussian_kernel(sigma: float, truncate: float = TRUNCATE) -> np.ndarray:
    """(2r + 1,) normalised Gaussian weights of standard deviation ``sigma`` pixels, radius
    r = int(truncate * sigma + 0.5) (as ``scipy.ndimage.gaussian_filter``)."""
    if not (np.isfinite(sigma) and sigma > 0):
        raise ValueError(f"sigma must be a positive number of pixels, got {sigma!r}")
    radius = int(truncate * float(sigma) + 0.5)
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    weights = np.exp(-0.5 * (x / float(sigma)) ** 2)
    return weights / weights.sum()


def correlate1d(image, weights, axis: int) -> Float[Array, ...]:
    """``image`` correlated with the odd-length ``weights`` along ``axis`` (-1: columns, -2:
    rows), borders reflected: ``out[i] = sum_k weights[k] image[i + k - r]``."""
    weights = np.asarray(weights, np.float64)
    if weights.ndim != 1 or weights.size % 2 == 0:
        raise ValueError(f"weights must be one odd-length vector, got shape {weights.shape}")
    radius = weights.size // 2
    axis = axis % image.ndim
    size = image.shape[axis]
    pad = [(0, 0)] * image.ndim
    pad[axis] = (radius, radius)
    if radius > size:  # a kernel wider than the image: reflect repeatedly, as SciPy does
        index = np.arange(-radius, size + radius)
        period = 2 * size
        index = np.mod(index, period)
        index = np.where(index >= size, period - 1 - index, index)
        padded = jnp.take(image, jnp.asarray(index), axis=axis)
    else:
        padded = jnp.pad(image, pad, mode="symmetric")
    out = jnp.zeros_like(image)
    for k, w in enumerate(weights):
        if w != 0:
            out = out + jnp.asarray(w, image.dtype) * jax.lax.slice_in_dim(padded, k, k + size, axis=axis)
    return out


def gaussian_blur(image, sigma: float | tuple[float, float], *, truncate: float = TRUNCATE) -> Float[Array, "... H W"]:
    """(..., H, W) images blurred by a Gaussian of ``sigma`` pixels (one number, or (rows,
    columns)); ``scipy.ndimage.gaussian_filter(image, sigma)`` over the last two axes."""
    image = _check_image(image)
    sigma_rows, sigma_cols = (sigma, sigma) if np.isscalar(sigma) else tuple(sigma)
    rows, cols = gaussian_kernel(sigma_rows, truncate), gaussian_kernel(sigma_cols, truncate)  # checked here, eagerly
    return _blur(image, tuple(rows.tolist()), tuple(cols.tolist()))


@functools.partial(jax.jit, static_argnums=(1, 2))
def _blur(image, rows: tuple, cols: tuple):
    return correlate1d(correlate1d(image, rows, axis=-2), cols, axis=-1)


def sobel(image) -> tuple[Float[Array, "... H W"], Float[Array, "... H W"]]:
    """The Sobel derivatives ``(d/dx, d/dy)`` of (..., H, W) images, x along the columns and y
    down the rows (unnormalised: a unit step gives 4); ``scipy.ndimage.sobel(image, axis=-1)``
    and ``(image, axis=-2)``."""
    return _sobel(_check_image(image))


@jax.jit
def _sobel(image):
    derivative, smooth = np.array([-1.0, 0.0, 1.0]), np.array([1.0, 2.0, 1.0])
    dx = correlate1d(correlate1d(image, derivative, axis=-1), smooth, axis=-2)
    dy = correlate1d(correlate1d(image, derivative, axis=-2), smooth, axis=-1)
    return dx, dy


def gradient_magnitude(image, sigma: float | None = None) -> Float[Array, "... H W"]:
    """|Sobel gradient| of (..., H, W) images, after a Gaussian blur of ``sigma`` when given."""
    image = _check_image(image)
    if sigma is not None:
        image = gaussian_blur(image, sigma)
    dx, dy = sobel(image)
    return jnp.sqrt(dx**2 + dy**2)
