"""Noise scales of the trackers' dynamics, fitted by maximum likelihood on motion data.

000 sec. 5.2 requires ``s_zx`` to be fitted on a validation set separate from the manifold's
training data (on the training set it would be underestimated). Given validation poses
``x_1..x_T`` (one or more sequences):

- ``s_xx`` (000 eq. 29): per pose entry, the RMS of ``x_t - x_{t-1}``;
- ``s_xz`` (000 eq. 27): per latent dimension, the RMS of ``g(x_t) - g(x_{t-1})``;
- ``s_zx`` (000 eq. 30): per joint angle, the RMS of ``x_t - mu(z_t)`` with ``z_t`` drawn as
  the filter draws it, ``z_t ~ N(g(x_{t-1}), diag(s_xz^2))`` (``samples`` draws per frame):
  the maximum-likelihood scale of eq. 30 under the filter's own generative model (the bare
  residual ``x_t - mu(g(x_t))`` is smaller still);
- ``s_global``: ``s_xx`` of the global entries (GPAPF, LatentPF);
- ``nu`` (003 Alg. 2): per latent dimension, the RMS of the steps of the *training* latent
  trajectory (within each training sequence).

Each is floored at ``floor`` so that no entry is exactly deterministic.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ._manifold_prior import ManifoldPrior


class NoiseScales(NamedTuple):
    s_xx: np.ndarray  # (D,)
    s_xz: np.ndarray  # (q,)
    s_zx: np.ndarray  # (Da,)
    s_global: np.ndarray  # (G,)
    nu: np.ndarray  # (q,)


def _rms(values, axis=0):
    return np.sqrt(np.mean(np.square(values), axis=axis))


def fit_noise_scales(prior: ManifoldPrior, validation, training_starts=None, *, key=None, samples: int = 16, floor: float = 1e-3) -> NoiseScales:
    """Fit the dynamics noise scales of the module docstring.

    Args:
        prior: the manifold prior (fitted on the training sequences).
        validation: one (T, D) pose array or a list of them, T >= 2 each.
        training_starts: first frame of each training sequence in the manifold's training
            data, ending with N (default: one sequence).
        key: PRNG key of the latent draws for ``s_zx`` (default ``jax.random.key(0)``: the
            fit is a deterministic function of the data).
        samples: latent draws per validation frame for ``s_zx``.
    """
    import jax
    sequences = [validation] if isinstance(validation, np.ndarray) and validation.ndim == 2 else list(validation)
    sequences = [np.asarray(s, np.float64) for s in sequences]
    d = prior.pose_dim
    for s in sequences:
        if s.ndim != 2 or s.shape[1] != d or s.shape[0] < 2:
            raise ValueError(f"validation poses must be (T >= 2, {d}) arrays, got {s.shape}")
        if not np.all(np.isfinite(s)):
            raise ValueError("validation poses contain NaN or infinite values")
    g = prior.global_dims
    steps = np.concatenate([np.diff(s, axis=0) for s in sequences])
    s_xx = np.maximum(_rms(steps), floor)
    latent = [np.asarray(prior.encode(_as_jax(s[:, g:], prior)), np.float64) for s in sequences]
    s_xz = np.maximum(_rms(np.concatenate([np.diff(z, axis=0) for z in latent])), floor)
    key = jax.random.key(0) if key is None else key
    residuals = []
    for i, (s, z) in enumerate(zip(sequences, latent)):
        eps = np.asarray(jax.random.normal(jax.random.fold_in(key, i), (samples,) + z[:-1].shape), np.float64)
        draws = (z[:-1][None] + s_xz * eps).reshape(-1, z.shape[1])
        mean = np.asarray(prior.decode(_as_jax(draws, prior)), np.float64).reshape(samples, len(s) - 1, -1)
        residuals.append((s[1:, g:][None] - mean).reshape(-1, mean.shape[-1]))
    s_zx = np.maximum(_rms(np.concatenate(residuals)), floor)
    train = np.asarray(prior.training_latent, np.float64)
    starts = list(training_starts) if training_starts is not None else [0, len(train)]
    train_steps = np.concatenate([np.diff(train[a:b], axis=0) for a, b in zip(starts[:-1], starts[1:]) if b - a >= 2])
    nu = np.maximum(_rms(train_steps), floor)
    return NoiseScales(s_xx=s_xx, s_xz=s_xz, s_zx=s_zx, s_global=s_xx[:g], nu=nu)


def _as_jax(values, prior):
    import jax.numpy as jnp

    return jnp.asarray(values, prior.training_latent.dtype)
