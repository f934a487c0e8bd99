"""Pose-space trackers with Gaussian diffusion dynamics: SIR / Condensation (001 eqs. 1-4) and
the annealed particle filter (Deutscher and Reid 2005; 001 Alg. 1)."""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp

from .._custom_types import Array, Float
from ._annealing import check_annealing, choose_beta
from ._core import FilterState, StepInfo, check_particles, check_scales, duplicate
from ._resampling import get_resampler
from ._weights import best_particle, effective_sample_size, log_mean_exp, normalise_log_weights, weighted_mean

ESTIMATORS = ("mean", "best")


def diffuse(key, particles: Float[Array, "n s"], scales: Float[Array, " s"]) -> Float[Array, "n s"]:
    """``x + N(0, diag(scales^2))`` for every particle."""
    return particles + scales * jax.random.normal(key, particles.shape, particles.dtype)


def estimate_pose(estimator: str, log_weights, particles):
    return weighted_mean(log_weights, particles) if estimator == "mean" else best_particle(log_weights, particles)


def _check_estimator(estimator, allowed=ESTIMATORS):
    if estimator not in allowed:
        raise ValueError(f"estimator must be one of {allowed}, got {estimator!r}")


class SIR(eqx.Module):
    """Sampling importance resampling (Condensation) with Gaussian diffusion in pose space.

    Per frame: resample by the previous weights, ``x_t = x_{t-1} + N(0, diag(scales^2))``,
    weight by the likelihood, estimate by the weighted mean (or the best particle).
    """

    likelihood: Callable
    scales: Float[Array, " d"]
    num_particles: int = eqx.field(static=True)
    resampler: str = eqx.field(static=True, default="systematic")
    estimator: str = eqx.field(static=True, default="mean")

    def __check_init__(self):
        check_particles(self.num_particles)
        get_resampler(self.resampler)
        _check_estimator(self.estimator)

    def init(self, key, initial_pose) -> FilterState:
        del key  # deterministic: N copies of the initial pose
        return duplicate(initial_pose.astype(self.scales.dtype), self.num_particles)

    def step(self, key, state: FilterState, observation) -> tuple[FilterState, StepInfo]:
        resample_key, move_key = jax.random.split(key)
        ancestors = get_resampler(self.resampler)(jax.random.fold_in(resample_key, 0), state.log_weights)
        particles = diffuse(jax.random.fold_in(move_key, 0), state.particles[ancestors], self.scales)
        log_lik = self.likelihood(particles, observation)
        log_weights, degenerate = normalise_log_weights(log_lik)
        ess = effective_sample_size(log_weights)
        info = StepInfo(
            estimate=estimate_pose(self.estimator, log_weights, particles),
            ess=ess,
            log_evidence=log_mean_exp(log_lik),
            betas=jnp.ones(1, particles.dtype),
            survival=(ess / self.num_particles)[None],
            degenerate=degenerate,
        )
        return FilterState(particles, log_weights), info


def make_sir(likelihood, scales, num_particles: int, *, resampler="systematic", estimator="mean", dtype=jnp.float32) -> SIR:
    """A ``SIR`` tracker; ``scales`` (D,) is the diffusion standard deviation per pose entry."""
    scales = jnp.asarray(check_scales("scales", scales, jnp.size(scales)), dtype)
    return SIR(likelihood=likelihood, scales=scales, num_particles=num_particles, resampler=resampler, estimator=estimator)


