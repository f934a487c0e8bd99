"""One SMC layer, the step every filter and every annealing layer is built from.

Order (as in blackjax's ``smc/base.py``): resample by the incoming weights, move each particle
(the dynamics' proposal, or an annealing layer's perturbation), weight by the tempered
likelihood times the move's importance correction, normalise. Weights stay in logs; an
all-``-inf``/NaN set is made uniform and flagged (``normalise_log_weights``), so no NaN leaves
a layer.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax

from .._custom_types import Array, Bool, Float, Int, PRNGKeyArray
from ..errors import TrackingError
from ._weights import effective_sample_size, log_mean_exp, normalise_log_weights


class LayerInfo(eqx.Module):
    """Per layer: the exponent ``beta`` applied to the log-likelihood, the ESS of the new weights,
    whether they were degenerate, ``ln mean_i exp(l_i)`` of the untempered log-likelihoods, and
    each new particle's ancestor (its index in the incoming particles)."""

    beta: Float[Array, ""]
    ess: Float[Array, ""]
    degenerate: Bool[Array, ""]
    log_evidence: Float[Array, ""]
    ancestors: Int[Array, " n"]


def layer_keys(key: PRNGKeyArray, layer) -> tuple[PRNGKeyArray, PRNGKeyArray]:
    """The (resample, move) keys of layer ``layer`` of a frame: ``key`` split in two, each
    folded with the layer index, so layers draw independent numbers from one frame key."""
    resample_key, move_key = jax.random.split(key)
    return jax.random.fold_in(resample_key, layer), jax.random.fold_in(move_key, layer)


def smc_layer(
    keys: tuple[PRNGKeyArray, PRNGKeyArray],
    particles: Float[Array, "n s"],
    log_weights: Float[Array, " n"],
    *,
    move: Callable,
    log_likelihood: Callable,
    resample: Callable,
    temper: Callable | None = None,
) -> tuple[Float[Array, "n s"], Float[Array, " n"], LayerInfo]:
    """Resample, move, weight, normalise.

    Args:
        keys: (resample key, move key), e.g. ``layer_keys(frame_key, m)``.
        particles, log_weights: the incoming particles (N, S) and their log-weights.
        move: ``(key, particles) -> (moved particles, log correction (N,))``, e.g.
            ``dynamics.propose``.
        log_likelihood: ``particles (N, S) -> (N,)`` log-likelihoods of this frame.
        resample: ``(key, log_weights) -> (N,) ancestor indices``.
        temper: ``log_likelihoods -> beta``; None for ``beta = 1`` (no tempering).

    Returns:
        the moved particles, their normalised log-weights
        ``beta l_i + correction_i - logsumexp(...)``, and the ``LayerInfo``.
    """
    resample_key, move_key = keys
    ancestors = resample(resample_key, log_weights)
    moved, log_correction = move(move_key, particles[ancestors])
    log_lik = log_likelihood(moved)
    check_layer_shapes(particles, moved, log_correction, log_lik)
    new_log_weights, info = weigh_layer(log_lik, log_correction, ancestors, temper)
    return moved, new_log_weights, info


def weigh_layer(
    log_lik: Float[Array, " n"], log_correction: Float[Array, " n"], ancestors: Int[Array, " n"], temper: Callable | None = None
) -> tuple[Float[Array, " n"], LayerInfo]:
    """The weighting half of ``smc_layer``: normalised log-weights
    ``beta l_i + correction_i - logsumexp(...)`` of moved particles and the layer's ``LayerInfo``
    (for a layer that resamples and moves in its own way, e.g. APF's final layer)."""
    if temper is None:
        beta = jax.numpy.ones((), log_lik.dtype)
        tempered = log_lik
    else:
        beta = temper(log_lik)
        tempered = beta * log_lik
    new_log_weights, degenerate = normalise_log_weights(tempered + log_correction)
    info = LayerInfo(beta=beta, ess=effective_sample_size(new_log_weights), degenerate=degenerate, log_evidence=log_mean_exp(log_lik),
                     ancestors=ancestors)
    return new_log_weights, info


def check_layer_shapes(particles, moved, log_correction, log_lik) -> None:
    """Raise ``TrackingError`` (at trace time, before anything runs) when a dynamics' move or a
    likelihood breaks its contract: N moved particles of the state's size, and one finite-able
    floating value per particle."""
    n = particles.shape[0]
    if moved.shape != particles.shape:
        raise TrackingError(f"the dynamics' move returned particles of shape {moved.shape} for {particles.shape} "
                            "(it must keep the number of particles and the state size)")
    for name, value in (("the likelihood", log_lik), ("the dynamics' log correction", log_correction)):
        if value.shape != (n,):
            raise TrackingError(f"{name} returned shape {value.shape} for {n} particles; it must return one value per particle, "
                                f"shape ({n},)")
        if not jax.numpy.issubdtype(value.dtype, jax.numpy.floating):
            raise TrackingError(f"{name} returned {value.dtype} values; it must return floating log-densities")
