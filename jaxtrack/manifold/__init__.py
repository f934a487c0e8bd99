"""Pose manifolds behind one interface (``AbstractManifold``): GPLVM, back-constrained GPLVM
(kernel or MLP), sparse GPLVM, GPDM and back-constrained GPDM, a PCA baseline, and ``ManifoldPrior``, a fitted
manifold precomputed for the trackers (docs/papers.md). The Laplacian Eigenmaps
family's graphs and embedding (LE, temporal LE, GLE with its DTW kernel; paper 002), its RBF
networks, and ``SpectralEmbedding`` (``fit_spectral``: LE, temporal LE or GLE with its RBF
networks, fitted in closed form), the manifold GLE-GbPF walks on. ``ManifoldKind`` and its
registry name every kind that can be fitted (``manifold_kinds()``)."""

from ._active_set import ActiveSetGPLVM as ActiveSetGPLVM
from ._active_set import fit_active_set as fit_active_set
from ._active_set import isomap as isomap
from ._active_set import ivm_select as ivm_select
from ._active_set import make_active_set_gplvm as make_active_set_gplvm
from ._active_set import optimise_points as optimise_points
from ._active_set import point_objective as point_objective
from ._base import AbstractManifold as AbstractManifold
from ._bc_gpdm import BCGPDM as BCGPDM
from ._bc_gpdm import make_bc_gpdm as make_bc_gpdm
from ._dtw import dtw_distance as dtw_distance
from ._dtw import subsequence_dtw as subsequence_dtw
from ._eigenmaps import connected_components as connected_components
from ._eigenmaps import gait_cycles as gait_cycles
from ._eigenmaps import gait_period as gait_period
from ._eigenmaps import gle_graph as gle_graph
from ._eigenmaps import knn_graph as knn_graph
from ._eigenmaps import laplacian_embedding as laplacian_embedding
from ._eigenmaps import stylistic_graph as stylistic_graph
from ._eigenmaps import stylistic_neighbours as stylistic_neighbours
from ._eigenmaps import temporal_graph as temporal_graph
from ._fit import DEFAULT_OPTIMISER as DEFAULT_OPTIMISER
from ._fit import OPTIMISERS as OPTIMISERS
from ._fit import FitInfo as FitInfo
from ._fit import fit_model as fit_model
from ._inverse import INVERSE_METHODS as INVERSE_METHODS
from ._kernels import LinearRBFKernel as LinearRBFKernel
from ._kernels import RBFBiasKernel as RBFBiasKernel
from ._kernels import cholesky_inverse as cholesky_inverse
from ._kernels import gaussian_log_marginal as gaussian_log_marginal
from ._kernels import rbf_bias_kernel as rbf_bias_kernel
from ._kernels import safe_cholesky as safe_cholesky
from ._kinds import FAMILIES as FAMILIES
from ._kinds import ManifoldKind as ManifoldKind
from ._kinds import get_manifold_kind as get_manifold_kind
from ._kinds import manifold_kinds as manifold_kinds
from ._kinds import register_manifold_kind as register_manifold_kind
from ._kinds import unregister_manifold_kind as unregister_manifold_kind
from ._lbfgs import LBFGS_MEMORY as LBFGS_MEMORY
from ._lbfgs import lbfgs_minimise as lbfgs_minimise
from ._models import BCGPLVM as BCGPLVM
from ._models import GPDM as GPDM
from ._models import GPDM_STARTS as GPDM_STARTS
from ._models import GPLVM as GPLVM
from ._models import KernelBackConstraint as KernelBackConstraint
from ._models import MLPBackConstraint as MLPBackConstraint
from ._models import PCAModel as PCAModel
from ._models import check_training_data as check_training_data
from ._models import fit_pca as fit_pca
from ._models import make_bc_gplvm as make_bc_gplvm
from ._models import make_gpdm as make_gpdm
from ._models import make_gplvm as make_gplvm
from ._models import pca as pca
from ._models import predict as predict
from ._plot import plot_latent as plot_latent
from ._predictor import AbstractPredictor as AbstractPredictor
from ._predictor import GPPredictor as GPPredictor
from ._prior import ManifoldPrior as ManifoldPrior
from ._prior import make_manifold_prior as make_manifold_prior
from ._prior import to_prior as to_prior
from ._rbf import RBFNetwork as RBFNetwork
from ._rbf import RBFPredictor as RBFPredictor
from ._rbf import fit_gaussian_mixture as fit_gaussian_mixture
from ._rbf import fit_rbf_network as fit_rbf_network
from ._serialise import MANIFOLD_CLASSES as MANIFOLD_CLASSES
from ._serialise import AbstractSaveableManifold as AbstractSaveableManifold
from ._serialise import ModelFileError as ModelFileError
from ._serialise import load_model as load_model
from ._serialise import read_header as read_header
from ._serialise import register_manifold as register_manifold
from ._serialise import save_model as save_model
from ._sparse import SparseGPLVM as SparseGPLVM
from ._sparse import make_sparse_gplvm as make_sparse_gplvm
from ._sparse import sparse_log_marginal as sparse_log_marginal
from ._sparse_bc_gplvm import SparseBCGPLVM as SparseBCGPLVM
from ._sparse_bc_gplvm import make_sparse_bc_gplvm as make_sparse_bc_gplvm
from ._spectral import SPECTRAL_GRAPHS as SPECTRAL_GRAPHS
from ._spectral import SpectralEmbedding as SpectralEmbedding
from ._spectral import fit_gle as fit_gle
from ._spectral import fit_spectral as fit_spectral
