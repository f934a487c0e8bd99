"""Dynamic time warping as a jitted JAX kernel (for GLE's stylistic neighbours, 002 sec. 2.1).

The cumulative cost ``D[i, j] = c[i, j] + min(D[i-1, j-1], D[i-1, j], D[i, j-1])`` is computed one
row at a time in a ``lax.scan``. Within a row the dependence on ``D[i, j-1]`` is the recurrence
``x_j = min(a_j + c_j, x_{j-1} + c_j)`` with ``a_j = min(D[i-1, j-1], D[i-1, j])``: an affine map
in the (min, +) semiring, and the composition of two such maps is one again, so each row is a
``lax.associative_scan`` (log-depth) rather than a Python or ``lax`` loop over the columns.

``subsequence_dtw`` is the open-begin, open-end variant used to find where a query (a frame's
temporal window) occurs inside a longer series (another repetition): the first row starts
anywhere, and each cell carries the column its path started from, so the matched window needs
no backtracking.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._custom_types import Array, Float, Int


def pairwise_distance(a: Float[Array, "m d"], b: Float[Array, "n d"]) -> Float[Array, "m n"]:
    """Euclidean distances between the rows of ``a`` and ``b`` (from the differences: exact 0
    for equal frames, which the expanded ``|a|^2 + |b|^2 - 2 a.b`` is not)."""
    return jnp.sqrt(jnp.sum((a[:, None, :] - b[None, :, :]) ** 2, axis=-1))


def _combine(left, right):
    """Compose the row maps ``x -> min(B, x + C)`` (with the start column of B's path)."""
    b1, s1, c1 = left
    b2, s2, c2 = right
    through = b1 + c2
    take_right = b2 <= through
    return jnp.where(take_right, b2, through), jnp.where(take_right, s2, s1), c1 + c2


def _next_row(previous, previous_start, cost_row):
    """Row i of the cumulative cost (and start columns) from row i-1 and the costs c[i, :]."""
    diagonal = jnp.concatenate([jnp.full((1,), jnp.inf, previous.dtype), previous[:-1]])
    diagonal_start = jnp.concatenate([previous_start[:1], previous_start[:-1]])
    take_diagonal = diagonal <= previous
    best = jnp.where(take_diagonal, diagonal, previous)
    best_start = jnp.where(take_diagonal, diagonal_start, previous_start)
    # x_j = min(best_j + c_j, x_{j-1} + c_j), x_{-1} = inf: the inclusive scan of the maps.
    values, starts, _ = jax.lax.associative_scan(_combine, (best + cost_row, best_start, cost_row))
    return values, starts


def _accumulate(cost: Float[Array, "m n"], first_row, first_start):
    def row(carry, cost_row):
        values, starts = _next_row(*carry, cost_row)
        return (values, starts), None

    (values, starts), _ = jax.lax.scan(row, (first_row, first_start), cost[1:])
    return values, starts


@jax.jit
def dtw_distance(a: Float[Array, "m d"], b: Float[Array, "n d"]) -> Float[Array, ""]:
    """The DTW distance of two series (sum of Euclidean frame distances along the best monotone
    alignment from (0, 0) to (m-1, n-1))."""
    cost = pairwise_distance(a, b)
    first = jnp.cumsum(cost[0])
    values, _ = _accumulate(cost, first, jnp.zeros(cost.shape[1], jnp.int32))
    return values[-1]


@jax.jit
def subsequence_dtw(query: Float[Array, "m d"], series: Float[Array, "n d"]) -> tuple[Float[Array, " n"], Int[Array, " n"]]:
    """Open-begin, open-end DTW of ``query`` against every window of ``series``.

    Returns:
        ``(cost, start)``, each (n,): for every end column j, the cost of the best alignment of
        the whole query with some ``series[start[j] : j + 1]``, and that start.
    """
    cost = pairwise_distance(query, series)
    return _accumulate(cost, cost[0], jnp.arange(cost.shape[1], dtype=jnp.int32))


def best_window(query: Float[Array, "m d"], series: Float[Array, "n d"]) -> tuple[Int[Array, ""], Int[Array, ""], Float[Array, ""]]:
    """The window ``series[start : end + 1]`` best aligned with ``query``: ``(start, end, cost)``."""
    cost, start = subsequence_dtw(query, series)
    end = jnp.argmin(cost)
    return start[end], end, cost[end]
