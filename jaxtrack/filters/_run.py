"""The one place that loops over frames: a filter's ``step`` scanned over a sequence in one
jitted ``lax.scan``."""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import ArrayLike, Float, PRNGKeyArray
from ._base import AbstractFilter, FilterState, StepInfo


@eqx.filter_jit
def _scan(filter_, key, initial_pose, observations):
    init_key, step_key = jax.random.split(key)
    state = filter_.init(init_key, initial_pose)
    num_frames = jax.tree.leaves(observations)[0].shape[0]
    keys = jax.random.split(step_key, num_frames)

    def body(state, inputs):
        frame_key, observation = inputs
        return filter_.step(frame_key, state, observation)

    return jax.lax.scan(body, state, (keys, observations))


def run_filter(
    filter_: AbstractFilter, key: PRNGKeyArray, initial_pose: Float[ArrayLike, " d"], observations: Any
) -> tuple[FilterState, StepInfo]:
    """Run a filter over a sequence in one jitted ``lax.scan``.

    Args:
        filter_: any ``AbstractFilter`` (SIR, APF, or one of your own).
        key: PRNG key; frame t uses the t-th of ``split(key)``'s per-frame keys. The same key
            gives the same result, jitted or not. Runs over several keys can be vmapped:
            ``jax.vmap(lambda k: run_filter(f, k, pose, obs))(keys)``.
        initial_pose: (D,) the pose at frame 0 (000 Alg. 1 line 1 duplicates it N times).
        observations: per-frame observations with a leading frame axis T, e.g. silhouettes
            (T, C, H, W).

    Returns:
        ``(final_state, infos)`` with every ``StepInfo`` field stacked over T frames.

    Raises:
        TypeError: if ``filter_`` is not an ``AbstractFilter``.
        ValueError: on an initial pose that is not one finite vector, or no frames.
    """
    if not isinstance(filter_, AbstractFilter):
        raise TypeError(f"run_filter needs an AbstractFilter, got {type(filter_).__name__}")
    initial_pose = jnp.asarray(initial_pose)
    if initial_pose.ndim != 1:
        raise ValueError(f"initial_pose must be one pose vector (D,), got shape {initial_pose.shape}")
    if not isinstance(initial_pose, jax.core.Tracer) and not np.all(np.isfinite(np.asarray(initial_pose))):
        raise ValueError("initial_pose contains NaN or infinite entries")
    leaves = jax.tree.leaves(observations)
    if not leaves or np.shape(leaves[0])[:1] in ((), (0,)):
        raise ValueError("observations must have a leading frame axis with at least one frame")
    return _scan(filter_, key, initial_pose, observations)
