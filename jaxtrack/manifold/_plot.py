"""Picture of a latent space: training points coloured by sequence over the predictive
variance (as paper 001 Fig. 4a)."""

from __future__ import annotations

import itertools
import os

import jax.numpy as jnp
import numpy as np


def plot_latent(model, path: str, *, sequence_starts=None, labels=None, resolution: int = 80, dpi: int = 110) -> str:
    """Write a PNG of the first two latent dimensions of a fitted model.

    Args:
        sequence_starts: first frame of each training sequence, ending with N.
        labels: optional names of the sequences for the legend.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    Z = np.asarray(model.training_latent())
    if Z.shape[1] < 2:
        raise ValueError("plot_latent needs a latent space of at least 2 dimensions")
    lo, hi = Z[:, :2].min(0), Z[:, :2].max(0)
    pad = 0.15 * (hi - lo) + 1e-6
    gx, gy = np.meshgrid(np.linspace(lo[0] - pad[0], hi[0] + pad[0], resolution), np.linspace(lo[1] - pad[1], hi[1] + pad[1], resolution))
    grid = np.zeros((resolution * resolution, Z.shape[1]))
    grid[:, 0], grid[:, 1] = gx.ravel(), gy.ravel()
    predictor = model.predictor()
    _, var = predictor(jnp.asarray(grid, model.data.dtype))
    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    image = ax.imshow(
        np.log10(np.asarray(var) + float(predictor.noise)).reshape(resolution, resolution),
        extent=(gx.min(), gx.max(), gy.min(), gy.max()), origin="lower", cmap="gray", aspect="auto",
    )
    fig.colorbar(image, ax=ax, label="log10 predictive variance")
    starts = list(sequence_starts) if sequence_starts is not None else [0, len(Z)]
    for i, (a, b) in enumerate(itertools.pairwise(starts)):
        name = labels[i] if labels is not None and i < len(labels) else f"sequence {i + 1}"
        ax.plot(Z[a:b, 0], Z[a:b, 1], ".-", ms=3, lw=0.6, label=name)
    ax.set_xlabel("latent 1")
    ax.set_ylabel("latent 2")
    ax.set_title(type(model).__name__)
    if len(starts) > 2:
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    directory = os.path.dirname(os.fspath(path))
    if directory:
        os.makedirs(directory, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path
