"""Noise scales of the trackers' dynamics, fitted by maximum likelihood on motion data.

000 sec. 5.2 requires ``s_zx`` to be fitted on a validation set separate from the manifold's
training data (on the training set it would be underestimated). Given validation poses
``x_1..x_T`` (one or more sequences):

- ``s_xx`` (000 eq. 29): per pose entry, the RMS of ``x_t - x_{t-1}``;
- ``s_xz`` (000 eq. 27): per latent dimension, the RMS of ``g(x_t) - g(x_{t-1})``;
- ``s_zx`` (000 eq. 30) and ``mrpf_s_xx``, MRPF's own eq. 29 scale of the joint angles: fitted
  jointly by maximising the validation likelihood of MRPF's whole transition model,
  ``p(x_t | x_{t-1}) = E_{z_t ~ N(g(x_{t-1}), diag(s_xz^2))} [p(x_t | x_{t-1}, z_t)]`` with
  ``p(x_t | x_{t-1}, z_t)`` the normalised Gaussian product of eq. 28 (``samples`` latent draws
  per frame, fixed by ``key``; BFGS on the log scales). 000 sec. 5.2 only says the scales are
  fitted on validation data; fitting eq. 30 alone and eq. 29 alone (``s_xx``) counts the motion
  between frames twice, once in each factor of eq. 28, and leaves MRPF a prior that favours
  standing still. Where one factor of eq. 28 explains the step alone the likelihood is flat
  in the other factor's scale, which the optimiser can push towards infinity; ``mrpf_s_xx``
  is clipped at ``10 s_xx`` and ``s_zx`` at ``10 s_zx_residual``;
- ``s_zx_residual``: eq. 30 fitted alone, the RMS of ``x_t - mu(z_t)`` (the start of the joint
  fit, and the scale for 000 Alg. 1 as printed, ``MRPF(proposal="prior")``, with ``s_xx``);
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
    mrpf_s_xx: np.ndarray  # (D,) MRPF's eq. 29 scale: s_xx with the angle entries fitted jointly with s_zx
    s_zx_residual: np.ndarray  # (Da,) eq. 30 fitted alone


def _rms(values, axis=0):
    return np.sqrt(np.mean(np.square(values), axis=axis))


def fit_noise_scales(prior: ManifoldPrior, validation, training_starts=None, *, key=None, samples: int = 64, floor: float = 1e-3) -> NoiseScales:
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
    residuals, manifold_means = [], []
    for i, (s, z) in enumerate(zip(sequences, latent)):
        eps = np.asarray(jax.random.normal(jax.random.fold_in(key, i), (samples,) + z[:-1].shape), np.float64)
        draws = (z[:-1][None] + s_xz * eps).reshape(-1, z.shape[1])
        mean = np.asarray(prior.decode(_as_jax(draws, prior)), np.float64).reshape(samples, len(s) - 1, -1)
        residuals.append((s[1:, g:][None] - mean).reshape(-1, mean.shape[-1]))
        manifold_means.append(mean)
    s_zx_start = np.maximum(_rms(np.concatenate(residuals)), floor)
    pairs = [(s[:-1, g:], s[1:, g:]) for s in sequences]
    s_xx_angles, s_zx = fit_transition_scales(pairs, manifold_means, s_xx[g:], s_zx_start, floor=floor)
    s_xx_angles, s_zx = np.minimum(s_xx_angles, 10 * s_xx[g:]), np.minimum(s_zx, 10 * s_zx_start)
    train = np.asarray(prior.training_latent, np.float64)
    starts = list(training_starts) if training_starts is not None else [0, len(train)]
    train_steps = np.concatenate([np.diff(train[a:b], axis=0) for a, b in zip(starts[:-1], starts[1:]) if b - a >= 2])
    nu = np.maximum(_rms(train_steps), floor)
    mrpf_s_xx = np.concatenate([s_xx[:g], s_xx_angles])
    return NoiseScales(s_xx=s_xx, s_xz=s_xz, s_zx=s_zx, s_global=s_xx[:g], nu=nu, mrpf_s_xx=mrpf_s_xx, s_zx_residual=s_zx_start)


def transition_log_likelihood(previous, current, manifold_means, s_xx, s_zx):
    """Mean log-density of MRPF's transition (000 eq. 28 with the latent draws of eq. 27) at
    observed pose pairs, by Monte Carlo over the latent draws.

    Args:
        previous, current: (T, A) joint angles at t-1 and t.
        manifold_means: (K, T, A) ``mu(z_t^k)`` for K latent draws ``z_t^k ~ p(z_t | x_{t-1})``.
        s_xx, s_zx: (A,) the scales of eqs. 29 and 30.
    Returns:
        scalar: ``1/T sum_t log 1/K sum_k N(x_t | m_k, diag(v))``, where ``N(x_t | m_k, v)`` is
        eq. 28 normalised over ``x_t``: mean ``m_k = (s_zx^2 x_{t-1} + s_xx^2 mu_k) / (s_xx^2 + s_zx^2)``,
        variance ``v = s_xx^2 s_zx^2 / (s_xx^2 + s_zx^2)``.
    """
    import jax.numpy as jnp
    from jax.scipy.special import logsumexp

    var_xx, var_zx = s_xx**2, s_zx**2
    total = var_xx + var_zx
    mean = (var_zx * previous[None] + var_xx * manifold_means) / total
    var = var_xx * var_zx / total
    log_density = -0.5 * jnp.sum((current[None] - mean) ** 2 / var + jnp.log(2 * jnp.pi * var), axis=-1)  # (K, T)
    k = manifold_means.shape[0]
    return jnp.mean(logsumexp(log_density, axis=0) - jnp.log(k))


def fit_transition_scales(pairs, manifold_means, s_xx_start, s_zx_start, *, floor: float = 1e-3, max_steps: int = 500):
    """Maximum-likelihood ``(s_xx, s_zx)`` of MRPF's transition (``transition_log_likelihood``)
    over validation pose pairs, by BFGS on ``log`` scales with a smooth floor
    ``s = sqrt(floor^2 + exp(2 theta))``. Returns two (A,) NumPy arrays."""
    import jax
    import jax.numpy as jnp
    import optimistix as optx

    previous = jnp.concatenate([jnp.asarray(a) for a, _ in pairs])
    current = jnp.concatenate([jnp.asarray(b) for _, b in pairs])
    means = jnp.concatenate([jnp.asarray(m) for m in manifold_means], axis=1)
    dims = previous.shape[1]

    def unpack(theta):
        scales = jnp.sqrt(floor**2 + jnp.exp(2 * theta))
        return scales[:dims], scales[dims:]

    def loss(theta, _):
        return -transition_log_likelihood(previous, current, means, *unpack(theta))

    start = jnp.log(jnp.sqrt(jnp.maximum(jnp.concatenate([jnp.asarray(s_xx_start), jnp.asarray(s_zx_start)]) ** 2 - floor**2, floor**2)))
    solution = optx.minimise(loss, optx.BFGS(rtol=1e-7, atol=1e-7), start.astype(previous.dtype), max_steps=max_steps, throw=False)
    theta = jnp.where(jnp.isfinite(loss(solution.value, None)), solution.value, start)
    s_xx, s_zx = (np.asarray(v, np.float64) for v in unpack(jax.lax.stop_gradient(theta)))
    return s_xx, s_zx


def _as_jax(values, prior):
    import jax.numpy as jnp

    return jnp.asarray(values, prior.training_latent.dtype)
