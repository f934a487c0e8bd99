"""GLE-GbPF (002 Alg. 1): a particle filter whose propagation is the graph walk over a
Generalised Laplacian Eigenmap fitted on the training motion (``SpectralEmbedding``; the
experiment fits it as the "gle" manifold, or "tle" / "le" for the ablations), resampling by
weight every frame, estimate the weighted mean pose. Like the other one-layer manifold trackers
it carries a Kalman-tracked root velocity by default (its root otherwise takes a zero-mean walk
and is left behind on a jog: 97 against 26 mm on the demo's S2 jog)."""

from ..dynamics import fit_gle_graph_walk
from ..filters import SIR
from ..manifold import SpectralEmbedding
from ._registry import FADING_START, TrackerRecipe


def fit(key, motion):
    del key
    if not isinstance(motion.model, SpectralEmbedding):
        raise ValueError(f"GLE-GbPF walks a Laplacian-Eigenmap embedding ('jaxtrack fit --model gle'), got "
                         f"{type(motion.model).__name__}")
    return fit_gle_graph_walk(motion.model, motion.validation)


def build(dynamics, likelihood, budget):
    return SIR(dynamics, likelihood, budget.particles)


RECIPE = TrackerRecipe("glegbpf", "GLE-GbPF", "graph-based particle filter on a Generalised Laplacian Eigenmap (002 Alg. 1)",
                       fit, build, needs_manifold=True, manifold="gle", velocity=True,
                       residual=FADING_START[0], residual_decay=FADING_START[1])
