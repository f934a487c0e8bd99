"""MRPF (000 Alg. 1): SIR with the manifold-regularised transition of 000 eqs. 27-30, drawn
exactly from eq. 28 ("mrpf") or as Alg. 1 prints it ("mrpf-alg1"). On a BC-GPLVM (000's
manifold, and "mrpf-alg1"'s default) the latent draw is eq. 27's; on a GPDM ("mrpf"'s default:
measured better on the real and the synthetic jogs, docs/trackers.md) the GPDM's predictive dynamics
from the particle's own latent point. "mrpf" fits eq. 28's scales with each left joint angle and
its right mirror sharing theirs, and raises eq. 30's factor to ``MANIFOLD_WEIGHT``; "mrpf-alg1"
fits per angle, as printed. ``make_mrpf`` builds the same filter from noise scales given
directly."""

import jax.numpy as jnp

from ..body import humaneva_skeleton, mirrored_groups
from ..dynamics import ManifoldRegularisedTransition, as_scale_vector, fit_mrpf_transition
from ..manifold import ManifoldPrior
from ._registry import TrackerRecipe
from ._sir import sir_filter


def _latent_proposal(manifold):
    return "gpdm" if manifold.latent_dynamics is not None else "back-constraint"


# A left joint angle and its right mirror share eq. 28's scales, fitted on both together: on the
# real takes it gained on six rows of eight (docs/trackers.md, "Left and right share MRPF's pull").
MIRRORED_ANGLES = mirrored_groups(humaneva_skeleton().dof_names[3:])


def _mirrored(manifold):
    """The HumanEva skeleton's mirrored angles, or None for a manifold of another skeleton's."""
    angles = manifold.pose_dim - manifold.global_dims
    return MIRRORED_ANGLES if angles == len(MIRRORED_ANGLES) else None


# Eq. 30's factor to the power 4 (its scales halved), chosen among 1, 2, 4 and 8 on the four
# real-motion protocols' validation takes, never their test takes, by the one-standard-error rule
# (docs/trackers.md, "Weighting MRPF's manifold").
MANIFOLD_WEIGHT = 4.0


def fit_product(key, motion):
    return fit_mrpf_transition(motion.manifold, list(motion.validation), key=key, proposal="product",
                               latent_proposal=_latent_proposal(motion.manifold), tied=_mirrored(motion.manifold),
                               manifold_weight=MANIFOLD_WEIGHT)


def fit_printed(key, motion):
    return fit_mrpf_transition(motion.manifold, list(motion.validation), key=key, proposal="prior",
                               latent_proposal=_latent_proposal(motion.manifold))


def build(dynamics, likelihood, budget):
    return sir_filter(dynamics, likelihood, budget.particles)


def make_mrpf(likelihood, prior: ManifoldPrior, s_xx, s_xz, s_zx, num_particles: int, *, proposal="product",
              resampler="systematic", estimator="mean", dtype=jnp.float32):
    """MRPF with noise scales of 000 eqs. 27, 29, 30 given directly (``fit_mrpf_transition``
    fits them); ``proposal="prior"`` is 000 Alg. 1 as printed, ``"product"`` (default) samples
    eq. 28 exactly."""
    dynamics = ManifoldRegularisedTransition(
        manifold=prior.astype(dtype),
        s_xx=jnp.asarray(as_scale_vector("s_xx", s_xx, prior.pose_dim, dtype), dtype),
        s_xz=jnp.asarray(as_scale_vector("s_xz", s_xz, prior.latent_dim, dtype), dtype),
        s_zx=jnp.asarray(as_scale_vector("s_zx", s_zx, prior.pose_dim - prior.global_dims, dtype), dtype),
        proposal=proposal,
    )
    return sir_filter(dynamics, likelihood, num_particles, resampler=resampler, estimator=estimator)


# 000 sec. 6.1: a 2-D latent space. (In 3-D, on real motion rendered with another body, one CMU jog
# run of five was lost, 207 mm; docs/trackers.md, "Where the manifold trackers start".)
LATENT_DIM = 2

RECIPE = TrackerRecipe("mrpf", "MRPF", "manifold regularised particle filter, eq. 28 sampled exactly (000)", fit_product, build,
                       needs_manifold=True, manifold="gpdm", velocity=True, latent_dim=LATENT_DIM)
PRINTED = TrackerRecipe("mrpf-alg1", "MRPF (Alg. 1)", "MRPF as 000 Alg. 1 prints it: eq. 29 proposal, eq. 30 weight",
                        fit_printed, build, needs_manifold=True)
