"""The transition of the manifold regularised particle filter (000 eqs. 27-30) and its fitting.

``z_t ~ N(g(x_{t-1}), diag(s_xz^2))`` (eq. 27, g the back-constraint) and
``p(x_t | x_{t-1}, z_t) ∝ N(x_t | x_{t-1}, diag(s_xx^2)) N(x_t^a | mu(z_t), diag(s_zx^2))``
(eq. 28; ``x^a`` the joint angles the manifold covers; the global entries follow eq. 29 only).

Fitting (000 sec. 5.2: on a validation set separate from the manifold's training data):

- ``s_xx`` (eq. 29): the RMS frame-to-frame step per pose entry;
- ``s_xz`` (eq. 27): the RMS step of ``g(x_t)`` per latent dimension;
- ``s_zx`` (eq. 30) and the joint-angle entries of ``s_xx``, for the exact ("product") draw:
  fitted jointly by maximising the validation likelihood of the whole transition,
  ``p(x_t | x_{t-1}) = E_{z_t} [p(x_t | x_{t-1}, z_t)]`` with ``p(x_t | x_{t-1}, z_t)`` eq. 28
  normalised over ``x_t`` (``samples`` latent draws per frame fixed by ``key``; BFGS on the log
  scales). Fitting eq. 30 alone and eq. 29 alone counts the motion between frames twice, once in
  each factor, and leaves a prior that favours standing still. Where one factor explains the step
  alone the likelihood is flat in the other factor's scale, which the optimiser can push towards
  infinity; the fitted scales are clipped at 10 times their separate fits.
- for 000 Alg. 1 as printed ("prior"): ``s_zx`` fitted alone, the RMS of ``x_t - mu(z_t)``,
  with the eq. 29 ``s_xx``.

Weighting the manifold (``manifold_weight`` lambda): eq. 28 is a product of two experts that
000 sec. 5.2 calls "hard to compare quantitatively". The fit above is the best *one-step*
density, but a filter of a few hundred particles does not carry that density's posterior: where
the silhouettes hold a limb loosely, resampling collapses the particles onto a few ancestors,
whose weakly pulled limbs wander together, and the estimate wanders with them. Raising eq. 30's
factor to the power lambda (its scales over ``sqrt(lambda)``) trades model fit for Monte Carlo
error. The experiment's MRPF takes lambda = 4, chosen by tracking the validation takes (docs/trackers.md,
"Weighting MRPF's manifold").

With ``tied`` groups of joint angles (``body.mirrored_groups``: a left angle and its right
mirror) each group shares its two scales, fitted on the group's entries together: one
validation take's left and right limbs estimate one pull between them, where per angle one
limb's idiosyncrasy in that take sets its pull alone (the experiment's default).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jax.scipy.special import logsumexp

from .._custom_types import Array, ArrayLike, Float, PRNGKeyArray
from ..manifold import ManifoldPrior
from ._base import (
    AbstractRefinableDynamics,
    check_scale_vector,
    copies,
    gaussian_log_density,
    gaussian_step,
    motion_sequences,
    rms_step,
)
from ._latent_noise import JUMP_STREAM, LatentNoiseMixture, check_latent_noise_fit, fit_latent_noise, gpdm_noise

LATENT_STREAM = 7919  # fold_in tag of the latent noise, so the pose noise uses the key as SIR does
MRPF_PROPOSALS = ("product", "prior")
MRPF_LATENT_PROPOSALS = ("back-constraint", "gpdm")


class ManifoldRegularisedTransition(AbstractRefinableDynamics):
    """MRPF's transition (module docstring); the state is the pose.

    ``proposal`` picks how ``x_t`` is drawn after ``z_t``:

    - ``"product"`` (default): exactly from eq. 28 normalised over x_t, a Gaussian with mean
      ``(s_zx^2 x_{t-1} + s_xx^2 mu(z_t)) / (s_xx^2 + s_zx^2)`` and variance
      ``s_xx^2 s_zx^2 / (s_xx^2 + s_zx^2)``; the weight of eq. 7 is then 1 and eq. 11 leaves the
      image likelihood. The paper calls this draw intractable in general (000 sec. 3); with the
      Gaussian models of sec. 5.2 it is not.
    - ``"prior"`` (000 Alg. 1 as printed): ``x_t ~ N(x_{t-1}, diag(s_xx^2))`` (eq. 29), log weight
      ``ln N(x_t^a | mu(z_t), diag(s_zx^2))`` up to a constant (eq. 30). Eq. 30 drops eq. 28's
      normaliser ``N(x_{t-1}^a | mu(z_t), diag(s_xx^2 + s_zx^2))``, which depends on the
      particle: it rewards latent draws whose mean stays near the previous pose.

    With ``s_zx`` very large both reduce to ``PoseRandomWalk(s_xx)``. ``perturb`` is the eq. 29
    random walk with ``s_xx`` scaled.

    ``latent_proposal`` picks where ``z_t`` comes from:

    - ``"back-constraint"`` (000 eq. 27): ``z_t ~ N(g(x_{t-1}), diag(s_xz^2))``, on a BC-GPLVM;
    - ``"gpdm"`` (the latent proposal issue #13 asks for, on 001's GPDM): ``z_t`` follows the
      GPDM's predictive dynamics from the particle's own previous latent draw,
      ``z_t ~ N(mu_X(z_{t-1}), sigma_X^2(z_{t-1}) I)`` (001 eqs. 7-9), so the latent point
      advances along the learned cycle and carries the gait phase the pose alone leaves
      ambiguous; ``s_xz`` is then unused (kept for the shape checks; the fit sets it to the
      RMS predictive sd). The latent noise is ``sigma_X`` times ``latent_noise``: the GPDM's
      own (default), or a scale mixture refitted on the validation motion (``_latent_noise``).

    The particle state is ``[x_t (D), z_t (q)]``: the pose and the latent draw it was made with
    (the next draw depends on ``x_t`` alone, eq. 27), so that the transition has a density,
    ``p(z_t | x_{t-1}) p(x_t | x_{t-1}, z_t)``, for gradient-refined moves.

    Attributes:
        manifold: a manifold with a back-constraint (BC-GPLVM).
        s_xx: (D,) eq. 29 scales; s_xz: (q,) eq. 27 scales; s_zx: (Da,) eq. 30 scales.
        latent_noise: the GPDM proposal's noise relative to ``sigma_X`` (default the GPDM's own).
    """

    manifold: ManifoldPrior
    s_xx: Float[Array, " dofs"]
    s_xz: Float[Array, " q"]
    s_zx: Float[Array, " a"]
    proposal: str = eqx.field(static=True, default="product")
    latent_proposal: str = eqx.field(static=True, default="back-constraint")
    latent_noise: LatentNoiseMixture = eqx.field(default_factory=gpdm_noise)

    def __check_init__(self):
        if self.proposal not in MRPF_PROPOSALS:
            raise ValueError(f"proposal must be one of {MRPF_PROPOSALS}, got {self.proposal!r}")
        check_latent_proposal(self.manifold, self.latent_proposal)
        check_scale_vector("s_xx", self.s_xx, self.manifold.pose_dim)
        check_scale_vector("s_xz", self.s_xz, self.manifold.latent_dim)
        check_scale_vector("s_zx", self.s_zx, self.manifold.pose_dim - self.manifold.global_dims)

    def init(self, key, pose, num_particles):
        del key  # the pose and its back-constrained latent point
        pose = pose.astype(self.s_xx.dtype)
        latent = self.manifold.encode(pose[None, self.manifold.global_dims :])[0]
        return copies(jnp.concatenate([pose, latent]), num_particles)

    def to_pose(self, states):
        return states[:, : self.manifold.pose_dim]

    def _product(self, previous, manifold_mean):
        """Mean (N, D) and standard deviation (D,) of eq. 28 normalised over x_t."""
        g = self.manifold.global_dims
        s_xx = self.s_xx[g:]
        pull = 1.0 / (1.0 + (self.s_zx / s_xx) ** 2)  # s_xx^2 / (s_xx^2 + s_zx^2), finite for any s_zx (inf: 0)
        angles = previous[:, g:] + pull * (manifold_mean - previous[:, g:])
        return jnp.concatenate([previous[:, :g], angles], axis=1), jnp.concatenate([self.s_xx[:g], s_xx * jnp.sqrt(1.0 - pull)])

    def _latent_prior(self, previous):
        """Mean (N, q) and standard deviation ((q,) or (N, 1)) of ``p(z_t | state_{t-1})``."""
        d = self.manifold.pose_dim
        if self.latent_proposal == "gpdm":
            mean, variance = self.manifold.predict_latent(previous[:, d:])
            return mean, jnp.sqrt(variance)[:, None]
        return self.manifold.encode(previous[:, self.manifold.global_dims : d]), self.s_xz

    def _draw_latent(self, key, previous):
        mean, sd = self._latent_prior(previous)
        if self.latent_proposal == "gpdm":  # the fitted noise's factor per particle
            sd = sd * self.latent_noise.factors(jax.random.fold_in(key, JUMP_STREAM), mean.shape[0], mean.dtype)[:, None]
        return gaussian_step(key, mean, sd)

    def propose(self, key, previous):
        g = self.manifold.global_dims
        latent = self._draw_latent(jax.random.fold_in(key, LATENT_STREAM), previous)
        previous = self.to_pose(previous)
        manifold_mean = self.manifold.decode_mean(latent)
        if self.proposal == "prior":
            particles = gaussian_step(key, previous, self.s_xx)
            correction = gaussian_log_density(particles[:, g:], manifold_mean, self.s_zx)
        else:
            particles = gaussian_step(key, *self._product(previous, manifold_mean))
            correction = jnp.zeros(previous.shape[0], previous.dtype)
        return jnp.concatenate([particles, latent], axis=1), correction

    def velocity_states(self, poses):
        # Eq. 27's draw carries no phase: the whole pose, each step's shift pulled back onto the
        # manifold (eq. 28), so a velocity of the joint angles predicts the limbs without leaving
        # the learned poses. The GPDM's draw advances the limbs itself: the root alone.
        if self.latent_proposal == "gpdm":
            return super().velocity_states(poses)
        return poses

    def perturb(self, key, states, factor):
        d = self.manifold.pose_dim
        return jnp.concatenate([gaussian_step(key, states[:, :d], self.s_xx * factor), states[:, d:]], axis=1)

    def log_transition(self, previous, states):
        g, d = self.manifold.global_dims, self.manifold.pose_dim
        before, pose, latent = previous[:, :d], states[:, :d], states[:, d:]
        latent_mean, latent_sd = self._latent_prior(previous)
        if self.latent_proposal == "gpdm":  # a per-particle variance: its normaliser depends on the particle
            log_latent = self.latent_noise.log_density(latent - latent_mean, latent_sd[:, 0])
        else:
            log_latent = gaussian_log_density(latent, latent_mean, latent_sd)  # eq. 27
        manifold_mean = self.manifold.decode_mean(latent)
        if self.proposal == "prior":  # eq. 29 times eq. 30, as Alg. 1 weighs it
            return log_latent + gaussian_log_density(pose, before, self.s_xx) + gaussian_log_density(pose[:, g:], manifold_mean, self.s_zx)
        return log_latent + gaussian_log_density(pose, *self._product(before, manifold_mean))  # eq. 28, normalised over x_t

    def noise_scales(self):
        return jnp.concatenate([self.s_xx, self.s_xz])


def check_latent_proposal(manifold: ManifoldPrior, latent_proposal: str) -> None:
    """Raise ``ValueError`` unless ``manifold`` supports MRPF's ``latent_proposal``."""
    if latent_proposal not in MRPF_LATENT_PROPOSALS:
        raise ValueError(f"latent_proposal must be one of {MRPF_LATENT_PROPOSALS}, got {latent_proposal!r}")
    if latent_proposal == "back-constraint" and not manifold.has_back_constraint:
        raise ValueError("MRPF's eq. 27 proposal needs a back-constrained manifold (BC-GPLVM); on a GPDM use "
                         "latent_proposal='gpdm'")
    if latent_proposal == "gpdm" and manifold.latent_dynamics is None:
        raise ValueError("MRPF's GPDM latent proposal needs a manifold with latent dynamics (a GPDM)")


