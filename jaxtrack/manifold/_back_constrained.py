"""A model whose latent points are a smooth function of the poses, ``Z = g(Y)`` (000 eq. 22's
kernel back-constraint), written once over the plain model it constrains: its objective, maps
and file header are the plain model's at ``g(Y)``. ``BCGPDM`` (the GPDM under it) and
``SparseBCGPLVM`` (004's sparse GPLVM under it) are the two."""

from __future__ import annotations

import abc

import equinox as eqx
import jax.numpy as jnp

from .._custom_types import Array, Float
from ._models import KernelBackConstraint
from ._predictor import GPPredictor
from ._serialise import AbstractSaveableManifold


class AbstractBackConstrainedModel(AbstractSaveableManifold):
    """A plain model (``unconstrained``) evaluated at the latent points ``g(Y)``.

    Attributes:
        back: the kernel back-constraint ``g`` over the standardised training poses.
        data: (N, D) the standardised training poses.
    """

    back: eqx.AbstractVar[KernelBackConstraint]
    data: eqx.AbstractVar[Float[Array, "n d"]]

    @abc.abstractmethod
    def unconstrained(self) -> AbstractSaveableManifold:
        """The plain model at this model's latent points ``g(Y)``: same objective, same maps."""

    def training_latent(self):
        return self.back(self.data)

    def objective(self):
        """The plain model's objective at ``Z = g(Y)``, maximised over ``g``'s weights (and the
        plain model's other parameters)."""
        return self.unconstrained().objective()

    def predictor(self) -> GPPredictor:
        return self.unconstrained().predictor()

    def header(self) -> dict:
        return self.unconstrained().header()


def back_constraint_template(plain: AbstractSaveableManifold, dtype) -> KernelBackConstraint:
    """A zero kernel back-constraint shaped for the template ``plain`` (its latent points (N, q)
    and data (N, D)), for loading a file into."""
    (n, q), d = plain.latent.shape, plain.data.shape[1]
    return KernelBackConstraint(weights=jnp.zeros((n, q), dtype), bias=jnp.zeros(q, dtype), inputs=jnp.zeros((n, d), dtype),
                                gamma_x=jnp.zeros((), dtype))
