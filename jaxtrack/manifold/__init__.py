"""Pose manifolds: PCA, GPLVM, back-constrained GPLVM and GPDM (../shared/METHODS.md section 3)."""

from ._fit import FitInfo as FitInfo
from ._fit import fit_model as fit_model
from ._kernels import LinearRBFKernel as LinearRBFKernel
from ._kernels import RBFBiasKernel as RBFBiasKernel
from ._kernels import gaussian_log_marginal as gaussian_log_marginal
from ._kernels import rbf_bias_kernel as rbf_bias_kernel
from ._kernels import safe_cholesky as safe_cholesky
from ._models import BCGPLVM as BCGPLVM
from ._models import GPDM as GPDM
from ._models import GPLVM as GPLVM
from ._models import KernelBackConstraint as KernelBackConstraint
from ._models import PCAModel as PCAModel
from ._models import fit_pca as fit_pca
from ._models import make_bc_gplvm as make_bc_gplvm
from ._models import make_gpdm as make_gpdm
from ._models import make_gplvm as make_gplvm
from ._models import pca as pca
from ._models import predict as predict
from ._inverse import encode as encode
from ._plot import plot_latent as plot_latent
from ._serialise import ModelFileError as ModelFileError
from ._serialise import load_model as load_model
from ._serialise import read_header as read_header
from ._serialise import save_model as save_model
