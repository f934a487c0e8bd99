"""SIR / Condensation (001 eqs. 1-4): a Gaussian random walk in pose space, one layer."""

from ..dynamics import fit_pose_random_walk
from ..filters import SIR
from ._registry import TrackerRecipe


def fit(key, motion):
    del key  # a deterministic fit
    return fit_pose_random_walk(list(motion.validation))


def build(dynamics, likelihood, budget):
    return SIR(dynamics, likelihood, budget.particles)


RECIPE = TrackerRecipe("sir", "SIR", "sampling importance resampling with a pose random walk (001 eqs. 1-4)", fit, build)
