"""The annealed particle filter (Deutscher and Reid 2005; 001 Alg. 1) with any dynamics, and
the optional final full-pose layer of the improved GPAPF (001 Alg. 3).

Layer 0 propagates by the dynamics; layers 1..M-1 perturb the particles with the dynamics'
noise shrunk by ``variance_decay^(m/2)`` (one ``lax.scan`` over the layers), each layer all the
state's entries or, with ``partitions``, only its own (Deutscher and Reid's hierarchical
partitioned annealing: the root, then the torso, then the limbs). Each layer is one ``smc_layer`` whose exponent
``beta_m`` is chosen so that about ``survival_target`` of the particles survive
(``fixed_betas`` overrides it). With the latent random walk this is GPAPF (001 Alg. 2).
With ``coarse_likelihood`` the first ``coarse_layers`` layers score with it instead
(coarse-to-fine annealing: e.g. ``likelihood.coarsen_likelihood``, the silhouettes at half the
resolution); the later layers, the final layer and the refinement score with ``likelihood``.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..dynamics import AbstractDynamics
from ..likelihood import AbstractLikelihood
from ._annealing import check_annealing, choose_beta
from ._base import AbstractComposedFilter, FilterState, StepInfo, check_particles
from ._estimators import AbstractEstimator, WeightedMean
from ._refine import LangevinRefinement, resample_and_refine
from ._resampling import get_resampler
from ._sir import REFINE_STREAM, check_components, check_refinement
from ._smc import check_layer_shapes, layer_keys, weigh_layer
from ._weights import effective_sample_size


class APF(AbstractComposedFilter):
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
        partitions: for layers 1..M-1 in turn, the state entries each layer perturbs (M - 1
            tuples of indices; the other entries keep their values), or None: every entry in
            every layer. Layer 0, the transition, always moves the whole state.
        coarse_likelihood: the likelihood of layers 0..coarse_layers-1 (the same observation is
            passed to it), or None.
        coarse_layers: how many leading layers score with ``coarse_likelihood`` (0: none).
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
    partitions: tuple[tuple[int, ...], ...] | None = eqx.field(static=True, default=None)
    coarse_likelihood: AbstractLikelihood | None = None
    coarse_layers: int = eqx.field(static=True, default=0)
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
        check_partitions(self.partitions, self.num_layers)
        check_coarse_layers(self.coarse_likelihood, self.coarse_layers, self.num_layers)

    def init(self, key, initial_pose) -> FilterState:
        particles = self.dynamics.init(key, initial_pose, self.num_particles)
        if self.partitions is not None:
            partition_masks(self.partitions, particles.shape[1])  # an entry past the state's end is refused here
        return FilterState(particles, jnp.zeros(self.num_particles, particles.dtype))

    def _temper(self, layer):
        if self.fixed_betas is not None:
            betas = self.fixed_betas
            return lambda log_lik: jnp.asarray(betas, log_lik.dtype)[layer]
        return lambda log_lik: choose_beta(log_lik, self.survival_target)

    def _score(self, m, poses, observation):
        """Layer m's log-likelihoods: the coarse likelihood's for m < coarse_layers."""
        if self.coarse_layers == 0:
            return self.likelihood(poses, observation)
        return jax.lax.cond(m < self.coarse_layers, lambda: self.coarse_likelihood(poses, observation),
                            lambda: self.likelihood(poses, observation))

    def step(self, key, state: FilterState, observation) -> tuple[FilterState, StepInfo]:
        anneal_key, final_key = jax.random.split(key) if self.final_layer is not None else (key, None)
        resample = get_resampler(self.resampler)
        dynamics, final = self.dynamics, self.final_layer
        m_last = self.num_layers  # the final layer's index, after layers 0..M-1

        def anneal_move(k, x, m):
            # Layer 0 is the transition, later layers perturb (one layer body, chosen by lax.cond).
            factor = self.variance_decay ** (0.5 * m.astype(x.dtype))

            def perturb():
                moved = dynamics.perturb(k, x, factor)
                if self.partitions is not None:
                    moved = jnp.where(partition_masks(self.partitions, x.shape[1])[m], moved, x)
                return moved, jnp.zeros(x.shape[0], x.dtype)

            return jax.lax.cond(m == 0, lambda: dynamics.propose(k, x), perturb)

        def layer(carry, xs):
            """One SMC layer (as ``smc_layer``): an annealing layer (m < M) or the final full-pose
            layer (m = M, 001 Alg. 3), which moves the poses of the annealed particles and weights
            them for the estimate while the annealed particles carry on unchanged. Both score
            their poses at this one call of the likelihood, so XLA compiles it once."""
            particles, log_weights, previous = carry
            m, (resample_key, move_key) = xs
            is_final = m == m_last
            ancestors = resample(resample_key, log_weights)
            chosen = particles[ancestors]
            if final is None:
                moved, correction = anneal_move(move_key, chosen, m)
                final_states, poses = None, dynamics.to_pose(moved)
            else:
                def final_move():
                    pose_states, correction = final.propose(move_key, dynamics.to_pose(chosen))
                    return chosen, pose_states, final.to_pose(pose_states), correction

                def annealing_move():
                    states, correction = anneal_move(move_key, chosen, m)
                    poses = dynamics.to_pose(states)
                    return states, poses, poses, correction

                moved, final_states, poses, correction = jax.lax.cond(is_final, final_move, annealing_move)
            log_lik = self._score(m, poses, observation)
            check_layer_shapes(particles, moved, correction, log_lik)
            if final is None:
                temper = self._temper(m)
            else:
                def temper(log_lik):
                    annealing_beta = self._temper(jnp.minimum(m, m_last - 1))(log_lik)
                    return jnp.where(is_final, choose_beta(log_lik, self.survival_target), annealing_beta)
            new_log_weights, info = weigh_layer(log_lik, correction, ancestors, temper)
            keep = lambda old, new: jnp.where(is_final, old, new)  # noqa: E731
            carry = (keep(particles, moved), keep(log_weights, new_log_weights), keep(previous, previous[ancestors]))
            return carry, (info, final_states, new_log_weights)

        annealing = jnp.arange(self.num_layers)
        anneal_keys = jax.vmap(lambda m: jnp.stack(layer_keys(anneal_key, m)))(annealing)
        final_keys = None if final is None else jnp.stack(jax.random.split(final_key))[None]
        with_final = final is not None and self.refine is None
        layer_index = jnp.arange(self.num_layers + 1) if with_final else annealing
        keys = jnp.concatenate([anneal_keys, final_keys]) if with_final else anneal_keys
        carry = (state.particles, state.log_weights, state.particles)
        carry, (layers, final_states, final_weights) = jax.lax.scan(layer, carry, (layer_index, keys))
        particles, log_weights, previous = carry
        refine_info = None
        if self.refine is not None:
            particles, log_weights, refine_info = resample_and_refine(
                self.refine, jax.random.fold_in(key, REFINE_STREAM), particles, previous, log_weights, dynamics=dynamics,
                log_likelihood=lambda states: self.likelihood(dynamics.to_pose(states), observation), resample=resample,
            )
            if final is not None:  # after the refinement: a layer of its own (the likelihood compiled once more)
                _, (last, last_states, last_weights) = layer((particles, log_weights, previous), (jnp.asarray(m_last), final_keys[0]))
                layers = jax.tree.map(lambda a, b: jnp.concatenate([a, b[None]]), layers, last)
                final_states = jnp.concatenate([final_states, last_states[None]])
                final_weights = jnp.concatenate([final_weights, last_weights[None]])
        if final is None:
            estimate = self.estimator(log_weights, particles, dynamics)
        else:
            estimate = WeightedMean()(final_weights[-1], final_states[-1], final)
        annealed = jax.tree.map(lambda x: x[: self.num_layers], layers)
        info = StepInfo(
            estimate=estimate, ess=effective_sample_size(log_weights), log_evidence=annealed.log_evidence[0], betas=annealed.beta,
            survival=annealed.ess / self.num_particles, degenerate=jnp.any(layers.degenerate), refine=refine_info,
        )
        return FilterState(particles, log_weights), info



def check_partitions(partitions, num_layers: int) -> None:
    """Validate APF's ``partitions`` (one non-empty tuple of distinct non-negative state indices
    per layer after the first); raises ``ValueError``."""
    if partitions is None:
        return
    if len(partitions) != num_layers - 1:
        raise ValueError(f"partitions has {len(partitions)} entries for the {num_layers - 1} layers after the first")
    for layer, entries in enumerate(partitions, start=1):
        if not entries or len(set(entries)) != len(entries) or any(not isinstance(i, int) or i < 0 for i in entries):
            raise ValueError(f"partitions[{layer - 1}] (layer {layer}) must be distinct non-negative state indices, got {entries!r}")


def check_coarse_layers(coarse_likelihood, coarse_layers, num_layers: int) -> None:
    """Validate APF's coarse-to-fine settings; raises ``ValueError`` or ``TypeError``."""
    if isinstance(coarse_layers, bool) or not isinstance(coarse_layers, int) or not 0 <= coarse_layers <= num_layers:
        raise ValueError(f"coarse_layers must be an integer in [0, {num_layers}] (the annealing layers), got {coarse_layers!r}")
    if coarse_layers > 0 and coarse_likelihood is None:
        raise ValueError(f"coarse_layers={coarse_layers} needs a coarse_likelihood")
    if coarse_likelihood is not None and not isinstance(coarse_likelihood, AbstractLikelihood):
        raise TypeError(f"coarse_likelihood must be an AbstractLikelihood or None, got {type(coarse_likelihood).__name__}")


def partition_masks(partitions, state_dim: int):
    """(M, S) boolean masks of the entries each layer moves (row 0, the transition: all)."""
    largest = max(max(entries) for entries in partitions)
    if largest >= state_dim:
        raise ValueError(f"partitions name state entry {largest}, but the state has {state_dim} entries")
    masks = np.zeros((len(partitions) + 1, state_dim), bool)
    masks[0] = True
    for layer, entries in enumerate(partitions, start=1):
        masks[layer, list(entries)] = True
    return jnp.asarray(masks)
