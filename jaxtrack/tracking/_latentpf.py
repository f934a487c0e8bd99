"""LatentPF (003 Alg. 2): Condensation over (global entries, latent point), estimate mu(E[omega]); the
latent random walk of its paper on a manifold without dynamics, or on a GPDM (the default) the
GPDM's predictive dynamics."""

from ..dynamics import fit_latent_dynamics
from ..filters import SIR, StateMean
from ._registry import TrackerRecipe


def fit(key, motion):
    del key
    return fit_latent_dynamics(motion.manifold, list(motion.validation), motion.training_starts)


def build(dynamics, likelihood, budget):
    return SIR(dynamics, likelihood, budget.particles, estimator=StateMean())


# 003 sec. 4 learns a 2-D latent space for 2-D tracking and cites a 3-D one as sufficient for
# 3-D poses, which these are.
LATENT_DIM = 3

RECIPE = TrackerRecipe("latentpf", "LatentPF", "Condensation in the latent space of the manifold (003 Alg. 2)", fit, build,
                       needs_manifold=True, manifold="gpdm", velocity=True, latent_dim=LATENT_DIM, residual=0.0)
