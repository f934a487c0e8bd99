"""Sampling importance resampling (Condensation; 001 eqs. 1-4) with any dynamics: one SMC layer
per frame. With the pose random walk this is SIR; with MRPF's transition it is MRPF
(000 Alg. 1); with the latent random walk it is the latent-space Condensation of 003 Alg. 2."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from ..dynamics import AbstractDynamics, is_refinable
from ..likelihood import AbstractLikelihood
from ._base import AbstractComposedFilter, FilterState, StepInfo, check_particles
from ._estimators import AbstractEstimator, WeightedMean
from ._refine import LangevinRefinement, resample_and_refine
from ._resampling import get_resampler
from ._smc import layer_keys, smc_layer

REFINE_STREAM = 104729  # fold_in tag of a frame's refinement key (without refinement, no key changes)


class AbstractOneLayerFilter(AbstractComposedFilter):
    """A filter of one SMC layer per frame (``SIR``, ``RecoveringSIR``): its parts, their checks
    and its initial state; subclasses say how a frame's step goes.

    Attributes:
        dynamics: the transition (``PoseRandomWalk``, ``ManifoldRegularisedTransition``, ...).
        likelihood: the observation likelihood.
        num_particles: N, the likelihood evaluations per frame.
        resampler: "systematic", "stratified", "multinomial" or "residual".
        estimator: how the frame's pose is estimated (default: the weighted mean).
        refine: gradient-refined moves after the weighting (``LangevinRefinement``), or None.
            Each costs ``refine.num_steps`` likelihood gradients per particle per frame.
    """

    dynamics: AbstractDynamics
    likelihood: AbstractLikelihood
    num_particles: int = eqx.field(static=True)
    resampler: str = eqx.field(static=True, default="systematic")
    estimator: AbstractEstimator = WeightedMean()
    refine: LangevinRefinement | None = None

    def __check_init__(self):
        check_particles(self.num_particles)
        get_resampler(self.resampler)
        check_components(self.dynamics, self.likelihood, self.estimator)
        check_refinement(self.refine, self.dynamics)

    def init(self, key, initial_pose) -> FilterState:
        particles = self.dynamics.init(key, initial_pose, self.num_particles)
        return FilterState(particles, jnp.zeros(self.num_particles, particles.dtype))


class SIR(AbstractOneLayerFilter):
    """Per frame: resample by the previous weights, ``s_t ~ dynamics.propose(s_{t-1})``, weight
    by ``p(I_t | pose(s_t))`` times the proposal's correction, estimate. Attributes: those of
    ``AbstractOneLayerFilter``."""

    def step(self, key, state: FilterState, observation) -> tuple[FilterState, StepInfo]:
        def log_likelihood(s):
            return self.likelihood(self.dynamics.to_pose(s), observation)

        resample = get_resampler(self.resampler)
        particles, log_weights, layer = smc_layer(
            layer_keys(key, 0), state.particles, state.log_weights, move=self.dynamics.propose, log_likelihood=log_likelihood,
            resample=resample,
        )
        return refine_and_report(self, key, state, particles, log_weights, layer, log_likelihood, resample)


def refine_and_report(filter_, key, state: FilterState, particles, log_weights, layer, log_likelihood, resample,
                      restarted=None) -> tuple[FilterState, StepInfo]:
    """The end of a one-layer step (``SIR``, ``RecoveringSIR``): the filter's gradient-refined
    moves if it has them, then the frame's estimate and ``StepInfo``."""
    refine_info = None
    if filter_.refine is not None:
        particles, log_weights, refine_info = resample_and_refine(
            filter_.refine, jax.random.fold_in(key, REFINE_STREAM), particles, state.particles[layer.ancestors], log_weights,
            dynamics=filter_.dynamics, log_likelihood=log_likelihood, resample=resample,
        )
    info = StepInfo(
        estimate=filter_.estimator(log_weights, particles, filter_.dynamics),
        ess=layer.ess,
        log_evidence=layer.log_evidence,
        betas=layer.beta[None],
        survival=(layer.ess / filter_.num_particles)[None],
        degenerate=layer.degenerate,
        refine=refine_info,
        restarted=restarted,
    )
    return FilterState(particles, log_weights), info


def check_components(dynamics, likelihood, estimator) -> None:
    """Raise ``TypeError`` unless the parts are a dynamics, a likelihood and an estimator."""
    for value, kind, name in ((dynamics, AbstractDynamics, "dynamics"), (likelihood, AbstractLikelihood, "likelihood"),
                              (estimator, AbstractEstimator, "estimator")):
        if not isinstance(value, kind):
            hint = " (wrap a plain function with jaxtrack.likelihood.as_likelihood)" if name == "likelihood" else ""
            raise TypeError(f"{name} must be an {kind.__name__}, got {type(value).__name__}{hint}")




def check_refinement(refine, dynamics) -> None:
    """Raise unless ``refine`` is None, or a ``LangevinRefinement`` and ``dynamics`` defines the
    transition density and noise scales its moves need."""
    if refine is None:
        return
    if not isinstance(refine, LangevinRefinement):
        raise TypeError(f"refine must be a LangevinRefinement or None, got {type(refine).__name__}")
    if not is_refinable(dynamics):
        raise ValueError(f"{type(dynamics).__name__} defines no transition density (it is not an AbstractRefinableDynamics, "
                         "with log_transition and noise_scales, all the way in), so its particles cannot be refined")