def fit_mrpf_transition(
    manifold: ManifoldPrior, validation, *, key: PRNGKeyArray, proposal: str = "product",
    latent_proposal: str = "back-constraint", samples: int = 64, floor: float = 1e-3, latent_noise: str = "gpdm",
    tied: ArrayLike | None = None, manifold_weight: float = 1.0,
) -> ManifoldRegularisedTransition:
    """Fit MRPF's scales on validation motion (module docstring).

    Args:
        manifold: a back-constrained manifold prior (fitted on the training sequences).
        validation: one (T, D) pose array or a list of them, T >= 2 each.
        key: PRNG key of the latent draws of the Monte-Carlo transition likelihood (the fit is
            a deterministic function of the data and the key).
        proposal: "product" (joint maximum-likelihood fit) or "prior" (separate fits).
        latent_proposal: "back-constraint" (eq. 27, BC-GPLVM) or "gpdm" (the GPDM's predictive
            dynamics; the validation latent draws start from each frame's encoded pose).
        samples: latent draws per validation frame.
        floor: smallest scale, so that no entry is deterministic.
        latent_noise: the GPDM proposal's noise: "gpdm" (its own predictive variance) or
            "validation" (the scale mixture fitted on the validation motion, ``_latent_noise``).
        tied: (A,) integer group of each joint angle (the pose after its global entries);
            angles of one group share ``s_xx`` and ``s_zx`` (module docstring), e.g.
            ``body.mirrored_groups(skeleton.dof_names[3:])``. None: each angle its own.
        manifold_weight: the power ``lambda`` of eq. 30's factor in eq. 28 after the fit,
            ``p(x_t | x_{t-1}) p(x_t | z_t)^lambda``: the fitted ``s_zx`` divided by
            ``sqrt(lambda)`` (module docstring, "Weighting the manifold"). 1: the fit as it is.

    Returns:
        the fitted ``ManifoldRegularisedTransition`` (in the manifold's dtype).
    """
    if proposal not in MRPF_PROPOSALS:
        raise ValueError(f"proposal must be one of {MRPF_PROPOSALS}, got {proposal!r}")
    check_latent_proposal(manifold, latent_proposal)
    check_latent_noise_fit(latent_noise)
    if not (np.isfinite(manifold_weight) and manifold_weight > 0):
        raise ValueError(f"manifold_weight must be positive and finite, got {manifold_weight!r}")
    sequences = motion_sequences(validation, manifold.pose_dim)
    g = manifold.global_dims
    groups = check_groups(tied, manifold.pose_dim - g)
    dtype = manifold.training_latent.dtype
    s_xx = rms_step(sequences, floor)
    latent = [np.asarray(manifold.encode(jnp.asarray(s[:, g:], dtype)), np.float64) for s in sequences]
    noise = gpdm_noise()
    if latent_proposal == "gpdm":
        if latent_noise == "validation":
            noise = fit_latent_noise(manifold, sequences)
        predicted = [manifold.predict_latent(jnp.asarray(z[:-1], dtype)) for z in latent]
        centres = [np.asarray(mean, np.float64) for mean, _ in predicted]
        spreads = [np.sqrt(np.asarray(variance, np.float64))[:, None] for _, variance in predicted]
        s_xz = np.full(manifold.latent_dim, np.sqrt(np.mean(np.square(np.concatenate(spreads)))))
    else:
        s_xz = rms_step(latent, floor)
        centres, spreads = [z[:-1] for z in latent], None
    residuals, manifold_means = [], []
    for i, (s, z, centre) in enumerate(zip(sequences, latent, centres)):
        draw_key = jax.random.fold_in(key, i)
        eps = np.asarray(jax.random.normal(draw_key, (samples,) + z[:-1].shape), np.float64)
        if spreads is None:  # eq. 27
            spread = s_xz
        else:  # the GPDM's predictive draw, times the fitted noise's factor per draw
            factors = noise.factors(jax.random.fold_in(draw_key, JUMP_STREAM), samples * (len(z) - 1), jnp.float32)
            spread = spreads[i][None] * np.asarray(factors, np.float64).reshape(samples, len(z) - 1, 1)
        draws = (centre[None] + spread * eps).reshape(-1, z.shape[1])
        mean = np.asarray(manifold.decode_mean(jnp.asarray(draws, dtype)), np.float64).reshape(samples, len(s) - 1, -1)
        residuals.append((s[1:, g:][None] - mean).reshape(-1, mean.shape[-1]))
        manifold_means.append(mean)
    s_zx_alone = np.maximum(np.sqrt(np.mean(np.square(np.concatenate(residuals)), axis=0)), floor)
    if tied is not None:
        s_zx_alone, s_xx = pooled_rms(s_zx_alone, groups), np.concatenate([s_xx[:g], pooled_rms(s_xx[g:], groups)])
    if proposal == "product":
        pairs = [(s[:-1, g:], s[1:, g:]) for s in sequences]
        s_xx_angles, s_zx = fit_transition_scales(pairs, manifold_means, s_xx[g:], s_zx_alone, floor=floor, groups=groups)
        s_xx = np.concatenate([s_xx[:g], np.minimum(s_xx_angles, 10 * s_xx[g:])])
        s_zx = np.minimum(s_zx, 10 * s_zx_alone)
    else:
        s_zx = s_zx_alone
    s_zx = np.maximum(s_zx / np.sqrt(manifold_weight), floor)
    return ManifoldRegularisedTransition(
        manifold=manifold, s_xx=jnp.asarray(s_xx, dtype), s_xz=jnp.asarray(s_xz, dtype), s_zx=jnp.asarray(s_zx, dtype),
        proposal=proposal, latent_proposal=latent_proposal, latent_noise=noise,
    )


