"""Boundary checks shared by the entry points: run on concrete arrays before anything is jitted."""

from __future__ import annotations

import numpy as np


def as_float_array(value, name: str, *, ndim: int | None = None, last: tuple[int, ...] = ()):
    """Convert ``value`` to a floating NumPy array and check its rank, trailing shape and finiteness.

    Raises:
        TypeError: if ``value`` is not numeric.
        ValueError: on a wrong rank, a wrong trailing shape, or a NaN/inf entry.
    """
    try:
        arr = np.asarray(value)
    except Exception as err:  # pragma: no cover - numpy raises many types here
        raise TypeError(f"{name} must be an array of numbers, got {type(value).__name__}") from err
    if arr.dtype == object or not (
        np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)
    ):
        raise TypeError(f"{name} must hold real numbers, got dtype {arr.dtype}")
    if not np.issubdtype(arr.dtype, np.floating):
        arr = arr.astype(np.float64)
    if ndim is not None and arr.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} dimensions, got shape {arr.shape}")
    if last and tuple(arr.shape[-len(last) :]) != tuple(last):
        raise ValueError(f"{name} must have trailing shape {tuple(last)}, got shape {arr.shape}")
    check_finite(arr, name)
    return arr


def check_finite(arr, name: str) -> None:
    """Raise ``ValueError`` naming the first non-finite entry of ``arr``."""
    arr = np.asarray(arr)
    if np.issubdtype(arr.dtype, np.floating) and not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(
            f"{name} contains a non-finite value ({arr[tuple(bad)]}) at index {tuple(int(i) for i in bad)}"
        )


def check_key(key, name: str = "key") -> None:
    """Raise ``TypeError`` unless ``key`` is one PRNG key: a typed key (``jax.random.key(seed)``,
    traced ones included) or a legacy raw ``uint32[2]`` key (``jax.random.PRNGKey(seed)``)."""
    import jax

    dtype = getattr(key, "dtype", None)
    shape = getattr(key, "shape", None)
    if dtype is not None and jax.dtypes.issubdtype(dtype, jax.dtypes.prng_key):
        if shape != ():
            raise TypeError(f"{name} must be one PRNG key, got a batch of shape {shape} (vmap over the keys instead)")
        return
    if dtype == np.uint32 and shape == (2,):
        return
    shown = repr(key) if isinstance(key, (int, float, str)) else type(key).__name__
    raise TypeError(f"{name} must be a PRNG key, e.g. jax.random.key(0); got {shown}")
