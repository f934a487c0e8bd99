"""The noise of the GPDM's latent dynamics, refitted on validation motion.

The GPDM's predictive variance ``sigma_X^2(z)`` (001 eqs. 7-9) is fitted on the training
trajectory, where the dynamics GP interpolates its own points. On another take of the motion it
is wrong both ways (docs/floor.md, "GPDM latent noise"): measured on the validation takes, most steps
``z_{t+1} - mu_X(z_t)`` of the projected poses are smaller than ``sigma_X``, and one in five to
one in three is many times larger (the next pose is nearer another stretch of the learned cycle:
another take's loop, or the other leg's phase). A Gaussian with the training variance leaves no
particle that can follow such a step; a Gaussian wide enough to cover them diffuses every
particle off the cycle. The trackers' other noise scales are fitted on validation motion (000
sec. 5.2), and so is this one: a two-component scale mixture,

    z_t ~ (1 - eps) N(mu_X(z_{t-1}), c_core^2 sigma_X^2 I) + eps N(mu_X(z_{t-1}), c_jump^2 sigma_X^2 I),

with ``(eps, c_core, c_jump)`` the maximum-likelihood fit (EM) to the validation steps. With
``eps = 0`` and ``c_core = 1`` it is the GPDM's own predictive distribution.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import logsumexp

from .._custom_types import Array, Float, PRNGKeyArray
from ..manifold import ManifoldPrior

JUMP_STREAM = 3571  # fold_in tag of the component choices, apart from the normal draws
MIN_STEPS = 10  # fewer validation steps than this: the GPDM's own noise, unfitted
LATENT_NOISE_FITS = ("gpdm", "validation")  # the GPDM's own noise, or the mixture fitted on validation motion


class LatentNoiseMixture(eqx.Module):
    """A scale mixture of two isotropic Gaussians relative to a per-particle standard deviation.

    Attributes:
        core: scale of the common component (times ``sigma_X``).
        jump: scale of the rare component (times ``sigma_X``), >= ``core``.
        jump_probability: weight ``eps`` of the rare component, in [0, 1).
    """

    core: Float[Array, ""]
    jump: Float[Array, ""]
    jump_probability: Float[Array, ""]

    def __check_init__(self):
        values = [np.asarray(v) for v in (self.core, self.jump, self.jump_probability) if not isinstance(v, jax.core.Tracer)]
        if len(values) == 3:
            core, jump, eps = (float(v) for v in values)
            if not (core > 0 and jump >= core and math.isfinite(jump) and 0 <= eps < 1):
                raise ValueError(f"need 0 < core <= jump (finite) and 0 <= jump_probability < 1, got {core}, {jump}, {eps}")

    def factors(self, key: PRNGKeyArray, num: int, dtype) -> Float[Array, " n"]:
        """(N,) each particle's scale factor: ``jump`` with probability ``eps``, else ``core``
        (the normal draws they multiply come from the caller's key, so that with ``eps = 0`` and
        ``core = 1`` a draw is bit for bit the GPDM's own)."""
        jumps = jax.random.uniform(key, (num,), dtype) < self.jump_probability
        return jnp.where(jumps, jnp.asarray(self.jump, dtype), jnp.asarray(self.core, dtype))

    def log_density(self, residual: Float[Array, "n q"], sd: Float[Array, " n"]) -> Float[Array, " n"]:
        """``ln p(residual)`` per row, normalised except for ``-(q/2) ln(2 pi)``."""
        q = residual.shape[-1]
        squared = jnp.sum(residual**2, axis=-1) / sd**2
        dtype = residual.dtype

        def component(weight, scale):
            scale = jnp.asarray(scale, dtype)
            return jnp.log(jnp.asarray(weight, dtype)) - 0.5 * squared / scale**2 - q * jnp.log(scale * sd)

        if_core = component(1.0 - self.jump_probability, self.core)
        if_jump = jnp.where(self.jump_probability > 0, component(jnp.maximum(self.jump_probability, 1e-30), self.jump), -jnp.inf)
        return logsumexp(jnp.stack([if_core, if_jump]), axis=0)


def check_latent_noise_fit(latent_noise: str) -> None:
    """Raise ``ValueError`` unless ``latent_noise`` is one of ``LATENT_NOISE_FITS``."""
    if latent_noise not in LATENT_NOISE_FITS:
        raise ValueError(f"latent_noise must be one of {LATENT_NOISE_FITS}, got {latent_noise!r}")


def gpdm_noise() -> LatentNoiseMixture:
    """The GPDM's own predictive distribution: one component of scale 1."""
    return LatentNoiseMixture(core=jnp.asarray(1.0), jump=jnp.asarray(1.0), jump_probability=jnp.asarray(0.0))


def fit_latent_noise(manifold: ManifoldPrior, sequences: list[np.ndarray], *, iterations: int = 500) -> LatentNoiseMixture:
    """Maximum-likelihood mixture (EM) for the validation steps of the GPDM's latent dynamics.

    Each (T, D) pose sequence is projected onto the manifold (``encode``); the statistic of step
    t is ``s_t = ||z_{t+1} - mu_X(z_t)||^2 / sigma_X^2(z_t)``, which under the mixture is
    ``c^2 chi^2_q`` with ``c`` the component's scale. With fewer than ``MIN_STEPS`` steps, the
    GPDM's own noise (``gpdm_noise``).
    """
    g, q = manifold.global_dims, manifold.latent_dim
    dtype = manifold.training_latent.dtype
    statistics = []
    for s in sequences:
        latent = manifold.encode(jnp.asarray(s[:, g:], dtype))
        mean, variance = manifold.predict_latent(latent[:-1])
        statistics.append(np.sum(np.square(np.asarray(latent[1:] - mean, np.float64)), axis=1) / np.asarray(variance, np.float64))
    s = np.concatenate(statistics)
    if s.size < MIN_STEPS:
        return gpdm_noise()
    return fit_scale_mixture(s, q, iterations=iterations, dtype=dtype)


def fit_scale_mixture(statistics, dims: int, *, iterations: int = 500, dtype=jnp.float32) -> LatentNoiseMixture:
    """Maximum-likelihood (EM) two-component scale mixture for squared normalised residuals:
    ``s ~ (1 - eps) c_core^2 chi^2_q + eps c_jump^2 chi^2_q`` with ``q = dims``.

    Args:
        statistics: (n,) the ``s`` values, non-negative and finite, n >= 2.
        dims: q, the residuals' dimension.
        iterations: most EM iterations (it stops when the mean log-likelihood gains < 1e-10).
        dtype: of the returned mixture's entries.
    """
    s = np.asarray(statistics, np.float64).ravel()
    if s.size < 2 or not np.all(np.isfinite(s)) or np.any(s < 0):
        raise ValueError(f"statistics must be at least 2 finite non-negative values, got {s.size} values")
    if dims < 1:
        raise ValueError(f"dims must be >= 1, got {dims}")
    s, q = np.maximum(s, 1e-12), dims

    def log_chi2(variance):  # ln density of s under variance * chi^2_q
        x = s / variance
        return (0.5 * q - 1) * np.log(x) - 0.5 * x - 0.5 * q * math.log(2) - math.lgamma(0.5 * q) - np.log(variance)

    variances = np.array([np.quantile(s, 0.5), np.quantile(s, 0.95)]) / q
    weights = np.array([0.8, 0.2])
    previous = -np.inf
    for _ in range(iterations):
        log_joint = np.stack([np.log(weights[k]) + log_chi2(variances[k]) for k in range(2)])
        total = np.logaddexp(log_joint[0], log_joint[1])
        responsibility = np.exp(log_joint - total)
        weights = np.clip(responsibility.mean(axis=1), 1e-6, 1 - 1e-6)
        variances = np.maximum((responsibility * s).sum(axis=1) / (q * responsibility.sum(axis=1)), 1e-12)
        if total.mean() - previous < 1e-10:
            break
        previous = total.mean()
    order = np.argsort(variances)
    variances, weights = variances[order], weights[order]
    core, jump = np.sqrt(variances)
    return LatentNoiseMixture(core=jnp.asarray(core, dtype), jump=jnp.asarray(max(jump, core), dtype),
                              jump_probability=jnp.asarray(weights[1], dtype))