def check_groups(tied, angles: int) -> np.ndarray:
    """``tied`` as (angles,) group ids 0..G-1, every id used (the identity when None); raises
    ``ValueError`` otherwise."""
    if tied is None:
        return np.arange(angles)
    groups = np.asarray(tied)
    if groups.shape != (angles,) or not np.issubdtype(groups.dtype, np.integer):
        raise ValueError(f"tied must be {angles} integer group ids, one per joint angle, got {groups.dtype} shape {groups.shape}")
    if groups.min(initial=0) < 0 or set(groups.tolist()) != set(range(int(groups.max(initial=-1)) + 1)):
        raise ValueError(f"tied must number its groups 0..G-1 with none skipped, got {sorted(set(groups.tolist()))}")
    return groups


def pooled_rms(scales, groups: np.ndarray) -> np.ndarray:
    """Each entry replaced by the RMS of ``scales`` over its group."""
    scales = np.asarray(scales, np.float64)
    totals = np.bincount(groups, weights=scales**2) / np.bincount(groups)
    return np.sqrt(totals[groups])


def transition_log_likelihood(
    previous: Float[ArrayLike, "t a"], current: Float[ArrayLike, "t a"], manifold_means: Float[ArrayLike, "k t a"],
    s_xx: Float[ArrayLike, " a"], s_zx: Float[ArrayLike, " a"],
) -> Float[Array, ""]:
    """Mean log-density of MRPF's transition (000 eq. 28 with the latent draws of eq. 27) at
    observed joint-angle pairs, by Monte Carlo over K latent draws ``z_t^k ~ p(z_t | x_{t-1})``
    (``manifold_means`` holds ``mu(z_t^k)``):
    ``1/T sum_t ln 1/K sum_k N(x_t | m_k, diag(v))`` with eq. 28 normalised over ``x_t``, mean
    ``m_k = (s_zx^2 x_{t-1} + s_xx^2 mu_k) / (s_xx^2 + s_zx^2)``, variance
    ``v = s_xx^2 s_zx^2 / (s_xx^2 + s_zx^2)``."""
    var_xx, var_zx = s_xx**2, s_zx**2
    total = var_xx + var_zx
    mean = (var_zx * previous[None] + var_xx * manifold_means) / total
    var = var_xx * var_zx / total
    log_density = -0.5 * jnp.sum((current[None] - mean) ** 2 / var + jnp.log(2 * jnp.pi * var), axis=-1)  # (K, T)
    k = manifold_means.shape[0]
    return jnp.mean(logsumexp(log_density, axis=0) - jnp.log(k))