def annealed_layers(
    key, particles, log_weights, observation, *, likelihood, to_pose, scales, num_layers, variance_decay,
    survival_target, fixed_betas, resampler,
):
    """The annealing loop shared by APF and GPAPF (001 Alg. 1 and 3), one ``lax.scan`` over layers.

    Layer m resamples (m > 0; layer 0 resamples by the previous frame's weights), diffuses the
    state with ``scales * variance_decay^(m/2)``, evaluates ``likelihood(to_pose(state))`` and
    weights with ``exp(beta_m l)``; ``beta_m`` is chosen for ``survival_target`` unless
    ``fixed_betas`` (M,) is given.

    Returns:
        particles, log_weights (normalised), and per-layer (betas, survival, degenerate), the
        first layer's evidence ``ln mean exp(l)``.
    """
    resample_key, move_key = jax.random.split(key)
    resample = get_resampler(resampler)
    n = particles.shape[0]
    dtype = particles.dtype

    def layer(carry, m):
        particles, log_weights = carry
        ancestors = resample(jax.random.fold_in(resample_key, m), log_weights)
        particles = diffuse(jax.random.fold_in(move_key, m), particles[ancestors], scales * variance_decay ** (0.5 * m.astype(dtype)))
        log_lik = likelihood(to_pose(particles), observation)
        beta = choose_beta(log_lik, survival_target) if fixed_betas is None else fixed_betas[m]
        log_weights, degenerate = normalise_log_weights(beta * log_lik)
        survival = effective_sample_size(log_weights) / n
        return (particles, log_weights), (beta, survival, degenerate, log_mean_exp(log_lik))

    (particles, log_weights), (betas, survival, degenerate, evidence) = jax.lax.scan(
        layer, (particles, log_weights), jnp.arange(num_layers)
    )
    return particles, log_weights, betas, survival, degenerate, evidence[0]


class APF(eqx.Module):
    """Annealed particle filter in pose space (Deutscher and Reid 2005; 001 Alg. 1).

    ``num_layers`` layers of ``num_particles`` each (the paper's budget: 5 x 100); the exponent
    of each layer is chosen so that about ``survival_target`` of the particles survive
    (``fixed_betas`` overrides it), and the diffusion variance shrinks by ``variance_decay``
    per layer (Deutscher's ``P_m`` scaled by the survival rate).
    """

    likelihood: Callable
    scales: Float[Array, " d"]
    num_particles: int = eqx.field(static=True)
    num_layers: int = eqx.field(static=True, default=5)
    survival_target: float = eqx.field(static=True, default=0.5)
    variance_decay: float = eqx.field(static=True, default=0.5)
    fixed_betas: tuple | None = eqx.field(static=True, default=None)
    resampler: str = eqx.field(static=True, default="systematic")
    estimator: str = eqx.field(static=True, default="mean")

    def __check_init__(self):
        check_particles(self.num_particles)
        check_annealing(self.num_layers, self.survival_target, self.fixed_betas)
        get_resampler(self.resampler)
        _check_estimator(self.estimator)

    def init(self, key, initial_pose) -> FilterState:
        del key
        return duplicate(initial_pose.astype(self.scales.dtype), self.num_particles)

    def step(self, key, state: FilterState, observation) -> tuple[FilterState, StepInfo]:
        dtype = self.scales.dtype
        betas = None if self.fixed_betas is None else jnp.asarray(self.fixed_betas, dtype)
        particles, log_weights, betas, survival, degenerate, evidence = annealed_layers(
            key, state.particles, state.log_weights, observation, likelihood=self.likelihood, to_pose=lambda x: x,
            scales=self.scales, num_layers=self.num_layers, variance_decay=self.variance_decay,
            survival_target=self.survival_target, fixed_betas=betas, resampler=self.resampler,
        )
        info = StepInfo(
            estimate=estimate_pose(self.estimator, log_weights, particles),
            ess=effective_sample_size(log_weights),
            log_evidence=evidence,
            betas=betas,
            survival=survival,
            degenerate=jnp.any(degenerate),
        )
        return FilterState(particles, log_weights), info


def make_apf(likelihood, scales, num_particles: int, num_layers: int = 5, *, dtype=jnp.float32, **options) -> APF:
    """An ``APF`` with ``num_layers`` x ``num_particles`` likelihood evaluations per frame."""
    scales = jnp.asarray(check_scales("scales", scales, jnp.size(scales)), dtype)
    return APF(likelihood=likelihood, scales=scales, num_particles=num_particles, num_layers=num_layers, **options)
