"""Particle filters: SIR, APF, MRPF, GPAPF and LatentPF, with resamplers, estimators and one
jitted runner (../shared/METHODS.md section 2)."""

from ._annealing import choose_beta as choose_beta
from ._core import FilterState as FilterState
from ._core import StepInfo as StepInfo
from ._core import run_filter as run_filter
from ._manifold_filters import GPAPF as GPAPF
from ._manifold_filters import MRPF as MRPF
from ._manifold_filters import MRPF_PROPOSALS as MRPF_PROPOSALS
from ._manifold_filters import make_gpapf as make_gpapf
from ._manifold_filters import make_latent_pf as make_latent_pf
from ._manifold_filters import make_mrpf as make_mrpf
from ._manifold_prior import ManifoldPrior as ManifoldPrior
from ._manifold_prior import make_manifold_prior as make_manifold_prior
from ._noise import NoiseScales as NoiseScales
from ._noise import fit_noise_scales as fit_noise_scales
from ._pose_filters import APF as APF
from ._pose_filters import SIR as SIR
from ._pose_filters import make_apf as make_apf
from ._pose_filters import make_sir as make_sir
from ._resampling import RESAMPLERS as RESAMPLERS
from ._resampling import get_resampler as get_resampler
from ._resampling import multinomial as multinomial
from ._resampling import residual as residual
from ._resampling import stratified as stratified
from ._resampling import systematic as systematic
from ._weights import best_particle as best_particle
from ._weights import effective_sample_size as effective_sample_size
from ._weights import log_mean_exp as log_mean_exp
from ._weights import normalise_log_weights as normalise_log_weights
from ._weights import weighted_mean as weighted_mean
