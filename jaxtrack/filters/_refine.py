"""Gradient-refined particles: Metropolis-adjusted Langevin moves (MALA; Roberts and Tweedie
1996) after a frame's weighting, in the resample-move scheme of Gilks and Berzuini (2001).

After the particles are weighted, they are resampled and each is moved by K MALA steps whose
target is its own posterior given its ancestor,

    pi_i(s) ∝ p(I_t | pose(s)) p(s | s_{t-1}^{(a_i)}),

(``likelihood`` times ``dynamics.log_transition``). Each step leaves pi_i invariant, so the
particles stay a sample of the filtering posterior: the filter is exactly as valid as without
the moves, while every particle has climbed the likelihood by its gradient (autodiff through
the soft rasteriser). The proposal is preconditioned by the dynamics' noise,

    s' = s + (h^2 / 2) diag(c^2) grad ln pi(s) + h diag(c) xi,    c = dynamics.noise_scales(),

so entries the transition sets exactly (c = 0) stay where they are. With ``adapt`` the step
``h`` of the next step is scaled by ``exp(acceptance - target)`` from the population's
acceptance rate (a move of the whole population, the usual adaptive SMC practice).
``metropolis=False`` gives the unadjusted Langevin move: cheaper in nothing, biased, for
comparison only.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp

from .._custom_types import Array, Float, PRNGKeyArray


class RefineInfo(eqx.Module):
    """Per frame: the acceptance rate of each of the K steps, and the final step size ``h``."""

    acceptance: Float[Array, " k"]
    step_size: Float[Array, ""]


def _value_and_gradients(log_target, states):
    """Per-particle values (N,) and gradients (N, S) of a target whose particles are independent;
    non-finite values become ``-inf`` and their gradients zero."""
    values, pullback = jax.vjp(log_target, states)
    (grads,) = pullback(jnp.ones_like(values))
    finite = jnp.isfinite(values)
    grads = jnp.where(finite[:, None] & jnp.all(jnp.isfinite(grads), axis=1, keepdims=True), grads, 0.0)
    return jnp.where(finite, values, -jnp.inf), grads


class LangevinRefinement(eqx.Module):
    """K MALA moves per frame (module docstring).

    Attributes:
        num_steps: K, the moves per frame (each costs one likelihood gradient per particle).
        step_size: the initial ``h``, relative to the dynamics' noise scales.
        metropolis: accept or reject each move (MALA); False for unadjusted Langevin.
        adapt: scale ``h`` between steps towards ``target_acceptance``.
        target_acceptance: 0.574, the optimal rate of MALA (Roberts and Rosenthal 1998).
    """

    num_steps: int = eqx.field(static=True, default=2)
    step_size: float = eqx.field(static=True, default=0.5)
    metropolis: bool = eqx.field(static=True, default=True)
    adapt: bool = eqx.field(static=True, default=True)
    target_acceptance: float = eqx.field(static=True, default=0.574)

    def __check_init__(self):
        if isinstance(self.num_steps, bool) or not isinstance(self.num_steps, int) or self.num_steps < 1:
            raise ValueError(f"num_steps must be a positive integer, got {self.num_steps!r}")
        if not self.step_size > 0:
            raise ValueError(f"step_size must be positive, got {self.step_size!r}")
        if not 0.0 < self.target_acceptance < 1.0:
            raise ValueError(f"target_acceptance must be in (0, 1), got {self.target_acceptance!r}")

    def __call__(
        self, key: PRNGKeyArray, states: Float[Array, "n s"], log_target: Callable, scales: Float[Array, " s"]
    ) -> tuple[Float[Array, "n s"], RefineInfo]:
        """Move ``states`` by K steps targeting ``log_target: (N, S) -> (N,)`` (a sum of
        per-particle terms), preconditioned by ``scales`` (S,)."""
        dtype = states.dtype
        scales = scales.astype(dtype)
        variance = scales**2

        def log_proposal(to, mean, h):
            safe = jnp.where(scales > 0, h * scales, 1.0)
            return -0.5 * jnp.sum(jnp.where(scales > 0, ((to - mean) / safe) ** 2, 0.0), axis=1)

        def step(carry, k):
            x, value, grad, h = carry
            noise_key, accept_key = jax.random.split(jax.random.fold_in(key, k))
            mean = x + 0.5 * h**2 * variance * grad
            proposed = mean + h * scales * jax.random.normal(noise_key, x.shape, dtype)
            new_value, new_grad = _value_and_gradients(log_target, proposed)
            if self.metropolis:
                back = proposed + 0.5 * h**2 * variance * new_grad
                log_ratio = new_value - value + log_proposal(x, back, h) - log_proposal(proposed, mean, h)
                log_ratio = jnp.where(jnp.isfinite(new_value), log_ratio, -jnp.inf)
                log_ratio = jnp.where(jnp.isnan(log_ratio), -jnp.inf, log_ratio)
                accept = jnp.log(jax.random.uniform(accept_key, value.shape, dtype)) < log_ratio
            else:
                accept = jnp.isfinite(new_value)
            rate = jnp.mean(accept.astype(dtype))
            x = jnp.where(accept[:, None], proposed, x)
            value = jnp.where(accept, new_value, value)
            grad = jnp.where(accept[:, None], new_grad, grad)
            if self.adapt:
                h = h * jnp.exp(rate - self.target_acceptance)
            return (x, value, grad, h), rate

        value, grad = _value_and_gradients(log_target, states)
        h0 = jnp.asarray(self.step_size, dtype)
        (states, _, _, h), rates = jax.lax.scan(step, (states, value, grad, h0), jnp.arange(self.num_steps))
        return states, RefineInfo(acceptance=rates, step_size=h)


def resample_and_refine(refinement: LangevinRefinement, key, particles, previous, log_weights, *, dynamics, log_likelihood,
                        resample):
    """Resample ``particles`` (N, S) with their ancestors' states ``previous`` (N, S) by
    ``log_weights``, then move each by ``refinement`` towards ``log_likelihood(s) +
    dynamics.log_transition(previous_i, s)``. Returns the moved particles, uniform log-weights
    and the ``RefineInfo``."""
    resample_key, move_key = jax.random.split(key)
    ancestors = resample(resample_key, log_weights)
    particles, previous = particles[ancestors], previous[ancestors]

    def log_target(states):
        return log_likelihood(states) + dynamics.log_transition(previous, states)

    moved, info = refinement(move_key, particles, log_target, dynamics.noise_scales())
    n = particles.shape[0]
    return moved, jnp.full(n, -jnp.log(n), particles.dtype), info
