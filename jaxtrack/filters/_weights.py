"""Log-weight arithmetic shared by every particle filter.

Weights are kept as logs throughout. A weight set that is all ``-inf`` or NaN (every particle
impossible, e.g. all behind a camera) is *degenerate*: it is replaced by uniform weights and
flagged, so no NaN ever leaves a filter step.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._custom_types import Array, Bool, Float


def normalise_log_weights(log_weights: Float[Array, " n"]) -> tuple[Float[Array, " n"], Bool[Array, ""]]:
    """Normalised log-weights (logsumexp 0) and whether the input was degenerate.

    NaN entries count as ``-inf``; when no entry is finite the result is uniform (``-ln N``).
    """
    n = log_weights.shape[0]
    clean = jnp.where(jnp.isnan(log_weights), -jnp.inf, log_weights)
    degenerate = ~jnp.any(jnp.isfinite(clean) | (clean == jnp.inf))
    # +inf particles share the mass equally; otherwise the usual shift by the maximum.
    clean = jnp.where(jnp.any(clean == jnp.inf), jnp.where(clean == jnp.inf, 0.0, -jnp.inf), clean)
    clean = jnp.where(degenerate, jnp.zeros_like(clean), clean)
    normalised = clean - jax.nn.logsumexp(clean)
    return jnp.where(degenerate, -jnp.log(n).astype(clean.dtype), normalised), degenerate


def effective_sample_size(log_weights: Float[Array, " n"]) -> Float[Array, ""]:
    """``1 / sum w_i^2`` of the normalised weights, in [1, N]."""
    normalised, _ = normalise_log_weights(log_weights)
    return jnp.exp(-jax.nn.logsumexp(2.0 * normalised))


def log_mean_exp(values: Float[Array, " n"]) -> Float[Array, ""]:
    """``ln (1/N sum exp v_i)``: the log-likelihood increment (evidence) of a step whose
    particles carried uniform weights before weighting; ``-inf`` when all are ``-inf``."""
    clean = jnp.where(jnp.isnan(values), -jnp.inf, values)
    return jax.nn.logsumexp(clean) - jnp.log(values.shape[0]).astype(clean.dtype)


def weighted_mean(log_weights: Float[Array, " n"], values: Float[Array, "n ..."]) -> Float[Array, ...]:
    """``sum_i w_i v_i`` with normalised weights (uniform when degenerate)."""
    normalised, _ = normalise_log_weights(log_weights)
    w = jnp.exp(normalised).astype(values.dtype)
    return jnp.tensordot(w, values, axes=1)


def best_particle(log_weights: Float[Array, " n"], values: Float[Array, "n ..."]) -> Float[Array, ...]:
    """The particle of largest weight (the first one when degenerate)."""
    clean = jnp.where(jnp.isnan(log_weights), -jnp.inf, log_weights)
    return values[jnp.argmax(clean)]
