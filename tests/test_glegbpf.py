"""Paper 002's GLE model and its graph-based particle filter (GLE-GbPF)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.dynamics import GLEGraphWalk
from jaxtrack.manifold import GLEModel, fit_gle, fit_rbf_network


@pytest.fixture(autouse=True)
def _float64():
    jax.config.update("jax_enable_x64", True)


def _loops():
    """Two repetitions of one 10-D loop at different speeds (three cycles each)."""
    rng = np.random.default_rng(0)
    lift = rng.normal(size=(3, 10))

    def loop(frames, period, phase):
        angle = 2 * np.pi * np.arange(frames) / period + phase
        return np.stack([np.cos(angle), np.sin(angle), 0.3 * np.cos(2 * angle)], 1) @ lift

    return [loop(120, 40, 0.0), loop(150, 50, 0.4)]


def test_fit_gle_embeds_the_training_loops_and_maps_back():
    sequences = _loops()
    model = fit_gle(sequences, latent_dim=3, components=20)
    Y = np.concatenate(sequences)
    assert model.latent.shape == (270, 3)
    # The next temporal neighbour: the following frame, and itself at each sequence's end.
    next_frame = np.asarray(model.next_frame)
    assert next_frame[0] == 1 and next_frame[119] == 119 and next_frame[120] == 121 and next_frame[269] == 269
    # Stylistic neighbours come from the other sequence's cycles (6 repetitions in all).
    style = np.asarray(model.style)
    assert style.shape == (270, 6) and np.all((style[:120, :3] == -1).sum(axis=1) == 1)
    # The forward map reproduces the training poses (under 5 % of their spread), the inverse
    # returns their latent points (under 20 % of the latent spread, which is 1; measured 12 %).
    reconstruction = np.asarray(model.decode(model.latent))
    assert np.sqrt(np.mean((reconstruction - Y) ** 2)) < 0.05 * Y.std()
    assert np.sqrt(np.mean((np.asarray(model.encode(jnp.asarray(Y))) - np.asarray(model.latent)) ** 2)) < 0.2


def _toy_model(alpha=0.5, bandwidth=0.6):
    """Five training frames on a line, with hand-made temporal and stylistic neighbours."""
    latent = np.array([[0.0], [1.0], [2.0], [3.0], [4.0]])
    network = fit_rbf_network(np.linspace(0, 4, 40)[:, None], np.linspace(0, 4, 40)[:, None], 4)
    return GLEModel(
        latent=jnp.asarray(latent), next_frame=jnp.asarray([1, 2, 3, 4, 4]),
        style=jnp.asarray([[-1, 3], [4, -1], [-1, 0], [1, -1], [-1, -1]]),
        forward=network, inverse=network, mean=jnp.zeros(1), scale=jnp.ones(1), bandwidth=jnp.asarray(bandwidth),
        alpha=jnp.asarray(alpha),
    )


def test_the_triple_resampling_draws_with_the_probabilities_it_claims():
    """From a particle at latent 1.3: attach to frame j with probability proportional to
    exp(-(1.3 - z_j)^2 / 2h^2) (002 eq. 11), step to next(j), then stay (weight 1) or move to a
    stylistic neighbour (weight alpha each). The frames drawn for 40000 particles match these
    probabilities (chi-square, 4 degrees of freedom, p > 0.001)."""
    from scipy.stats import chisquare

    model = _toy_model()
    walk = GLEGraphWalk(model=model, s_global=jnp.full(6, 0.01))
    n = 40000
    step = eqx.filter_jit(lambda w, key, latent: w.graph_step(key, latent))
    frames = np.asarray(step(walk, jax.random.key(0), jnp.full((n, 1), 1.3)))
    z = np.asarray(model.latent)[:, 0]
    attach = np.exp(-0.5 * (1.3 - z) ** 2 / 0.6**2)
    attach /= attach.sum()
    nxt, style = np.asarray(model.next_frame), np.asarray(model.style)
    expected = np.zeros(5)
    for j, p in enumerate(attach):
        k = nxt[j]
        options = [(k, 1.0)] + [(s, 0.5) for s in style[k] if s >= 0]
        total = sum(w for _, w in options)
        for frame, w in options:
            expected[frame] += p * w / total
    counts = np.bincount(frames, minlength=5)
    assert chisquare(counts, expected * n).pvalue > 1e-3, (counts, expected * n)


@pytest.mark.slow
def test_glegbpf_tracks_through_the_experiment(tmp_path):
    """Registered as ``glegbpf``: the experiment fits its GLE on the training motion and tracks."""
    from jaxtrack.experiment import ExperimentConfig, run_experiment
    from jaxtrack.tracking import available_trackers

    from helpers import small_experiment_sequences

    assert "glegbpf" in available_trackers()
    train, validation, test = small_experiment_sequences()
    results = run_experiment(train, validation, test, ExperimentConfig(methods=("glegbpf",), budget=60, runs=1, frames=4),
                             names={"test": ["walk"]}, progress=False, animations=False)
    error = results["sequences"]["walk"]["glegbpf"]["error_mm_mean"]
    assert np.isfinite(error) and error < 150, error
