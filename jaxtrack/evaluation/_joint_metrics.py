"""Tracking error in millimetres (paper 000 eq. 31; docs/papers.md)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import jax.numpy as jnp

from .._custom_types import Array, ArrayLike, Float


def joint_errors_mm(
    estimate: Float[ArrayLike, "frames joints 3"], truth: Float[ArrayLike, "frames joints 3"]
) -> Float[Array, "frames joints"]:
    """Euclidean distance between estimated and true joint positions (metres in; JAX or NumPy
    arrays), millimetres out."""
    estimate, truth = jnp.asarray(estimate), jnp.asarray(truth)
    if estimate.shape != truth.shape:
        raise ValueError(f"estimate {estimate.shape} and truth {truth.shape} must have the same shape")
    return 1000.0 * jnp.linalg.norm(estimate - truth, axis=-1)


def mean_joint_error_mm(estimate, truth) -> Float[Array, ""]:
    """``err = 1 / (T M) sum_t sum_w ||w(x_t) - w(x_hat_t)||`` (000 eq. 31), in mm."""
    return jnp.mean(joint_errors_mm(estimate, truth))


def per_frame_error_mm(estimate, truth) -> Float[Array, " frames"]:
    """Error curve: the eq. 31 average over joints for each frame (000 Fig. 6), mm."""
    return jnp.mean(joint_errors_mm(estimate, truth), axis=-1)


def per_group_error_mm(
    estimate, truth, groups: Mapping[str, Sequence[int]]
) -> dict[str, Float[Array, ""]]:
    """Eq. 31 restricted to each body-part group (000 Table 2: torso, head, legs, arms), mm."""
    errors = joint_errors_mm(estimate, truth)
    return {name: jnp.mean(errors[:, jnp.asarray(index)]) for name, index in groups.items()}
