"""Resampling: multinomial, stratified, systematic and residual (Douc, Cappe and Moulines 2005).

Each resampler maps ``(key, log_weights (N,))`` to ``N`` ancestor indices; each particle ``i``
is selected ``N w_i`` times in expectation. A degenerate weight set resamples uniformly.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from .._custom_types import Array, Float, Int
from ._weights import normalise_log_weights


def _inverse_cdf(log_weights, uniforms):
    """Indices ``i`` with ``cdf_{i-1} <= u < cdf_i``; zero-weight particles are never chosen."""
    normalised, _ = normalise_log_weights(log_weights)
    cdf = jnp.cumsum(jnp.exp(normalised))
    cdf = cdf / cdf[-1]
    indices = jnp.searchsorted(cdf, uniforms, side="right")
    return jnp.minimum(indices, log_weights.shape[0] - 1).astype(jnp.int32)


def multinomial(key, log_weights: Float[Array, " n"]) -> Int[Array, " n"]:
    """Independent draws from the weights."""
    n = log_weights.shape[0]
    return _inverse_cdf(log_weights, jax.random.uniform(key, (n,), dtype=log_weights.dtype))


def stratified(key, log_weights: Float[Array, " n"]) -> Int[Array, " n"]:
    """One uniform draw in each stratum ``[i/N, (i+1)/N)``."""
    n = log_weights.shape[0]
    u = (jnp.arange(n, dtype=log_weights.dtype) + jax.random.uniform(key, (n,), dtype=log_weights.dtype)) / n
    return _inverse_cdf(log_weights, u)


def systematic(key, log_weights: Float[Array, " n"]) -> Int[Array, " n"]:
    """One uniform offset shared by all strata: ``u_i = (i + U) / N``."""
    n = log_weights.shape[0]
    u = (jnp.arange(n, dtype=log_weights.dtype) + jax.random.uniform(key, (), dtype=log_weights.dtype)) / n
    return _inverse_cdf(log_weights, u)


def residual(key, log_weights: Float[Array, " n"]) -> Int[Array, " n"]:
    """``floor(N w_i)`` copies of each particle, the remaining slots drawn multinomially from the
    residual weights ``N w_i - floor(N w_i)``."""
    n = log_weights.shape[0]
    normalised, _ = normalise_log_weights(log_weights)
    expected = n * jnp.exp(normalised)
    counts = jnp.floor(expected).astype(jnp.int32)
    deterministic = jnp.repeat(jnp.arange(n, dtype=jnp.int32), counts, total_repeat_length=n)
    remainder = expected - counts
    has_remainder = jnp.sum(remainder) > 0
    residual_log = jnp.where(has_remainder, jnp.log(jnp.maximum(remainder, 0.0)), normalised)
    drawn = multinomial(key, residual_log)
    return jnp.where(jnp.arange(n) < jnp.sum(counts), deterministic, drawn)


RESAMPLERS: dict[str, Callable] = {
    "multinomial": multinomial,
    "stratified": stratified,
    "systematic": systematic,
    "residual": residual,
}


def get_resampler(name: str) -> Callable:
    """The resampler called ``name`` (one of ``RESAMPLERS``)."""
    if name not in RESAMPLERS:
        raise ValueError(f"unknown resampler {name!r}; choose one of {sorted(RESAMPLERS)}")
    return RESAMPLERS[name]
