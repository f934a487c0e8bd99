"""The Laplacian Eigenmaps family (002 sec. 2.1; docs/papers.md): the graphs of
LE (k nearest neighbours in pose space), temporal LE (the t previous and next frames) and GLE
(temporal plus ``alpha`` times stylistic neighbours found by sliding DTW), and the embedding
that minimises ``sum_ij W_ij ||z_i - z_j||^2`` subject to ``Z^T D Z = I`` (002 eqs. 1 and 7):
the generalised eigenvectors ``L v = lambda D v`` of the n smallest non-zero eigenvalues, with
``L = D - W`` and ``D = diag(sum_j W_ij)``.

The eigenproblem is solved densely (``scipy.linalg.eigh`` on the symmetric pencil), which is
exact and fast for the few thousand frames of a motion-capture training set (4000 frames: a
few seconds); beyond that a sparse iterative solver (LOBPCG or ARPACK shift-invert on the
sparse Laplacian) would be the choice, as the graphs have O(k) entries per row.

The graphs are built with NumPy on the host (they are small, integer-indexed and built once);
the stylistic search, the expensive part, runs the jitted DTW kernel of ``_dtw`` vmapped over
the frames.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigurationError


def _check_frames(frames: int, needed: int, what: str) -> None:
    if frames < needed:
        raise ConfigurationError(f"{what} needs at least {needed} frames, got {frames}")


def knn_graph(Y, k: int) -> np.ndarray:
    """LE's graph: ``W_ij = 1`` when j is among the ``k`` nearest neighbours of i in pose space
    or i among j's (symmetrised), else 0. ``Y``: (M, D)."""
    Y = np.asarray(Y, np.float64)
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
        raise ConfigurationError(f"the neighbourhood size k must be a positive integer, got {k!r}")
    _check_frames(Y.shape[0], k + 1, f"a {k}-nearest-neighbour graph")
    distance = np.sum((Y[:, None] - Y[None]) ** 2, axis=-1)
    np.fill_diagonal(distance, np.inf)
    nearest = np.argsort(distance, axis=1, kind="stable")[:, :k]
    W = np.zeros((Y.shape[0],) * 2)
    W[np.repeat(np.arange(Y.shape[0]), k), nearest.ravel()] = 1.0
    return np.maximum(W, W.T)


def temporal_graph(lengths, t: int) -> np.ndarray:
    """Temporal LE's graph (002 eq. 2): ``W_ij = 1`` when frames i and j are of the same
    sequence and 0 < |i - j| <= t. ``lengths``: frames of each training sequence, in order."""
    lengths = [int(n) for n in lengths]
    if isinstance(t, bool) or not isinstance(t, (int, np.integer)) or t < 1:
        raise ConfigurationError(f"the temporal neighbourhood t must be a positive integer, got {t!r}")
    for n in lengths:
        _check_frames(n, t + 1, f"a temporal neighbourhood of t = {t} in every sequence")
    total = sum(lengths)
    W = np.zeros((total, total))
    offset = 0
    for n in lengths:
        index = np.arange(n)
        gap = np.abs(index[:, None] - index[None])
        W[offset:offset + n, offset:offset + n] = (gap > 0) & (gap <= t)
        offset += n
    return W


def connected_components(W) -> list[np.ndarray]:
    """The connected components of the graph ``W`` (lists of frame indices), largest first."""
    from scipy.sparse.csgraph import connected_components as components

    count, labels = components(np.asarray(W) > 0, directed=False)
    groups = [np.flatnonzero(labels == c) for c in range(count)]
    return sorted(groups, key=len, reverse=True)


