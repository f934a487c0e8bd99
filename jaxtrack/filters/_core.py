"""What every filter shares: its state, its per-frame info, and the jitted runner that scans a
filter over the frames of a sequence.

A filter is an equinox Module with two pure methods,

    init(key, initial_pose (D,)) -> FilterState
    step(key, state, observation) -> (FilterState, StepInfo)

whose per-particle work is vmapped (or batched) over the leading particle axis. A likelihood is
any callable ``(poses (N, D), observation) -> (N,)`` log-likelihoods, such as
``SilhouetteLikelihood(...).log_likelihood``.
"""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp

from .._custom_types import Array, Bool, Float


class FilterState(eqx.Module):
    """Particles (a leading axis of N) and their log-weights (not necessarily normalised).

    ``particles`` is (N, S): poses for the pose-space filters, (global 6 DoF, latent point)
    for the latent-space ones.
    """

    particles: Float[Array, "n s"]
    log_weights: Float[Array, " n"]


class StepInfo(eqx.Module):
    """What a step reports for its frame.

    Attributes:
        estimate: (D,) the pose estimate.
        ess: effective sample size of the final weights.
        log_evidence: the log-likelihood increment ``ln p(I_t | I_1:t-1)`` estimate
            (of the final layer's target for annealed filters).
        betas: (M,) annealing exponents per layer (ones for unannealed filters).
        survival: (M,) survival rate ``ESS / N`` per layer.
        degenerate: whether any layer's weights were all ``-inf``/NaN (then made uniform).
    """

    estimate: Float[Array, " d"]
    ess: Float[Array, ""]
    log_evidence: Float[Array, ""]
    betas: Float[Array, " m"]
    survival: Float[Array, " m"]
    degenerate: Bool[Array, ""]


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


def run_filter(filter_, key, initial_pose: Float[Array, " d"], observations: Any) -> tuple[FilterState, StepInfo]:
    """Run a filter over a sequence in one jitted ``lax.scan``.

    Args:
        filter_: a filter (SIR, APF, MRPF, GPAPF, LatentPF).
        key: PRNG key; the same key gives the same result, jitted or not.
        initial_pose: (D,) the pose at frame 0 (000 Alg. 1 line 1 duplicates it N times).
        observations: per-frame observations with a leading frame axis T, e.g. silhouettes
            (T, C, H, W).

    Returns:
        ``(final_state, infos)`` with every ``StepInfo`` field stacked over T frames.
    """
    initial_pose = jnp.asarray(initial_pose)
    if initial_pose.ndim != 1:
        raise ValueError(f"initial_pose must be one pose vector (D,), got shape {initial_pose.shape}")
    if not bool(jnp.all(jnp.isfinite(initial_pose))):
        raise ValueError("initial_pose contains NaN or infinite entries")
    leaves = jax.tree.leaves(observations)
    if not leaves or leaves[0].shape[0] == 0:
        raise ValueError("observations must have a leading frame axis with at least one frame")
    return _scan(filter_, key, initial_pose, observations)


def check_scales(name: str, scales, size: int, dtype=None):
    """A positive (size,) noise scale vector (a scalar is broadcast); raises ``ValueError``.
    With ``dtype``, values beyond its range are clipped to its largest finite number (a scale
    that large is flat; casting would overflow to inf)."""
    import numpy as np

    values = np.broadcast_to(np.asarray(scales, np.float64), (size,)) if np.ndim(scales) == 0 else np.asarray(scales, np.float64)
    if values.shape != (size,):
        raise ValueError(f"{name} must be a scalar or have shape ({size},), got {values.shape}")
    if not np.all(np.isfinite(values)) or np.any(values < 0):
        raise ValueError(f"{name} must be finite and non-negative")
    if dtype is not None:
        values = np.minimum(values, float(np.finfo(np.dtype(dtype)).max))
    return values


def check_particles(num_particles: int):
    if not isinstance(num_particles, int) or num_particles < 1:
        raise ValueError(f"num_particles must be a positive integer, got {num_particles!r}")


def duplicate(initial, num_particles: int):
    """``N`` copies of one state with uniform log-weights (000 Alg. 1 line 1)."""
    particles = jnp.broadcast_to(initial, (num_particles,) + initial.shape)
    return FilterState(particles=particles, log_weights=jnp.zeros(num_particles, initial.dtype))
