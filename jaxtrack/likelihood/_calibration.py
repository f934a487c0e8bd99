"""Body-shape calibration: the capsule radii fitted to observed silhouettes by gradient descent
through the soft rasteriser, with the pose held at a known estimate (e.g. the initial pose that
every run of the experiment starts from).

Real people are not the default capsules. The silhouette likelihood's optimum moves away from
the true pose when the radii are wrong (a thicker torso explains the arms' pixels), so the
trackers fit the radii first: the maximum a posteriori ``log r`` (left and right capsules
share a radius) under the tracker's own likelihood, ``sum_frames ln p(I | x, r)`` (000 eq. 12 at
the likelihood's temperature), and a Gaussian prior on each ``log r`` around its starting value
with standard deviation ``prior_sd`` (default 0.15: people's limb girths differ from the
default capsules by about 10-20 %). Without the prior, noisy silhouettes (foot shadows,
boundary jitter, clutter) are explained by fattening the capsules: on the demo's noisy 80x60
views an almost unregularised fit doubled the shins' radii.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from .._custom_types import ArrayLike, Float, Shaped
from ._silhouette import SilhouetteLikelihood


class ShapeCalibration(NamedTuple):
    """What a calibration did: radii (metres) and cost (000 eq. 12, mean over frames and views)
    before and after, and the loss per step."""

    capsule_names: tuple[str, ...]
    radii_before: np.ndarray
    radii_after: np.ndarray
    cost_before: float
    cost_after: float
    trace: np.ndarray


def symmetric_groups(names: tuple[str, ...]) -> np.ndarray:
    """(K,) parameter index of each capsule: capsules named ``l<part>`` and ``r<part>`` share one."""
    keys, index = [], []
    for name in names:
        key = name[1:] if name[:1] in "lr" and ("l" + name[1:]) in names and ("r" + name[1:]) in names else name
        if key not in keys:
            keys.append(key)
        index.append(keys.index(key))
    return np.asarray(index)


def calibrate_shape(
    likelihood: SilhouetteLikelihood,
    poses: Float[ArrayLike, "frames dofs"],
    observations: Shaped[ArrayLike, "frames views height width"],
    *,
    steps: int = 150,
    learning_rate: float = 0.03,
    prior_sd: float = 0.15,
    symmetric: bool = True,
) -> tuple[SilhouetteLikelihood, ShapeCalibration]:
    """Fit the likelihood body's capsule radii to silhouettes of known poses.

    Args:
        likelihood: the silhouette likelihood whose body to calibrate.
        poses: (F, D) the known poses of the F frames used (e.g. the initial pose, F = 1).
        observations: (F, C, H, W) their observed silhouettes (0/1).
        steps: Adam steps on the log radii.
        learning_rate: Adam's step size (log-radius units).
        prior_sd: standard deviation of the Gaussian prior on each log radius around its start.
        symmetric: left and right capsules share a radius.

    Returns:
        the likelihood with the fitted radii, and a ``ShapeCalibration`` report.

    Raises:
        ValueError: on shapes that do not match the likelihood's rig and body, a non-finite
            pose, an empty observed silhouette, or non-positive settings.
    """
    poses = np.asarray(poses, np.float64)
    observations = np.asarray(observations)
    body = likelihood.body
    views = likelihood.rig.num_views
    if poses.ndim != 2 or poses.shape[1] != body.skeleton.num_dofs or poses.shape[0] < 1:
        raise ValueError(f"poses must be (frames >= 1, {body.skeleton.num_dofs}), got {poses.shape}")
    if observations.ndim != 4 or observations.shape[:2] != (poses.shape[0], views):
        raise ValueError(f"observations must be ({poses.shape[0]}, {views}, H, W) to match the poses and cameras, got {observations.shape}")
    if not np.all(np.isfinite(poses)):
        raise ValueError("poses contain NaN or infinite values")
    empty = np.argwhere(observations.reshape(observations.shape[:2] + (-1,)).sum(-1) == 0)
    if len(empty):
        raise ValueError(f"observed silhouette of frame {empty[0][0]}, view {empty[0][1]} is empty")
    if steps < 1 or not learning_rate > 0 or not prior_sd > 0:
        raise ValueError("steps, learning_rate and prior_sd must be positive")
    dtype = body.radii.dtype
    groups = symmetric_groups(body.capsule_names) if symmetric else np.arange(body.num_capsules)
    start = np.log(np.asarray(body.radii, np.float64))
    theta0 = np.array([start[groups == g].mean() for g in range(groups.max() + 1)])
    fitted_theta, trace, before, after = _fit(
        likelihood, jnp.asarray(poses, dtype), jnp.asarray(observations, dtype), jnp.asarray(theta0, dtype),
        jnp.asarray(groups), steps, learning_rate, prior_sd,
    )
    radii = jnp.exp(fitted_theta)[jnp.asarray(groups)]
    calibrated = eqx.tree_at(lambda lik: lik.body.radii, likelihood, radii.astype(dtype))
    report = ShapeCalibration(
        capsule_names=body.capsule_names, radii_before=np.asarray(body.radii, np.float64), radii_after=np.asarray(radii, np.float64),
        cost_before=float(before), cost_after=float(after), trace=np.asarray(trace),
    )
    return calibrated, report


@eqx.filter_jit
def _fit(likelihood, poses, observations, theta0, groups, steps, learning_rate, prior_sd):
    optimiser = optax.adam(learning_rate)

    def cost(theta):
        model = eqx.tree_at(lambda lik: lik.body.radii, likelihood, jnp.exp(theta)[groups])
        per_frame = jax.vmap(lambda pose, obs: model.log_likelihood(pose[None], obs)[0])(poses, observations)
        return -jnp.mean(per_frame) / likelihood.scale

    def loss(theta):
        # -ln p(I | x, r) summed over the frames, minus the log prior
        return likelihood.scale * cost(theta) * poses.shape[0] + 0.5 * jnp.sum(((theta - theta0) / prior_sd) ** 2)

    def step(carry, _):
        theta, state = carry
        value, grad = jax.value_and_grad(loss)(theta)
        updates, state = optimiser.update(grad, state)
        return (optax.apply_updates(theta, updates), state), value

    (theta, _), trace = jax.lax.scan(step, (theta0, optimiser.init(theta0)), None, length=steps)
    return theta, trace, cost(theta0), cost(theta)
