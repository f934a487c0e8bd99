"""Pytree helpers shared by the packages: the one precision cast at the tracking boundary."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np


def cast_floating(tree, dtype):
    """``tree`` with every floating array cast to ``dtype``; integer, key and static leaves are
    kept. Values beyond the dtype's range are clipped to its largest finite value first, so a
    noise scale that is effectively infinite (a flat factor) stays finite instead of becoming
    ``inf`` (which would turn ``0 * inf`` into NaN downstream). Concrete arrays are converted
    on the host (exact float64 -> float32 rounding whether or not x64 is enabled)."""
    largest = float(np.finfo(np.dtype(dtype)).max)

    def cast(leaf):
        if not (eqx.is_inexact_array(leaf) and jnp.issubdtype(leaf.dtype, jnp.floating)):
            return leaf
        if float(np.finfo(leaf.dtype).max) <= largest:  # widening (or same): every value fits
            return leaf.astype(dtype)
        if isinstance(leaf, jax.core.Tracer):
            return jnp.clip(leaf, -largest, largest).astype(dtype)
        return jnp.asarray(np.clip(np.asarray(leaf), -largest, largest).astype(dtype))

    return jax.tree.map(cast, tree)
