"""Sparse back-constrained GPLVM: the manifold paper 004 fits (004 sec. 5.1, "a sparse
back-constrained GPLVM with 100-200 pseudo-points").

The sparse GPLVM's collapsed bound (``_sparse``: Titsias 2009, or DTC) with the latent points
a smooth function of the poses, ``Z = g(Y)`` (000 eq. 22's kernel back-constraint, as the
BC-GPLVM constrains the GPLVM). Maximised over ``g``'s weights, the M inducing inputs ``U`` and
the kernel's hyperparameters; the prior ``-1/2 ||Z||_F^2`` of 000 eq. 16 stays on ``g(Y)``.

What the back-constraint gives 004: similar poses get similar latent points, and a pose maps
to its latent point in one evaluation of ``g`` (``back_constraint()``), which is how the
prototypes' uncertainties ``C_n`` are estimated (samples of the GP's prediction mapped back
through ``g``, ``dynamics.latent_uncertainties``). What the inducing points give: an objective
in O(N M^2 D) rather than O(N^3), and a predictor over M points rather than N.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._custom_types import Array, Float
from ._back_constrained import AbstractBackConstrainedModel, back_constraint_template
from ._kernels import RBFBiasKernel
from ._models import KernelBackConstraint, kernel_back_constraint
from ._serialise import register_manifold
from ._sparse import SparseGPLVM, make_sparse_gplvm


@register_manifold
class SparseBCGPLVM(AbstractBackConstrainedModel):
    """Sparse GPLVM with latent points ``g(Y)`` (module docstring).

    Attributes:
        back: the kernel back-constraint ``g`` (000 eq. 22) over the standardised training poses.
        inducing: (M, q) inducing inputs U (learned).
        kernel, data, mean, scale, approximation: as for ``SparseGPLVM``.
    """

    back: KernelBackConstraint
    inducing: Float[Array, "m q"]
    kernel: RBFBiasKernel
    data: Float[Array, "n d"]
    mean: Float[Array, " d"]
    scale: Float[Array, " d"]
    approximation: str = eqx.field(static=True, default="vfe")

    @property
    def latent_dim(self) -> int:
        # From the shapes: evaluating g(Y) for it would run the float64 map outside float64 mode.
        return int(self.back.bias.shape[0])

    def unconstrained(self) -> SparseGPLVM:
        """The plain sparse GPLVM at this model's latent points ``g(Y)``: same bound, same maps."""
        return SparseGPLVM(latent=self.back(self.data), inducing=self.inducing, kernel=self.kernel, data=self.data,
                           mean=self.mean, scale=self.scale, approximation=self.approximation)

    def trainable(self):
        spec = jax.tree.map(lambda _: False, self)
        every = lambda tree: jax.tree.map(lambda _: True, tree)  # noqa: E731
        return eqx.tree_at(lambda m: (m.back, m.inducing, m.kernel), spec, (self.back.trainable(), True, every(self.kernel)))

    def back_constraint(self):
        """``g``: standardised poses -> latent points (000 eq. 22)."""
        return self.back

    @classmethod
    def template(cls, header, dtype):
        sparse = SparseGPLVM.template(header, dtype)
        return cls(back=back_constraint_template(sparse, dtype), inducing=sparse.inducing, kernel=sparse.kernel, data=sparse.data,
                   mean=sparse.mean, scale=sparse.scale, approximation=sparse.approximation)


def make_sparse_bc_gplvm(Y, latent_dim: int = 3, *, num_inducing: int = 150, approximation: str = "vfe",
                         gamma_x: float | None = None, scale: bool = False, dtype=jnp.float64) -> SparseBCGPLVM:
    """A sparse BC-GPLVM initialised as ``make_sparse_gplvm`` (PCA latent points, inducing points
    at evenly spaced training frames), with ``g``'s weights solved so that ``g(Y)`` starts there.

    Args:
        num_inducing: M, at most the number of frames (004: 100-200).
        approximation: "vfe" (Titsias's bound) or "dtc".
        gamma_x: inverse width of the back-constraint's kernel, in standardised pose units
            (000 eq. 22); default ``1 / (mean squared distance between training poses)``, as
            ``make_bc_gplvm``.
    """
    base = make_sparse_gplvm(Y, latent_dim, num_inducing=num_inducing, approximation=approximation, scale=scale, dtype=dtype)
    return SparseBCGPLVM(back=kernel_back_constraint(base.data, base.latent, gamma_x), inducing=base.inducing, kernel=base.kernel,
                         data=base.data, mean=base.mean, scale=base.scale, approximation=base.approximation)
