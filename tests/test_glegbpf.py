"""Paper 002's Laplacian-Eigenmap manifolds (LE, temporal LE, GLE) behind the manifold interface,
and the graph-based particle filter (GLE-GbPF)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.dynamics import GLEGraphWalk
from jaxtrack.errors import ConfigurationError
from jaxtrack.manifold import SpectralEmbedding, fit_gle, fit_rbf_network, fit_spectral


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


@pytest.mark.slow  # 9 s or more on 2 cores with an empty compilation cache (docs/testing.md, 2026-11-27)
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
    reconstruction = np.asarray(model.decode(model.latent)[0])
    assert np.sqrt(np.mean((reconstruction - Y) ** 2)) < 0.05 * Y.std()
    assert np.sqrt(np.mean((np.asarray(model.encode(jnp.asarray(Y))) - np.asarray(model.latent)) ** 2)) < 0.2


def _toy_model(alpha=0.5, bandwidth=0.6):
    """Five training frames on a line, with hand-made temporal and stylistic neighbours."""
    latent = np.array([[0.0], [1.0], [2.0], [3.0], [4.0]])
    network = fit_rbf_network(np.linspace(0, 4, 40)[:, None], np.linspace(0, 4, 40)[:, None], 4)
    return SpectralEmbedding(
        data=jnp.asarray(latent), mean=jnp.zeros(1), scale=jnp.ones(1), latent=jnp.asarray(latent),
        next_frame=jnp.asarray([1, 2, 3, 4, 4]), style=jnp.asarray([[-1, 3], [4, -1], [-1, 0], [1, -1], [-1, -1]]),
        edges=jnp.asarray([[0, 1], [1, 2], [2, 3], [3, 4]]), edge_weights=jnp.ones(4), forward=network, inverse=network,
        residual=jnp.asarray(0.0), bandwidth=jnp.asarray(bandwidth), alpha=jnp.asarray(alpha),
    )


def test_the_walk_starts_at_the_nearest_training_frame_and_keeps_the_global_entries():
    walk = GLEGraphWalk(model=_toy_model(), s_global=jnp.full(6, 0.01))
    pose = jnp.asarray([0.1, 0.2, 0.9, 0.0, 0.1, 0.0, 2.8])
    states = walk.init(jax.random.key(0), pose, 4)
    np.testing.assert_array_equal(np.asarray(states), np.tile([0.1, 0.2, 0.9, 0.0, 0.1, 0.0, 3.0], (4, 1)))
    np.testing.assert_allclose(walk.to_pose(states)[:, :6], states[:, :6])


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


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
@pytest.mark.parametrize("graph", ["le", "tle", "gle"])
def test_spectral_manifolds_fit_save_load_and_serve_the_trackers(graph, tmp_path):
    """LE, temporal LE and GLE behind the manifold interface: the objective is minus the sum of
    the graph's n smallest non-zero generalised eigenvalues (the embedding's Rayleigh quotients),
    ``fit`` is the identity, a saved file loads back equal, and the ``ManifoldPrior`` decodes and
    encodes as the model does."""
    from scipy.linalg import eigh

    from jaxtrack.manifold import ManifoldPrior, load_model, make_manifold_prior, plot_latent, save_model

    sequences = _loops() if graph != "tle" else _loops()[:1]  # TLE's graph of two sequences is in two pieces
    model = fit_spectral(sequences, graph, latent_dim=2, components=12)
    assert model.graph == graph and model.latent_dim == 2 and model.data_dim == 10
    frames = sum(len(s) for s in sequences)
    W = np.zeros((frames, frames))
    edges = np.asarray(model.edges)
    W[edges[:, 0], edges[:, 1]] = W[edges[:, 1], edges[:, 0]] = np.asarray(model.edge_weights)
    values = eigh(np.diag(W.sum(1)) - W, np.diag(W.sum(1)), eigvals_only=True)
    assert float(model.objective()) == pytest.approx(-values[1:3].sum(), rel=1e-8)
    assert (graph == "gle") == (model.style.shape[1] > 0) and (graph == "gle") == (float(model.alpha) > 0)
    fitted, info = model.fit(max_steps=10)
    assert fitted is model and info.steps == 0 and info.objective == pytest.approx(float(model.objective()))

    path = tmp_path / f"{graph}.eqx"
    save_model(path, model, extra={"sequences": ["a", "b"]})
    loaded, header = load_model(path, expected_class="SpectralEmbedding")
    assert header["graph"] == graph and loaded.graph == graph and loaded.repetitions == model.repetitions
    for a, b in zip(jax.tree.leaves(model), jax.tree.leaves(loaded)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))

    prior = make_manifold_prior(loaded, 16)
    assert isinstance(prior, ManifoldPrior) and prior.has_back_constraint and prior.pose_dim == 16
    z = model.latent[:5]
    mean, variance = prior.decode(z)
    np.testing.assert_allclose(mean, model.decode(z)[0], rtol=1e-12)
    assert np.all(np.asarray(variance) >= 0) and np.all(np.asarray(variance) <= 1)
    far = prior.decode(jnp.full((1, 2), 50.0))[1]
    assert float(far[0]) == pytest.approx(1.0)  # no activation reaches far from the data
    poses = model.training_poses()[:5]
    np.testing.assert_allclose(prior.encode(poses), model.inverse(model.data[:5]), rtol=1e-12)
    assert plot_latent(loaded, str(tmp_path / "latent.png")).endswith("latent.png")


def test_spectral_manifolds_refuse_bad_training_data():
    sequences = _loops()
    with pytest.raises(ConfigurationError, match="connected components"):
        fit_spectral(sequences, "tle")  # two sequences, no edge between them: the components are named
    with pytest.raises(ConfigurationError, match="a 10-nearest-neighbour graph needs at least 11 frames, got 8"):
        fit_spectral([sequences[0][:8]], "le", k=10)
    with pytest.raises(ConfigurationError, match="fewer than the DTW window of 2t \\+ 1 = 5"):
        fit_spectral([sequences[0], sequences[1][:4]], "gle", t=2)
    with pytest.raises(ConfigurationError, match="graph must be one of"):
        fit_spectral(sequences, "isomap")
    with pytest.raises(ConfigurationError, match="finite"):
        fit_spectral([np.full((30, 10), np.nan)], "le")


@pytest.mark.slow
def test_fit_cli_writes_a_gle_model_that_glegbpf_tracks_with(tmp_path):
    """``jaxtrack fit --model gle`` on two subjects' files, ``plot-latent`` on it, and
    ``jaxtrack track --method glegbpf`` with it."""
    from jaxtrack.cli import main
    from jaxtrack.data import generate_motion
    from jaxtrack.io import Sequence, save_sequence

    from helpers import small_scene

    files = []
    for subject, seed in (("S1", 0), ("S2", 1)):
        motion = generate_motion("walk", subject, num_frames=80, fps=30.0, key=jax.random.key(seed), dtype=jnp.float64)
        files.append(tmp_path / f"{subject}.npz")
        save_sequence(files[-1], Sequence.create(fps=30.0, pose=motion.pose, pose_layout=np.array(motion.body.skeleton.pose_layout)))
    out = tmp_path / "gle.eqx"
    assert main(["fit", *map(str, files), "--model", "gle", "--out", str(out)]) == 0
    from jaxtrack.manifold import load_model

    model, header = load_model(out)
    assert type(model).__name__ == "SpectralEmbedding" and model.latent_dim == 3 and header["extra"]["sequences"] == ["S1.npz", "S2.npz"]
    assert len(model.repetitions) >= 4  # two cycles or more of each walk
    assert main(["plot-latent", str(out)]) == 0
    test = tmp_path / "test.npz"
    save_sequence(test, small_scene()[2])
    estimates = tmp_path / "estimates.npz"
    assert main(["track", str(test), "--model", str(out), "--method", "glegbpf", "--validation", str(files[0]),
                 "--budget", "40", "--out", str(estimates)]) == 0
    assert main(["track", str(test), "--model", str(out), "--method", "gpapf", "--validation", str(files[0]),
                 "--budget", "40", "--out", str(estimates)]) == 2  # GPAPF needs a GPDM's latent dynamics


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
