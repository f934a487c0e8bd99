"""LatentPF (003 Alg. 2): Condensation over (global entries, latent point), estimate mu(E[omega]); the
latent random walk of its paper on a manifold without dynamics, or on a GPDM (the default) the
GPDM's predictive dynamics. ``make_latent_pf`` builds the same filter on a latent random walk
with scales given directly."""

import jax.numpy as jnp

from ..dynamics import LatentRandomWalk, as_scale_vector, fit_latent_dynamics
from ..filters import SIR, make_estimator
from ..manifold import ManifoldPrior
from ._registry import FADING_START, TrackerRecipe
from ._sir import sir_filter


def fit(key, motion):
    del key
    return fit_latent_dynamics(motion.manifold, list(motion.validation), motion.training_starts)


def latent_random_walk(prior: ManifoldPrior, s_global, s_latent, dtype) -> LatentRandomWalk:
    """A ``LatentRandomWalk`` from scalars or vectors, in ``dtype``."""
    return LatentRandomWalk(
        manifold=prior.astype(dtype), s_global=jnp.asarray(as_scale_vector("s_global", s_global, prior.global_dims), dtype),
        s_latent=jnp.asarray(as_scale_vector("s_latent", s_latent, prior.latent_dim), dtype),
    )


def latent_pf_filter(dynamics, likelihood, num_particles: int, *, resampler="systematic", estimator="latent_mean") -> SIR:
    """LatentPF (003 Alg. 2): Condensation over (global entries, latent point) by the latent
    ``dynamics``, weights from the likelihood of ``mu(x)``, estimate ``mu(E[x])``."""
    manifold = dynamics.manifold if estimator == "data_mean" else None  # only the projection needs it
    return sir_filter(dynamics, likelihood, num_particles, resampler=resampler, estimator=make_estimator(estimator, manifold))


def make_latent_pf(likelihood, prior: ManifoldPrior, s_global, nu, num_particles: int, *, resampler="systematic",
                   estimator="latent_mean", dtype=jnp.float32) -> SIR:
    """LatentPF on the latent random walk ``x_{t+1} = x_t + N(0, nu^2)`` of 003 Alg. 2 (and
    ``s_global`` on the global entries)."""
    return latent_pf_filter(latent_random_walk(prior, s_global, nu, dtype), likelihood, num_particles, resampler=resampler,
                            estimator=estimator)


def build(dynamics, likelihood, budget):
    return latent_pf_filter(dynamics, likelihood, budget.particles)


# 003 sec. 4 learns a 2-D latent space for 2-D tracking and cites a 3-D one as sufficient for
# 3-D poses, which these are.
LATENT_DIM = 3

RECIPE = TrackerRecipe("latentpf", "LatentPF", "Condensation in the latent space of the manifold (003 Alg. 2)", fit, build,
                       needs_manifold=True, manifold="gpdm", velocity=True, latent_dim=LATENT_DIM,
                       residual=FADING_START[0], residual_decay=FADING_START[1])
