"""Dynamics: how particle states move between frames (``AbstractDynamics``), each with the
function that fits it to motion data: the pose random walk of SIR and APF, second-order
(constant-velocity) pose dynamics, the latent random walk of GPAPF and 003's latent
Condensation, MRPF's manifold-regularised transition (000 eqs. 27-30, both proposals), the
GPDM's latent dynamics (001 eqs. 7-9) with their noise optionally refitted on validation motion,
and three wrappers for any of them: a Kalman-tracked velocity, an off-manifold pose residual and
a per-particle gait rate;
and 004's motion prototypes (a Gaussian mixture fitted to uncertain points) ordered by a
variable-length Markov model."""

from ._autoregressive import AutoregressivePoseDynamics as AutoregressivePoseDynamics
from ._autoregressive import fit_autoregressive_dynamics as fit_autoregressive_dynamics
from ._base import AbstractDynamics as AbstractDynamics
from ._base import AbstractDynamicsWrapper as AbstractDynamicsWrapper
from ._base import AbstractRefinableDynamics as AbstractRefinableDynamics
from ._base import AbstractRestartableDynamics as AbstractRestartableDynamics
from ._base import as_scale_vector as as_scale_vector
from ._base import gaussian_step as gaussian_step
from ._base import is_refinable as is_refinable
from ._base import is_restartable as is_restartable
from ._base import restart_states as restart_states
from ._gait_rate import GaitRate as GaitRate
from ._gle_graph import GLEGraphWalk as GLEGraphWalk
from ._gle_graph import fit_gle_graph_walk as fit_gle_graph_walk
from ._gpdm_latent import GPDMLatentDynamics as GPDMLatentDynamics
from ._gpdm_latent import fit_gpdm_latent_dynamics as fit_gpdm_latent_dynamics
from ._gpdm_latent import fit_latent_dynamics as fit_latent_dynamics
from ._latent_noise import LATENT_NOISE_FITS as LATENT_NOISE_FITS
from ._latent_noise import LatentNoiseMixture as LatentNoiseMixture
from ._latent_noise import fit_latent_noise as fit_latent_noise
from ._latent_noise import fit_scale_mixture as fit_scale_mixture
from ._latent_noise import gpdm_noise as gpdm_noise
from ._latent_random_walk import LatentRandomWalk as LatentRandomWalk
from ._latent_random_walk import fit_latent_random_walk as fit_latent_random_walk
from ._mrpf import MRPF_LATENT_PROPOSALS as MRPF_LATENT_PROPOSALS
from ._mrpf import MRPF_PROPOSALS as MRPF_PROPOSALS
from ._mrpf import ManifoldRegularisedTransition as ManifoldRegularisedTransition
from ._mrpf import fit_mrpf_transition as fit_mrpf_transition
from ._mrpf import fit_transition_scales as fit_transition_scales
from ._mrpf import transition_log_likelihood as transition_log_likelihood
from ._prototypes import GaussianMixture as GaussianMixture
from ._prototypes import MixtureFit as MixtureFit
from ._prototypes import fit_uncertain_mixture as fit_uncertain_mixture
from ._prototypes import initial_mixture as initial_mixture
from ._random_walk import PoseRandomWalk as PoseRandomWalk
from ._random_walk import fit_pose_random_walk as fit_pose_random_walk
from ._random_walk import make_pose_random_walk as make_pose_random_walk
from ._residual import PoseResidual as PoseResidual
from ._residual import fit_pose_residual as fit_pose_residual
from ._velocity import REST_PROBABILITY as REST_PROBABILITY
from ._velocity import StateVelocity as StateVelocity
from ._velocity import VelocityFit as VelocityFit
from ._velocity import fit_root_velocity as fit_root_velocity
from ._velocity import fit_state_velocity as fit_state_velocity
from ._velocity import heading_to_world as heading_to_world
from ._velocity import world_to_heading as world_to_heading
from ._vlmm import VLMM as VLMM
from ._vlmm import SuffixTree as SuffixTree
from ._vlmm import compile_automaton as compile_automaton
from ._vlmm import fit_suffix_tree as fit_suffix_tree
from ._vlmm import fit_vlmm as fit_vlmm
from ._vlmm_dynamics import VLMMDynamics as VLMMDynamics
from ._vlmm_dynamics import VLMMFit as VLMMFit
from ._vlmm_dynamics import augmented_latent as augmented_latent
from ._vlmm_dynamics import fit_step_scale as fit_step_scale
from ._vlmm_dynamics import fit_vlmm_dynamics as fit_vlmm_dynamics
from ._vlmm_dynamics import latent_uncertainties as latent_uncertainties
from ._vlmm_dynamics import vlmm_from_record as vlmm_from_record
from ._vlmm_dynamics import vlmm_to_record as vlmm_to_record
from ._vlmm_plot import plot_prototypes as plot_prototypes
