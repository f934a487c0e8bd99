"""Annealing exponents chosen to hit a target survival rate (Deutscher and Reid 2005; 001 Alg. 1).

At a layer with log-likelihoods ``l_i`` the weights are ``w_i ~ exp(beta l_i)``; the survival
rate ``alpha(beta) = ESS(beta l) / N`` falls from 1 at ``beta = 0`` as beta grows, and the
layer's beta is the largest value in (0, 1] with ``alpha(beta) >= target``, found by bisection
on ``log beta``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._custom_types import Array, Float
from ._weights import effective_sample_size

MIN_LOG_BETA = -20.0  # beta = 2e-9


def survival_rate(log_likelihoods: Float[Array, " n"], beta) -> Float[Array, ""]:
    return effective_sample_size(beta * log_likelihoods) / log_likelihoods.shape[0]


def choose_beta(log_likelihoods: Float[Array, " n"], target: float, iterations: int = 40) -> Float[Array, ""]:
    """The largest ``beta`` in (0, 1] whose survival rate is at least ``target``."""
    finite = jnp.isfinite(log_likelihoods)
    # Shift by the best finite value so exp() stays in range; -inf entries stay -inf.
    shifted = log_likelihoods - jnp.max(jnp.where(finite, log_likelihoods, -jnp.inf), initial=-jnp.inf, where=finite)
    shifted = jnp.where(finite, shifted, -jnp.inf)

    def bisect(bounds, _):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        ok = survival_rate(shifted, jnp.exp(mid)) >= target
        return (jnp.where(ok, mid, lo), jnp.where(ok, hi, mid)), None

    dtype = log_likelihoods.dtype
    (lo, _), _ = jax.lax.scan(bisect, (jnp.asarray(MIN_LOG_BETA, dtype), jnp.asarray(0.0, dtype)), None, length=iterations)
    full = survival_rate(shifted, jnp.asarray(1.0, dtype)) >= target
    return jnp.where(full, jnp.asarray(1.0, dtype), jnp.exp(lo))


def check_annealing(num_layers, survival_target, fixed_betas) -> None:
    """Validate the annealing settings shared by APF and GPAPF; raises ``ValueError``."""
    if not isinstance(num_layers, int) or num_layers < 1:
        raise ValueError(f"num_layers must be a positive integer, got {num_layers!r}")
    if not 0.0 < survival_target < 1.0:
        raise ValueError(f"survival_target must be in (0, 1), got {survival_target}")
    if fixed_betas is not None and len(fixed_betas) != num_layers:
        raise ValueError(f"fixed_betas has {len(fixed_betas)} entries for {num_layers} layers")
