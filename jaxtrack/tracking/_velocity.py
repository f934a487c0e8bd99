"""SIR and APF with second-order (constant-velocity) pose dynamics fitted on the validation
motion (003 sec. 5.2's AR(2) baseline) instead of a zero-mean random walk."""

from ..dynamics import fit_autoregressive_dynamics
from ..filters import APF, SIR
from ._registry import TrackerRecipe


def fit(key, motion):
    del key  # a deterministic fit
    return fit_autoregressive_dynamics(list(motion.validation))


def build_sir(dynamics, likelihood, budget):
    return SIR(dynamics, likelihood, budget.particles)


def build_apf(dynamics, likelihood, budget):
    return APF(dynamics, likelihood, budget.per_layer, budget.layers)


SIR_RECIPE = TrackerRecipe("sir-ar2", "SIR-AR2", "SIR with second-order (constant-velocity) pose dynamics (003 sec. 5.2)",
                           fit, build_sir)
APF_RECIPE = TrackerRecipe("apf-ar2", "APF-AR2", "APF with second-order (constant-velocity) pose dynamics", fit, build_apf,
                           annealed=True)
