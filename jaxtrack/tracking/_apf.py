"""The annealed particle filter (001 Alg. 1): the pose random walk, ``layers`` layers."""

from ..dynamics import fit_pose_random_walk
from ..filters import APF
from ._registry import TrackerRecipe


def fit(key, motion):
    del key
    return fit_pose_random_walk(list(motion.validation))


def build(dynamics, likelihood, budget):
    return APF(dynamics, likelihood, budget.per_layer, budget.layers)


RECIPE = TrackerRecipe("apf", "APF", "annealed particle filter in pose space (Deutscher and Reid; 001 Alg. 1)", fit, build,
                       annealed=True)
