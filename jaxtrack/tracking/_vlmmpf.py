"""VLMM-PF (004 sec. 5): Condensation over the augmented latent space of a back-constrained
GPLVM, moved by motion prototypes whose order a variable-length Markov model predicts
(``dynamics.VLMMDynamics``); weights from any likelihood of the library; estimate ``mu(E[x])``
with the global entries' weighted mean. The filter is ``filters.RecoveringSIR``: with 004's
blob likelihood the evidence is fitted from the last estimate and from the prediction, the
better fit kept, and a frame whose best particle fits the evidence poorly restarts the
particles from the VLMM's initial states (004 sec. 6.1; ``likelihood.lost_threshold``)."""

from ..dynamics import fit_vlmm_dynamics, vlmm_from_record
from ..filters import RecoveringSIR, make_estimator
from ..likelihood import as_likelihood, lost_threshold
from ._registry import TrackerRecipe


def fit(key, motion):
    """The prototypes and automaton a model file of ``jaxtrack fit --model vlmm`` stored, read as
    they were fitted (the global walk's scales from the validation motion); otherwise fitted on
    the manifold's training latent points."""
    record = motion.stored.get("vlmm")
    if record is not None:
        try:
            return vlmm_from_record(record, motion.manifold, validation=list(motion.validation))
        except ValueError as err:
            raise ValueError(f"the model file's VLMM record does not fit its manifold: {err}") from err
    dynamics, _ = fit_vlmm_dynamics(motion.manifold, list(motion.validation), motion.training_starts, key=key)
    return dynamics


def build(dynamics, likelihood, budget):
    likelihood = as_likelihood(likelihood)
    return RecoveringSIR(dynamics, likelihood, budget.particles, estimator=make_estimator("latent_mean"),
                         lost_below=lost_threshold(likelihood))


# 004 sec. 7 learns a 3-D latent space (jumping jacks, 100 pseudo-points) and a 5-label memory.
LATENT_DIM = 3

RECIPE = TrackerRecipe("vlmmpf", "VLMM-PF", "motion prototypes ordered by a variable-length Markov model (004 sec. 5)", fit,
                       build, needs_manifold=True, manifold="bc-gplvm", manifolds=("bc-gplvm", "sparse-bc-gplvm"), velocity=True,
                       latent_dim=LATENT_DIM, residual=0.0)