def fit_transition_scales(pairs, manifold_means, s_xx_start, s_zx_start, *, floor: float = 1e-3, max_steps: int = 500,
                          groups=None):
    """Maximum-likelihood ``(s_xx, s_zx)`` of MRPF's transition (``transition_log_likelihood``)
    over pose pairs ``[(previous (T, A), current (T, A)), ...]`` with ``manifold_means``
    ``[(K, T, A), ...]``, by BFGS on log scales with a smooth floor
    ``s = sqrt(floor^2 + exp(2 theta))``; with ``groups`` ((A,) ids 0..G-1) one pair of scales
    per group (started at the group's first entry). Returns two (A,) float64 NumPy arrays."""
    previous = jnp.concatenate([jnp.asarray(a) for a, _ in pairs])
    current = jnp.concatenate([jnp.asarray(b) for _, b in pairs])
    means = jnp.concatenate([jnp.asarray(m) for m in manifold_means], axis=1)
    dims = previous.shape[1]
    groups = np.arange(dims) if groups is None else np.asarray(groups)
    count = int(groups.max()) + 1

    def unpack(theta):
        scales = jnp.sqrt(floor**2 + jnp.exp(2 * theta))
        return scales[:count][groups], scales[count:][groups]

    def loss(theta, _):
        return -transition_log_likelihood(previous, current, means, *unpack(theta))

    first = np.array([np.flatnonzero(groups == k)[0] for k in range(count)])
    start_scales = jnp.concatenate([jnp.asarray(s_xx_start)[first], jnp.asarray(s_zx_start)[first]])
    start = jnp.log(jnp.sqrt(jnp.maximum(start_scales**2 - floor**2, floor**2)))
    solution = optx.minimise(loss, optx.BFGS(rtol=1e-7, atol=1e-7), start.astype(previous.dtype), max_steps=max_steps, throw=False)
    theta = jnp.where(jnp.isfinite(loss(solution.value, None)), solution.value, start)
    s_xx, s_zx = (np.asarray(v, np.float64) for v in unpack(jax.lax.stop_gradient(theta)))
    return s_xx, s_zx
