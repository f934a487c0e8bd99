"""Picture of 004's motion prototypes: the training latent points coloured by prototype, each
prototype's position covariance as a 2-sd ellipse with its mean velocity as an arrow, and the
VLMM's first-order transitions between prototypes (the automaton's prediction after one label)."""

from __future__ import annotations

import numpy as np


def plot_prototypes(dynamics, augmented, labels, path: str, *, min_probability: float = 0.05, dpi: int = 110) -> str:
    """Write a PNG of the first two latent dimensions.

    Args:
        dynamics: a fitted ``VLMMDynamics``.
        augmented: (N, 2q) the training points ``[x, x_dot]`` (``VLMMFit.augmented``).
        labels: the prototype of each training point (N,) (``VLMMFit.labels`` concatenated).
        min_probability: the smallest switch probability drawn as a transition.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Ellipse

    q = dynamics.manifold.latent_dim
    if q < 2:
        raise ValueError("plot_prototypes needs a latent space of at least 2 dimensions")
    augmented, labels = np.asarray(augmented), np.asarray(labels)
    means = np.asarray(dynamics.prototypes.means, np.float64)
    covs = np.asarray(dynamics.prototypes.covariances, np.float64)
    M = len(means)
    colours = plt.get_cmap("tab20")(np.arange(M) % 20)
    fig, ax = plt.subplots(figsize=(6.0, 5.0))
    ax.scatter(augmented[:, 0], augmented[:, 1], c=colours[labels], s=6, alpha=0.6, lw=0)
    for m in range(M):
        values, vectors = np.linalg.eigh(covs[m, :2, :2])
        angle = np.degrees(np.arctan2(vectors[1, -1], vectors[0, -1]))
        width, height = 4.0 * np.sqrt(np.maximum(values[::-1], 0.0))
        ax.add_patch(Ellipse(means[m, :2], width, height, angle=angle, fill=False, color=colours[m], lw=1.2))
        ax.annotate("", means[m, :2] + 3 * means[m, q:q + 2], means[m, :2], arrowprops={"arrowstyle": "->", "color": colours[m]})
        ax.text(*means[m, :2], str(m), fontsize=7, ha="center", va="center")
    vlmm = dynamics.vlmm
    transition, output = np.asarray(vlmm.transition), np.asarray(vlmm.output)
    for m in range(M):
        after = output[transition[0, m]]  # the prediction after one label m
        for n in range(M):
            if n != m and after[n] >= min_probability:
                ax.annotate("", means[n, :2], means[m, :2], arrowprops={
                    "arrowstyle": "-|>", "color": "0.3", "lw": 0.5 + 3 * after[n], "alpha": 0.7, "connectionstyle": "arc3,rad=0.2"})
    ax.set_xlabel("latent 1")
    ax.set_ylabel("latent 2")
    ax.set_title(f"{M} motion prototypes, VLMM of {vlmm.num_states} states (004 sec. 5)")
    ax.autoscale_view()
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path
