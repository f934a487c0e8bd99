"""The annealed particle filter (Deutscher and Reid 2005; 001 Alg. 1) with any dynamics, and
the optional final full-pose layer of the improved GPAPF (001 Alg. 3).

Layer 0 propagates by the dynamics; layers 1..M-1 perturb the particles with the dynamics'
noise shrunk by ``variance_decay^(m/2)`` (one ``lax.scan`` over the layers). Each layer is one ``smc_layer`` whose exponent
``beta_m`` is chosen so that about ``survival_target`` of the particles survive
(``fixed_betas`` overrides it). With the latent random walk this is GPAPF (001 Alg. 2).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from ..dynamics import AbstractDynamics
from ..likelihood import AbstractLikelihood
from ._annealing import check_annealing, choose_beta
from ._base import AbstractFilter, FilterState, StepInfo, check_particles
from ._estimators import AbstractEstimator, WeightedMean
from ._refine import LangevinRefinement, resample_and_refine
from ._resampling import get_resampler
from ._sir import REFINE_STREAM, check_components, check_refinement
from ._smc import layer_keys, smc_layer
from ._weights import effective_sample_size


class APF(AbstractFilter):
    """Annealed particle filter: ``num_layers`` layers of ``num_particles`` each per frame
    (the papers' budget: 5 x 100).

    Attributes:
        dynamics: the transition of layer 0 and the perturbation of the later layers.
        likelihood: the observation likelihood.
        num_particles: N per layer.
        num_layers: M annealing layers.
        survival_target: the survival rate each layer's beta aims for (001: 0.5).
        variance_decay: the perturbation variance shrinks by this factor per layer.
        fixed_betas: (M,) exponents to use instead of choosing them.
        final_layer: a dynamics whose state is the pose (e.g. ``PoseRandomWalk``) for one more
            layer after the annealing (001 Alg. 3, GPAPF's improved variant): it moves the
            poses of the annealed particles, weights them (beta chosen for the survival target)
            and gives the estimate, their weighted mean; the annealed particles are what the
            next frame starts from.
        resampler, estimator: as for ``SIR``.
        refine: gradient-refined moves after the annealing layers and before the final layer
            (``LangevinRefinement``), targeting the untempered posterior given each particle's
            ancestor in the previous frame; or None.
    """

    dynamics: AbstractDynamics
    likelihood: AbstractLikelihood
    num_particles: int = eqx.field(static=True)
    num_layers: int = eqx.field(static=True, default=5)
    survival_target: float = eqx.field(static=True, default=0.5)
    variance_decay: float = eqx.field(static=True, default=0.5)
    fixed_betas: tuple | None = eqx.field(static=True, default=None)
    final_layer: AbstractDynamics | None = None
    resampler: str = eqx.field(static=True, default="systematic")
    estimator: AbstractEstimator = WeightedMean()
    refine: LangevinRefinement | None = None

    def __check_init__(self):
        check_particles(self.num_particles)
        check_annealing(self.num_layers, self.survival_target, self.fixed_betas)
        get_resampler(self.resampler)
        check_components(self.dynamics, self.likelihood, self.estimator)
        check_refinement(self.refine, self.dynamics)
        if self.final_layer is not None and not isinstance(self.final_layer, AbstractDynamics):
            raise TypeError(f"final_layer must be an AbstractDynamics or None, got {type(self.final_layer).__name__}")
        if not 0.0 < self.variance_decay <= 1.0:
            raise ValueError(f"variance_decay must be in (0, 1], got {self.variance_decay}")

    def init(self, key, initial_pose) -> FilterState:
        particles = self.dynamics.init(key, initial_pose, self.num_particles)
        return FilterState(particles, jnp.zeros(self.num_particles, particles.dtype))

    def _temper(self, layer):
        if self.fixed_betas is not None:
            betas = self.fixed_betas
            return lambda log_lik: jnp.asarray(betas, log_lik.dtype)[layer]
        return lambda log_lik: choose_beta(log_lik, self.survival_target)

    def step(self, key, state: FilterState, observation) -> tuple[FilterState, StepInfo]:
        anneal_key, final_key = jax.random.split(key) if self.final_layer is not None else (key, None)
        resample = get_resampler(self.resampler)
        dynamics = self.dynamics

        def log_likelihood(states):
            return self.likelihood(dynamics.to_pose(states), observation)

        def anneal(carry, m):
            particles, log_weights, previous = carry
            factor = self.variance_decay ** (0.5 * m.astype(particles.dtype))

            def move(k, x):
                # Layer 0 is the transition, later layers perturb; one layer body in one scan, so
                # the likelihood is compiled once.
                return jax.lax.cond(
                    m == 0, lambda: dynamics.propose(k, x), lambda: (dynamics.perturb(k, x, factor), jnp.zeros(x.shape[0], x.dtype))
                )

            particles, log_weights, info = smc_layer(
                layer_keys(anneal_key, m), particles, log_weights, move=move, log_likelihood=log_likelihood,
                resample=resample, temper=self._temper(m),
            )
            # Each particle's state in the previous frame, followed through the layers' resampling.
            return (particles, log_weights, previous[info.ancestors]), info

        carry = (state.particles, state.log_weights, state.particles)
        (particles, log_weights, previous), layers = jax.lax.scan(anneal, carry, jnp.arange(self.num_layers))
        refine_info = None
        if self.refine is not None:
            particles, log_weights, refine_info = resample_and_refine(
                self.refine, jax.random.fold_in(key, REFINE_STREAM), particles, previous, log_weights, dynamics=dynamics,
                log_likelihood=log_likelihood, resample=resample,
            )
        degenerate = layers.degenerate
        if self.final_layer is None:
            estimate = self.estimator(log_weights, particles, dynamics)
        else:
            final = self.final_layer
            refined, final_weights, last = smc_layer(
                tuple(jax.random.split(final_key)), dynamics.to_pose(particles), log_weights, move=final.propose,
                log_likelihood=lambda x: self.likelihood(final.to_pose(x), observation), resample=resample,
                temper=lambda log_lik: choose_beta(log_lik, self.survival_target),
            )
            estimate = WeightedMean()(final_weights, refined, final)
            degenerate = jnp.concatenate([degenerate, last.degenerate[None]])
        info = StepInfo(
            estimate=estimate, ess=effective_sample_size(log_weights), log_evidence=layers.log_evidence[0], betas=layers.beta,
            survival=layers.ess / self.num_particles, degenerate=jnp.any(degenerate), refine=refine_info,
        )
        return FilterState(particles, log_weights), info
