"""GLE-GbPF (002 Alg. 1): a particle filter whose propagation is the graph walk over a
Generalised Laplacian Eigenmap fitted on the training motion (its own manifold, not the GP
experiment manifold), resampling by weight every frame, estimate the weighted mean pose. Like
the other one-layer manifold trackers it carries a Kalman-tracked root velocity by default
(its root otherwise takes a zero-mean walk and is left behind on a jog: 97 against 26 mm on
the demo's S2 jog)."""

from ..body import joint_angles
from ..dynamics import fit_gle_graph_walk
from ..filters import SIR
from ..manifold import fit_gle
from ._registry import TrackerRecipe


def fit(key, motion):
    del key
    return fit_gle_graph_walk(fit_gle([joint_angles(s) for s in motion.training]), motion.validation)


def build(dynamics, likelihood, budget):
    return SIR(dynamics, likelihood, budget.particles)


RECIPE = TrackerRecipe("glegbpf", "GLE-GbPF", "graph-based particle filter on a Generalised Laplacian Eigenmap (002 Alg. 1)",
                       fit, build, velocity=True)
