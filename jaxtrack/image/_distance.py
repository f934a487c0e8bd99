"""The exact Euclidean distance transform in JAX: each pixel's distance to the nearest feature
pixel, by Felzenszwalb and Huttenlocher's lower envelope of parabolas (P. F. Felzenszwalb and
D. P. Huttenlocher, "Distance Transforms of Sampled Functions", Theory of Computing 8, 2012),
one pass along the rows and one along the columns, each linear in the pixels.

The 1-D pass keeps the lower envelope of the parabolas ``(q - p)^2 + f(p)`` rooted at the
pixels p: a ``lax.scan`` over the pixels pushes each new parabola after popping those it hides
(a ``lax.while_loop``); each pixel's value is then read from the envelope segment that holds it
(a ``searchsorted`` on the segments' boundaries). Vmapped over rows and over any leading axes.
Values are whole numbers below 2^24 for images up to 2,800 pixels on a side, so float32 keeps
them exact and the result equals ``scipy.ndimage.distance_transform_edt`` (tested).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

from .._custom_types import Array, Float


def _envelope_1d(f):
    """Squared distance transform of one sampled function f (n,): min_p (q - p)^2 + f(p)."""
    n = f.shape[0]
    q = jnp.arange(n, dtype=f.dtype)
    h = f + q * q

    def meet(a, b):  # where the parabolas rooted at a and b cross (a > b)
        return (h[a] - h[b]) / (2.0 * (a - b).astype(f.dtype))

    def push(carry, a):
        k, roots, bounds = carry
        s = meet(a, roots[k])

        def hidden(state):
            k, s = state
            return s <= bounds[k]

        def pop(state):
            k, _ = state
            return k - 1, meet(a, roots[k - 1])

        k, s = jax.lax.while_loop(hidden, pop, (k, s))  # bounds[0] = -inf: k never leaves 0
        k = k + 1
        return (k, roots.at[k].set(a), bounds.at[k].set(s)), None

    roots = jnp.zeros(n, jnp.int32)
    bounds = jnp.full(n + 1, jnp.inf, f.dtype).at[0].set(-jnp.inf)
    (k, roots, bounds), _ = jax.lax.scan(push, (jnp.int32(0), roots, bounds), jnp.arange(1, n, dtype=jnp.int32))
    bounds = jnp.where(jnp.arange(n + 1) <= k, bounds, jnp.inf)
    segment = jnp.searchsorted(bounds, q, side="left") - 1  # the last boundary below q
    root = roots[segment]
    return (q - root.astype(f.dtype)) ** 2 + f[root]


def squared_distance_transform(features, max_distance: int | None = None) -> Float[Array, "... H W"]:
    """(..., H, W) squared Euclidean distance, in pixels^2, from every pixel to the nearest
    True pixel of ``features`` (0 on them); ``inf`` in an image without one.

    With ``max_distance`` = R (whole pixels), distances up to R are exact and larger ones
    ``inf``: two separable passes of 2R + 1 shifted minima (the same lower envelope, its
    parabolas limited to offsets within R), much faster than the full transform when R is
    small (edge maps, morphology)."""
    features = jnp.asarray(features)
    if features.ndim < 2:
        raise ValueError(f"features must be (..., height, width), got shape {features.shape}")
    if max_distance is None:
        return _squared_distance(features.astype(bool))
    if isinstance(max_distance, bool) or not isinstance(max_distance, int) or max_distance < 0:
        raise ValueError(f"max_distance must be a whole number of pixels >= 0, got {max_distance!r}")
    return _squared_distance_within(features.astype(bool), max_distance)


def _shifted_minimum(cost, radius: int, axis: int):
    """min over |k| <= radius of k^2 + cost[i + k] along ``axis`` (inf outside the image)."""
    size = cost.shape[axis]
    pad = [(0, 0)] * cost.ndim
    pad[axis] = (radius, radius)
    padded = jnp.pad(cost, pad, constant_values=jnp.inf)
    out = cost
    for k in range(-radius, radius + 1):
        if k:
            out = jnp.minimum(out, float(k * k) + jax.lax.slice_in_dim(padded, radius + k, radius + k + size, axis=axis))
    return out


@functools.partial(jax.jit, static_argnums=1)
def _squared_distance_within(features, radius: int):
    cost = jnp.where(features, 0.0, jnp.inf).astype(jnp.float32)
    squared = _shifted_minimum(_shifted_minimum(cost, radius, -1), radius, -2)
    return jnp.where(squared <= radius * radius, squared, jnp.inf)


@jax.jit
def _squared_distance(features):
    """``squared_distance_transform`` compiled once per shape (traced inside a caller's jit)."""
    height, width = features.shape[-2:]
    big = float(height * height + width * width + 1)  # beyond any real squared distance
    cost = jnp.where(features, 0.0, big).astype(jnp.float32)
    flat = cost.reshape((-1, height, width))
    rows = jax.vmap(jax.vmap(_envelope_1d))(flat)  # along each row
    both = jax.vmap(jax.vmap(_envelope_1d))(jnp.swapaxes(jnp.minimum(rows, big), -1, -2))  # then each column
    squared = jnp.swapaxes(both, -1, -2).reshape(features.shape)
    return jnp.where(squared >= big, jnp.inf, squared)


def distance_transform(features) -> Float[Array, "... H W"]:
    """(..., H, W) Euclidean distance in pixels from every pixel to the nearest True pixel of
    ``features`` (``scipy.ndimage.distance_transform_edt(~features)``); ``inf`` in an image
    without one."""
    return jnp.sqrt(squared_distance_transform(features))
