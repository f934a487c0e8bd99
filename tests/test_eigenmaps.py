"""Paper 002's Laplacian Eigenmaps family: graphs, the generalised eigenproblem, and DTW."""

import jax
import numpy as np
import pytest

from jaxtrack.errors import ConfigurationError
from jaxtrack.manifold import (
    dtw_distance,
    gait_cycles,
    gait_period,
    gle_graph,
    knn_graph,
    laplacian_embedding,
    stylistic_neighbours,
    subsequence_dtw,
    temporal_graph,
)


def test_a_ring_embeds_as_a_circle_with_its_known_spectrum():
    """A ring of M frames (degree 2): L v = lambda D v has eigenvalues 1 - cos(2 pi k / M), each
    twice, with cosine and sine eigenvectors; the first two span a circle."""
    M = 40
    W = temporal_graph([M], 1)
    W[0, -1] = W[-1, 0] = 1.0
    Z, values = laplacian_embedding(W, 4)
    np.testing.assert_allclose(values, 1 - np.cos(2 * np.pi * np.array([1, 1, 2, 2]) / M), rtol=1e-10)
    radius = np.linalg.norm(Z[:, :2], axis=1)
    np.testing.assert_allclose(radius, radius.mean(), rtol=1e-10)
    np.testing.assert_allclose(Z.T @ np.diag(W.sum(1)) @ Z, np.eye(4), atol=1e-10)


def test_a_path_embeds_as_cosines():
    """A path of M frames (temporal LE, t = 1): the random-walk Laplacian's eigenvalues are
    1 - cos(pi k / (M - 1)) with eigenvectors cos(pi k j / (M - 1)) (the embedding of a time
    series is its phase)."""
    M = 25
    Z, values = laplacian_embedding(temporal_graph([M], 1), 3)
    k = np.arange(1, 4)
    np.testing.assert_allclose(values, 1 - np.cos(np.pi * k / (M - 1)), rtol=1e-10)
    for column, kk in zip(Z.T, k):
        expected = np.cos(np.pi * kk * np.arange(M) / (M - 1))
        assert abs(np.corrcoef(column, expected)[0, 1]) > 1 - 1e-10


def test_the_embedding_solves_scipys_generalised_eigenproblem():
    from scipy.linalg import eigh

    rng = np.random.default_rng(0)
    A = rng.random((60, 60)) * (rng.random((60, 60)) < 0.15)
    A = np.maximum(A, A.T)
    np.fill_diagonal(A, 0)
    Z, values = laplacian_embedding(A, 3)
    D = np.diag(A.sum(1))
    reference = eigh(D - A, D, eigvals_only=True)[1:4]
    np.testing.assert_allclose(values, reference, rtol=1e-9)
    np.testing.assert_allclose((D - A) @ Z, D @ Z * values, atol=1e-9)


def test_knn_graph_and_bad_graphs_are_refused():
    Y = np.concatenate([np.random.default_rng(1).normal(size=(12, 3)), 100 + np.random.default_rng(2).normal(size=(8, 3))])
    W = knn_graph(Y, 3)
    assert np.array_equal(W, W.T) and np.all(W.sum(1) >= 3)
    with pytest.raises(ConfigurationError, match=r"2 connected components \(sizes 12, 8\)"):
        laplacian_embedding(W, 2)
    with pytest.raises(ConfigurationError, match="at least 6 frames"):
        knn_graph(Y[:5], 5)
    with pytest.raises(ConfigurationError, match="at least 4 frames"):
        laplacian_embedding(temporal_graph([3], 1), 3)
    with pytest.raises(ConfigurationError, match="symmetric"):
        laplacian_embedding(np.triu(np.ones((5, 5)), 1), 2)
    with pytest.raises(ConfigurationError, match="at least 4 frames"):
        temporal_graph([10, 3], 3)


def _dtw_reference(a, b, open_begin=False):
    """The plain dynamic programme, cell by cell (ties: diagonal, up, left)."""
    c = np.linalg.norm(a[:, None] - b[None], axis=-1)
    m, n = c.shape
    D, S = np.full((m, n), np.inf), np.zeros((m, n), int)
    for i in range(m):
        for j in range(n):
            if i == 0:
                D[i, j] = c[i, j] if open_begin else c[i, j] + (D[i, j - 1] if j else 0.0)
                S[i, j] = j if open_begin else 0
                continue
            options = [(D[i - 1, j - 1], S[i - 1, j - 1]) if j else (np.inf, 0), (D[i - 1, j], S[i - 1, j]),
                       (D[i, j - 1], S[i, j - 1]) if j else (np.inf, 0)]
            value, start = min(options, key=lambda o: o[0])
            D[i, j], S[i, j] = c[i, j] + value, start
    return D, S


