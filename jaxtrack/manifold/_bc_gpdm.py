"""Back-constrained GPDM: 001's GPDM (eqs. 5-11) whose latent trajectory is a smooth function of
the poses, ``X = g(Y)`` with 000 eq. 22's kernel back-constraint, as the BC-GPLVM constrains the
GPLVM.

Why: a GPDM fitted on several takes of one periodic motion can give each take its own arc of
latent points. Nothing in 001 eq. 11 draws the arcs of two takes together where their poses
agree ("spatially similar but temporally distant data points can still be placed far apart",
004 sec. 4.2), and the dynamics GP has no transition out of a take's last point. Under
``X = g(Y)`` similar poses get similar latent points and the arcs are smooth. On CMU subject
35's three jog takes (200 fit steps), in 2-D each take's last point lies 1-4 median steps from
another take's points against 10-16 for the plain GPDM (in 3-D 3-7 against 5-7), and the largest
step along an arc is 2-4 median steps against 10-37.

What it does to tracking depends on the training set (docs/trackers.md, "A back-constrained GPDM"): on one
activity's takes it keeps every run of LatentPF (80 on the real-motion table, sd at most 4 mm,
where on the plain GPDM it loses the CMU jogger), but where walks and jogs train one manifold it
draws them together too, and LatentPF on it loses the demo's walk (77 mm). The kernel's width
moves both results, so it is a manifold kind to choose (``fit_manifold(kind="bc-gpdm")``,
``jaxtrack experiment --manifold bc-gpdm``), not a tracker's default.

Tracking encodes a pose by projection onto the mean surface (``ManifoldPrior.encode``), as for
the plain GPDM: ``g`` is a kernel regression that falls to its bias away from the training
poses, where the projection stays on the manifold. So ``back_constraint()`` is None and ``g``
shapes the fit only; it is the attribute ``back``.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._custom_types import Array, Float
from ._back_constrained import AbstractBackConstrainedModel, back_constraint_template
from ._kernels import LinearRBFKernel, RBFBiasKernel
from ._models import GPDM, KernelBackConstraint, kernel_back_constraint, make_gpdm
from ._predictor import GPPredictor
from ._serialise import register_manifold


@register_manifold
class BCGPDM(AbstractBackConstrainedModel):
    """GPDM with latent points ``g(Y)`` (module docstring).

    Attributes:
        back: the kernel back-constraint ``g`` (000 eq. 22) over the standardised training poses.
        kernel, dynamics, log_w, data, mean, scale, sequence_starts: as for ``GPDM``.
    """

    back: KernelBackConstraint
    kernel: RBFBiasKernel
    dynamics: LinearRBFKernel
    log_w: Float[Array, " d"]
    data: Float[Array, "n d"]
    mean: Float[Array, " d"]
    scale: Float[Array, " d"]
    sequence_starts: tuple[int, ...] = eqx.field(static=True)

    def unconstrained(self) -> GPDM:
        """The plain GPDM at this model's latent points ``g(Y)``: 001 eq. 11 is its objective."""
        return GPDM(latent=self.back(self.data), kernel=self.kernel, dynamics=self.dynamics, log_w=self.log_w, data=self.data,
                    mean=self.mean, scale=self.scale, sequence_starts=self.sequence_starts)

    def latent_dynamics(self) -> GPPredictor:
        return self.unconstrained().latent_dynamics()

    def trainable(self):
        spec = jax.tree.map(lambda _: False, self)
        every = lambda tree: jax.tree.map(lambda _: True, tree)  # noqa: E731
        return eqx.tree_at(lambda m: (m.back, m.kernel, m.dynamics, m.log_w), spec,
                           (self.back.trainable(), every(self.kernel), every(self.dynamics), True))

    def back_constraint(self):
        # g shapes the fit; tracking encodes by projection (module docstring).
        return None

    @classmethod
    def template(cls, header, dtype):
        gpdm = GPDM.template(header, dtype)
        return cls(back=back_constraint_template(gpdm, dtype), kernel=gpdm.kernel, dynamics=gpdm.dynamics, log_w=gpdm.log_w,
                   data=gpdm.data, mean=gpdm.mean, scale=gpdm.scale, sequence_starts=gpdm.sequence_starts)


def make_bc_gpdm(sequences, latent_dim: int = 3, *, gamma_x: float | None = None, scale: bool = True,
                 dtype=jnp.float64) -> BCGPDM:
    """A back-constrained GPDM over one or more training sequences (list of (T_i, D) arrays),
    initialised as ``make_gpdm`` (PCA latent points) with ``g``'s weights solved so that ``g(Y)``
    starts there.

    Args:
        gamma_x: inverse width of the back-constraint's kernel, in standardised pose units
            (000 eq. 22); default ``1 / (mean squared distance between training poses)``, as
            ``make_bc_gplvm``.
    """
    base = make_gpdm(sequences, latent_dim, scale=scale, dtype=dtype)
    return BCGPDM(back=kernel_back_constraint(base.data, base.latent, gamma_x), kernel=base.kernel, dynamics=base.dynamics,
                  log_w=base.log_w, data=base.data, mean=base.mean, scale=base.scale, sequence_starts=base.sequence_starts)
