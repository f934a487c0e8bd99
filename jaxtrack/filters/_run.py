"""The one place that loops over frames: a filter's ``step`` scanned over a sequence in one
jitted ``lax.scan``."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import ArrayLike, Float, PRNGKeyArray
from .._validation import check_key
from ._base import AbstractFilter, FilterState, StepInfo


def _constrain(state: FilterState, sharding) -> FilterState:
    """The particle axis of the state laid out by ``sharding`` (None: as XLA chooses)."""
    if sharding is None:
        return state
    return jax.tree.map(lambda x: jax.lax.with_sharding_constraint(x, sharding), state)


# Matrix products inside a filter are traced at full float32 precision. On a GPU, JAX's default
# lets float32 products run in TF32 (a 10-bit mantissa), which the GP predictive maps cannot
# afford (measured in docs/testing.md, "On a GPU"). CPUs compute float32 products at full
# precision either way.
FILTER_MATMUL_PRECISION = "highest"


@eqx.filter_jit
def _init(filter_, key, initial_pose, num_frames: int, sharding=None):
    """The initial state and the per-frame keys (frame t uses the t-th of ``split(step_key)``)."""
    init_key, step_key = jax.random.split(key)
    with jax.default_matmul_precision(FILTER_MATMUL_PRECISION):
        state = filter_.init(init_key, initial_pose)
    return _constrain(state, sharding), jax.random.split(step_key, num_frames)


@eqx.filter_jit
def _scan(filter_, state, keys, observations, sharding=None):
    def body(state, inputs):
        frame_key, observation = inputs
        state, info = filter_.step(frame_key, _constrain(state, sharding), observation)
        return _constrain(state, sharding), info

    with jax.default_matmul_precision(FILTER_MATMUL_PRECISION):
        return jax.lax.scan(body, state, (keys, observations))


def particle_sharding(devices=None) -> jax.sharding.NamedSharding:
    """A sharding that splits the particle axis over ``devices`` (default: all of
    ``jax.devices()``), for ``run_filter(..., sharding=...)``. The particle count must be a
    multiple of the number of devices."""
    devices = jax.devices() if devices is None else list(devices)
    mesh = jax.sharding.Mesh(np.asarray(devices), ("particles",))
    return jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("particles"))


def run_filter(
    filter_: AbstractFilter, key: PRNGKeyArray, initial_pose: Float[ArrayLike, " d"], observations: Any, *,
    chunk_frames: int | None = None, on_chunk: Callable[[int, StepInfo], None] | None = None,
    sharding: jax.sharding.Sharding | None = None,
) -> tuple[FilterState, StepInfo]:
    """Run a filter over a sequence in one jitted ``lax.scan`` (or one per chunk of frames).

    Args:
        filter_: any ``AbstractFilter`` (SIR, APF, or one of your own).
        key: PRNG key; frame t uses the t-th of ``split(key)``'s per-frame keys. The same key
            gives the same result, jitted or not, and chunked or not. Runs over several keys can
            be vmapped: ``jax.vmap(lambda k: run_filter(f, k, pose, obs))(keys)``.
        initial_pose: (D,) the pose at frame 0 (000 Alg. 1 line 1 duplicates it N times).
        observations: per-frame observations with a leading frame axis T, e.g. silhouettes
            (T, C, H, W).
        chunk_frames: scan this many frames at a time, the state carried between chunks (the
            last chunk may be shorter, and compiles once more); None: all in one scan.
        on_chunk: called after each chunk as ``on_chunk(frames_done, infos_so_far)`` (host
            side, e.g. to save the estimates so far so that a failure loses one chunk at most).
        sharding: lay the particles out over several devices, e.g. ``particle_sharding()``
            (every device of the process) or a ``NamedSharding`` over a mesh axis of your own;
            XLA partitions the step and gathers across devices where resampling needs it. The
            same key gives the same result as unsharded, up to the order of floating-point sums.
            With ``jax.distributed.initialize()`` the mesh may span processes on several
            machines (docs/trackers.md, "Several devices").

    Returns:
        ``(final_state, infos)`` with every ``StepInfo`` field stacked over T frames.

    Raises:
        TypeError: if ``filter_`` is not an ``AbstractFilter``.
        ValueError: on an initial pose that is not one finite vector, no frames, or a chunk size
            that is not a positive integer.
    """
    if not isinstance(filter_, AbstractFilter):
        raise TypeError(f"run_filter needs an AbstractFilter, got {type(filter_).__name__}")
    check_key(key)
    initial_pose = jnp.asarray(initial_pose)
    if initial_pose.ndim != 1:
        raise ValueError(f"initial_pose must be one pose vector (D,), got shape {initial_pose.shape}")
    if not isinstance(initial_pose, jax.core.Tracer) and not np.all(np.isfinite(np.asarray(initial_pose))):
        raise ValueError("initial_pose contains NaN or infinite entries")
    leaves = jax.tree.leaves(observations)
    if not leaves or np.shape(leaves[0])[:1] in ((), (0,)):
        raise ValueError("observations must have a leading frame axis with at least one frame")
    if chunk_frames is not None and (isinstance(chunk_frames, bool) or not isinstance(chunk_frames, int) or chunk_frames < 1):
        raise ValueError(f"chunk_frames must be a positive integer or None, got {chunk_frames!r}")
    num_frames = int(np.shape(leaves[0])[0])
    if sharding is not None:
        shards = getattr(sharding, "num_devices", 1)
        particles = getattr(filter_, "num_particles", None)
        if particles is not None and particles % shards:
            raise ValueError(f"{particles} particles cannot be split evenly over {shards} devices; use a multiple of {shards}")
    state, keys = _init(filter_, key, initial_pose, num_frames, sharding)
    return _run_chunks(filter_, state, keys, observations, num_frames, chunk_frames, on_chunk, sharding)


def continue_filter(filter_: AbstractFilter, key: PRNGKeyArray, state: FilterState, observations: Any, *,
                    sharding: jax.sharding.Sharding | None = None) -> tuple[FilterState, StepInfo]:
    """Run a filter on from a state (``run_filter``'s final state) over further frames, in one
    jitted ``lax.scan``: frame t of them uses the t-th of ``split(key)``'s per-frame keys. A
    stream tracked a segment at a time carries the particles and their weights across.
    ``run_filter(f, key, pose, obs)`` is ``continue_filter(f, k_step, f.init(k_init, pose), obs)``
    with ``k_init, k_step = split(key)``.

    Raises:
        TypeError: if ``filter_`` is not an ``AbstractFilter``.
        ValueError: on observations with no frames.
    """
    if not isinstance(filter_, AbstractFilter):
        raise TypeError(f"continue_filter needs an AbstractFilter, got {type(filter_).__name__}")
    check_key(key)
    leaves = jax.tree.leaves(observations)
    if not leaves or np.shape(leaves[0])[:1] in ((), (0,)):
        raise ValueError("observations must have a leading frame axis with at least one frame")
    num_frames = int(np.shape(leaves[0])[0])
    return _scan(filter_, _constrain(state, sharding), jax.random.split(key, num_frames), observations, sharding)


def _run_chunks(filter_, state, keys, observations, num_frames: int, chunk_frames, on_chunk, sharding):
    chunk = num_frames if chunk_frames is None else chunk_frames
    pieces = []
    for start in range(0, num_frames, chunk):
        frames = slice(start, min(start + chunk, num_frames))
        state, infos = _scan(filter_, state, keys[frames], jax.tree.map(lambda x, f=frames: x[f], observations), sharding)
        pieces.append(infos)
        if on_chunk is not None:
            # joined on the host: a device concatenation would compile anew at every chunk's length
            so_far = pieces[0] if len(pieces) == 1 else jax.tree.map(lambda *xs: np.concatenate([np.asarray(x) for x in xs]), *pieces)
            on_chunk(frames.stop, so_far)
    infos = pieces[0] if len(pieces) == 1 else jax.tree.map(lambda *xs: jnp.concatenate(xs), *pieces)
    return state, infos
