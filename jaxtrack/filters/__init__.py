"""Particle filters (``AbstractFilter``) built from one SMC layer: ``SIR`` (one layer per frame)
and ``APF`` (annealed layers, optional final full-pose layer), optionally with gradient-refined
particles (``LangevinRefinement``), each with any dynamics and
likelihood; resamplers, weights, estimators and the one jitted
runner (docs/papers.md)."""

from ._annealing import choose_beta as choose_beta
from ._annealing import survival_rate as survival_rate
from ._apf import APF as APF
from ._base import AbstractComposedFilter as AbstractComposedFilter
from ._base import AbstractFilter as AbstractFilter
from ._base import FilterState as FilterState
from ._base import StepInfo as StepInfo
from ._estimators import AbstractEstimator as AbstractEstimator
from ._estimators import BestParticle as BestParticle
from ._estimators import ProjectedMean as ProjectedMean
from ._estimators import StateMean as StateMean
from ._estimators import WeightedMean as WeightedMean
from ._estimators import make_estimator as make_estimator
from ._recovering import RecoveringSIR as RecoveringSIR
from ._refine import LangevinRefinement as LangevinRefinement
from ._refine import RefineInfo as RefineInfo
from ._refine import resample_and_refine as resample_and_refine
from ._resampling import RESAMPLERS as RESAMPLERS
from ._resampling import get_resampler as get_resampler
from ._resampling import multinomial as multinomial
from ._resampling import residual as residual
from ._resampling import stratified as stratified
from ._resampling import systematic as systematic
from ._run import continue_filter as continue_filter
from ._run import particle_sharding as particle_sharding
from ._run import run_filter as run_filter
from ._sir import SIR as SIR
from ._smc import LayerInfo as LayerInfo
from ._smc import layer_keys as layer_keys
from ._smc import smc_layer as smc_layer
from ._weights import best_particle as best_particle
from ._weights import effective_sample_size as effective_sample_size
from ._weights import log_mean_exp as log_mean_exp
from ._weights import normalise_log_weights as normalise_log_weights
from ._weights import weighted_mean as weighted_mean
