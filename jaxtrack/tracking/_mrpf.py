"""MRPF (000 Alg. 1): SIR with the manifold-regularised transition of 000 eqs. 27-30, drawn
exactly from eq. 28 ("mrpf") or as Alg. 1 prints it ("mrpf-alg1")."""

from ..dynamics import fit_mrpf_transition
from ..filters import SIR
from ._registry import TrackerRecipe


def fit_product(key, motion):
    return fit_mrpf_transition(motion.manifold, list(motion.validation), key=key, proposal="product")


def fit_printed(key, motion):
    return fit_mrpf_transition(motion.manifold, list(motion.validation), key=key, proposal="prior")


def build(dynamics, likelihood, budget):
    return SIR(dynamics, likelihood, budget.particles)


RECIPE = TrackerRecipe("mrpf", "MRPF", "manifold regularised particle filter, eq. 28 sampled exactly (000)", fit_product, build,
                       needs_manifold=True, manifolds=("bc-gplvm",))
PRINTED = TrackerRecipe("mrpf-alg1", "MRPF (Alg. 1)", "MRPF as 000 Alg. 1 prints it: eq. 29 proposal, eq. 30 weight",
                        fit_printed, build, needs_manifold=True, manifolds=("bc-gplvm",))