def laplacian_embedding(W, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The embedding (002 eq. 7): the generalised eigenvectors ``L v = lambda D v`` of the ``n``
    smallest non-zero eigenvalues, normalised so that ``Z^T D Z = I``.

    Returns:
        ``(Z (M, n), eigenvalues (n,))``.

    Raises:
        ConfigurationError: if the graph is not symmetric and non-negative, has an isolated frame or
            several connected components (each would add a zero eigenvalue whose eigenvector is
            constant on the components: the components are reported instead), or fewer than
            ``n + 1`` frames.
    """
    from scipy.linalg import eigh

    W = np.asarray(W, np.float64)
    if W.ndim != 2 or W.shape[0] != W.shape[1]:
        raise ConfigurationError(f"the graph must be a square (M, M) weight matrix, got shape {W.shape}")
    if not np.all(np.isfinite(W)) or np.any(W < 0) or not np.allclose(W, W.T):
        raise ConfigurationError("the graph weights must be finite, non-negative and symmetric")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ConfigurationError(f"the embedding dimension must be a positive integer, got {n!r}")
    _check_frames(W.shape[0], n + 1, f"a {n}-dimensional Laplacian embedding")
    groups = connected_components(W)
    if len(groups) > 1:
        sizes = ", ".join(str(len(g)) for g in groups[:8]) + (", ..." if len(groups) > 8 else "")
        firsts = ", ".join(str(int(g[0])) for g in groups[1:4])
        raise ConfigurationError(f"the neighbourhood graph has {len(groups)} connected components (sizes {sizes}); the embedding "
                            f"would be constant on each. Frames {firsts}... start the smaller ones: connect them (a larger "
                            "neighbourhood, stylistic neighbours across sequences) or embed them separately")
    degree = W.sum(axis=1)
    laplacian = np.diag(degree) - W
    values, vectors = eigh(laplacian, np.diag(degree))
    # The smallest eigenvalue is 0 (constant eigenvector) for a connected graph: skip it.
    return vectors[:, 1:n + 1], values[1:n + 1]


def stylistic_neighbours(Y, lengths, t: int, *, batch: int = 64) -> np.ndarray:
    """GLE's stylistic neighbours (002 eq. 3): for every frame k and every other repetition h
    (a training sequence, or a gait cycle of one), the temporal window of 2t + 1 frames around k
    (shifted inside its repetition at the ends) is aligned to h by subsequence DTW, and the frame
    of the aligned window closest to frame k in pose space is k's neighbour in h.

    Args:
        Y: (M, D) the training frames, the repetitions one after another.
        lengths: frames of each repetition, in order (at least two repetitions).
        t: half-width of the temporal window.
        batch: frames aligned at once (memory: batch x repetitions x (2t+1) x longest).

    Returns:
        (M, R) global frame index of frame k's neighbour in repetition h; -1 where h is k's own.
    """
    import jax
    import jax.numpy as jnp

    from ._dtw import subsequence_dtw

    Y = np.asarray(Y, np.float64)
    lengths = [int(n) for n in lengths]
    if len(lengths) < 2:
        raise ConfigurationError("stylistic neighbours need at least two repetitions (sequences or cycles) to align")
    if sum(lengths) != Y.shape[0]:
        raise ConfigurationError(f"the repetitions hold {sum(lengths)} frames, the training data {Y.shape[0]}")
    window = 2 * t + 1
    for index, n in enumerate(lengths):
        if n < window:
            raise ConfigurationError(f"repetition {index} has {n} frames, fewer than the DTW window of 2t + 1 = {window}")
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    longest = max(lengths)
    far = np.abs(Y).max() * 1e3 + 1e3  # padding no alignment ends in
    reps = np.full((len(lengths), longest, Y.shape[1]), far)
    for h, (s, n) in enumerate(zip(starts, lengths)):
        reps[h, :n] = Y[s:s + n]
    owner = np.repeat(np.arange(len(lengths)), lengths)
    frame = np.arange(Y.shape[0])
    window_start = np.clip(frame - t, starts[owner], starts[owner] + np.asarray(lengths)[owner] - window)
    valid = np.arange(longest)[None, :] < np.asarray(lengths)[:, None]  # (R, longest)

    Yj, reps_j, valid_j = jnp.asarray(Y), jnp.asarray(reps), jnp.asarray(valid)

    def neighbours_of(k, first):
        query = jax.lax.dynamic_slice_in_dim(Yj, first, window)

        def in_repetition(rep, ok):
            cost, begin = subsequence_dtw(query, rep)
            end = jnp.argmin(jnp.where(ok, cost, jnp.inf))
            inside = ok & (jnp.arange(longest) >= begin[end]) & (jnp.arange(longest) <= end)
            distance = jnp.sum((rep - Yj[k]) ** 2, axis=1)
            return jnp.argmin(jnp.where(inside, distance, jnp.inf))

        return jax.vmap(in_repetition)(reps_j, valid_j)

    local = jax.lax.map(lambda kf: neighbours_of(*kf), (jnp.asarray(frame), jnp.asarray(window_start)), batch_size=batch)
    result = np.asarray(local) + starts[None, :]
    result[frame, owner] = -1
    return result


def stylistic_graph(neighbours: np.ndarray) -> np.ndarray:
    """``W_S`` (002 eq. 5): 1 between each frame and its stylistic neighbours, symmetrised."""
    M = neighbours.shape[0]
    W = np.zeros((M, M))
    rows, cols = np.nonzero(neighbours >= 0)
    W[rows, neighbours[rows, cols]] = 1.0
    return np.maximum(W, W.T)


def gle_graph(Y, lengths, t: int, alpha: float = 1.0) -> np.ndarray:
    """GLE's graph ``W = W_T + alpha W_S`` (002 eqs. 4-6): temporal neighbours within each
    repetition and ``alpha`` times the stylistic ones across repetitions."""
    if not (np.isfinite(alpha) and alpha >= 0):
        raise ConfigurationError(f"alpha must be a finite number >= 0, got {alpha!r}")
    return temporal_graph(lengths, t) + alpha * stylistic_graph(stylistic_neighbours(Y, lengths, t))


def gait_period(poses, *, min_period: int = 8, max_period: int | None = None, min_correlation: float = 0.5) -> int:
    """The period (frames) of a cyclic motion: the lag of the highest autocorrelation peak of the
    mean-removed joint trajectories between ``min_period`` and ``max_period`` (default: half the
    sequence). Raises ``ConfigurationError`` when no peak reaches ``min_correlation`` of the
    zero-lag value (no clear period: fewer than two cycles, or not a cyclic motion)."""
    Y = np.asarray(poses, np.float64)
    T = Y.shape[0]
    max_period = T // 2 if max_period is None else max_period
    if T < 2 * min_period or max_period < min_period:
        raise ConfigurationError(f"a gait period of at least {min_period} frames needs two cycles: {2 * min_period} frames or "
                                 f"more, got {T}")
    centred = Y - Y.mean(axis=0)
    lags = np.arange(min_period, max_period + 1)
    # Normalised by the overlap, so long lags are not penalised for having fewer terms.
    correlation = np.array([np.sum(centred[:-lag] * centred[lag:]) / (T - lag) for lag in lags])
    zero_lag = np.sum(centred * centred) / T
    peaks = [i for i in range(1, len(lags) - 1) if correlation[i] >= correlation[i - 1] and correlation[i] >= correlation[i + 1]
             and correlation[i] >= min_correlation * zero_lag]
    if not peaks:
        raise ConfigurationError(f"no clear period between {min_period} and {max_period} frames in a sequence of {T} frames "
                                 f"(no autocorrelation peak reaches {min_correlation:g} of its value at lag 0)")
    return int(lags[max(peaks, key=lambda i: correlation[i])])


def gait_cycles(poses, *, min_period: int = 8, max_period: int | None = None, min_correlation: float = 0.5) -> list[int]:
    """Split one cyclic sequence into its repetitions (gait cycles) for GLE's stylistic
    neighbours: boundaries where the pose returns closest to the first frame's, searched within
    a quarter period of each multiple of ``gait_period``. Returns the cycles' lengths (they sum
    to the sequence's frames; a tail shorter than half a period joins the last cycle)."""
    Y = np.asarray(poses, np.float64)
    period = gait_period(Y, min_period=min_period, max_period=max_period, min_correlation=min_correlation)
    distance = np.linalg.norm(Y - Y[0], axis=1)
    bounds, last = [0], 0
    while last + period + period // 4 < Y.shape[0]:
        lo, hi = last + period - period // 4, min(Y.shape[0] - 1, last + period + period // 4)
        last = lo + int(np.argmin(distance[lo:hi + 1]))
        bounds.append(last)
    if Y.shape[0] - bounds[-1] < period // 2 and len(bounds) > 1:
        bounds.pop()
    return [int(b - a) for a, b in zip(bounds, bounds[1:] + [Y.shape[0]])]