def test_dtw_equals_the_plain_dynamic_programme():
    rng = np.random.default_rng(3)
    for _ in range(4):
        a, b = rng.normal(size=(7, 3)), rng.normal(size=(13, 3))
        D, _ = _dtw_reference(a, b)
        assert float(dtw_distance(a, b)) == pytest.approx(D[-1, -1], rel=1e-12)
        D, S = _dtw_reference(a, b, open_begin=True)
        cost, start = subsequence_dtw(a, b)
        np.testing.assert_allclose(np.asarray(cost), D[-1], rtol=1e-12)
        np.testing.assert_array_equal(np.asarray(start), S[-1])
    assert float(dtw_distance(a, a)) == 0.0


def test_subsequence_dtw_finds_a_time_warped_copy():
    """A loop warped in time (t -> t^1.3, 45 frames for 30) between two stretches of clutter:
    the best window is the copy, from its first to its last frame (to a frame or two at the
    start, where the warp is slow and the first frames are nearly equal)."""
    rng = np.random.default_rng(4)
    t = np.linspace(0, 1, 30)
    query = np.stack([np.sin(2 * np.pi * t), np.cos(2 * np.pi * t)], 1)
    warped = np.linspace(0, 1, 45) ** 1.3
    series = np.concatenate([5 + 3 * rng.normal(size=(20, 2)), np.stack([np.sin(2 * np.pi * warped), np.cos(2 * np.pi * warped)], 1),
                             5 + 3 * rng.normal(size=(15, 2))])
    cost, start = subsequence_dtw(query, series)
    end = int(np.argmin(np.asarray(cost)))
    assert end == 64 and 20 <= int(start[end]) <= 23, (int(start[end]), end)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_stylistic_neighbours_align_two_repetitions_by_phase():
    """Two repetitions of one loop at different speeds (60 and 90 frames) and a phase offset:
    every frame's neighbour in the other repetition has its phase (to one frame's spacing)."""
    jax.config.update("jax_enable_x64", True)

    def loop(n, phase):
        a = np.linspace(0, 2 * np.pi, n, endpoint=False) + phase
        return a, np.stack([np.cos(a), np.sin(a), 0.1 * np.cos(2 * a)], 1)

    (a0, y0), (a1, y1) = loop(60, 0.0), loop(90, 0.5)
    neighbours = stylistic_neighbours(np.concatenate([y0, y1]), [60, 90], 3)
    assert np.all(neighbours[:60, 0] == -1) and np.all(neighbours[60:, 1] == -1)
    gap = np.angle(np.exp(1j * (a0 - a1[neighbours[:60, 1] - 60])))
    assert np.abs(gap).max() <= 2 * np.pi / 90
    gap = np.angle(np.exp(1j * (a1 - a0[neighbours[60:, 0]])))
    assert np.abs(gap).max() <= 2 * np.pi / 60
    W = gle_graph(np.concatenate([y0, y1]), [60, 90], 2, alpha=0.5)
    assert set(np.unique(W)) <= {0.0, 0.5, 1.0, 1.5}
    Z, _ = laplacian_embedding(W, 2)  # connected through the stylistic edges
    assert Z.shape == (150, 2)
    with pytest.raises(ConfigurationError, match="repetition 1 has 5 frames, fewer than the DTW window of 2t \\+ 1 = 7"):
        stylistic_neighbours(np.concatenate([y0, y1[:5]]), [60, 5], 3)


def test_gait_cycles_split_a_cyclic_motion_at_its_period():
    """A noisy periodic trajectory of period 37 frames over 160 frames: the period is found, the
    cycles are 37 frames (the tail of 12 joins the last one), and a synthetic walk's cycles
    match its period too."""
    t = np.arange(160)
    Y = np.stack([np.sin(2 * np.pi * t / 37), np.cos(2 * np.pi * t / 37), 0.3 * np.sin(4 * np.pi * t / 37)], 1)
    Y = Y + 0.02 * np.random.default_rng(0).normal(size=Y.shape)
    assert gait_period(Y) == 37
    cycles = gait_cycles(Y)
    assert sum(cycles) == 160 and all(abs(c - 37) <= 1 for c in cycles[:-1]) and cycles[-1] == 160 - sum(cycles[:-1])
    with pytest.raises(ConfigurationError, match="needs two cycles"):
        gait_period(Y[:10])
    # A random walk has no period: no autocorrelation peak reaches half its lag-0 value.
    wander = np.cumsum(np.random.default_rng(5).normal(size=(160, 3)), axis=0)
    with pytest.raises(ConfigurationError, match="no clear period"):
        gait_cycles(wander)
