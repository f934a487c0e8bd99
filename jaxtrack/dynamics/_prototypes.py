"""Motion prototypes (004 sec. 5.1): a Gaussian mixture fitted by EM to points that each carry
their own uncertainty covariance ``C_n``, with the number of components chosen by the
minimum-message-length criterion of Figueiredo and Jain (2002).

Component m sees point n as drawn from ``N(mu_m, Sigma_m + C_n)``: with ``A_mn = Sigma_m + C_n``
the mean is 004 eq. 3, ``mu_m = (sum_n P_nm A_mn^-1)^-1 sum_n P_nm A_mn^-1 x_n``, and the
covariance solves 004 eq. 4, ``sum_n P_nm A_mn^-1 Sigma_m A_mn^-1 = sum_n P_nm A_mn^-1 ((x_n -
mu_m)(x_n - mu_m)^T - C_n) A_mn^-1``, linear in ``Sigma_m`` once ``A_mn`` is held at the last
estimate (a ``d^2 x d^2`` system; a few alternations of the two, as 004 says). With every
``C_n = 0`` both reduce to ordinary EM.

The number of components follows Figueiredo and Jain's component-wise EM (CEM^2): start with
``max_components``, update one component at a time, weights by their MML rule
``w_m ~ max(0, sum_n P_nm - T/2)`` (T: free parameters per component) so that a component
without the support of T/2 points is annihilated; at convergence record the message length,
remove the weakest component and start again, down to ``min_components``; keep the shortest.
Everything runs in fixed-size arrays with an ``alive`` mask, jitted (one compile for every
component count).
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float, PRNGKeyArray


class GaussianMixture(eqx.Module):
    """A mixture of M full-covariance Gaussians in d dimensions.

    Attributes:
        weights: (M,) mixing weights, summing to 1.
        means: (M, d).
        covariances: (M, d, d), symmetric positive definite.
    """

    weights: Float[Array, " m"]
    means: Float[Array, "m d"]
    covariances: Float[Array, "m d d"]

    @property
    def num_components(self) -> int:
        return self.weights.shape[0]

    @property
    def dim(self) -> int:
        return self.means.shape[1]

    def component_log_densities(self, points, uncertainties=None) -> Float[Array, "n m"]:
        """``ln w_m + ln N(x_n; mu_m, Sigma_m + C_n)`` for every point and component."""
        return _joint_log_densities(self.weights, self.means, self.covariances, points, _uncertainties(points, uncertainties))

    def log_likelihood(self, points, uncertainties=None) -> Float[Array, " n"]:
        """``ln sum_m w_m N(x_n; mu_m, Sigma_m + C_n)`` per point."""
        return jax.nn.logsumexp(self.component_log_densities(points, uncertainties), axis=1)

    def responsibilities(self, points, uncertainties=None) -> Float[Array, "n m"]:
        """The expected assignments ``P_nm`` (rows sum to 1)."""
        return jax.nn.softmax(self.component_log_densities(points, uncertainties), axis=1)

    def labels(self, points, uncertainties=None) -> Array:
        """The most probable component of each point, (N,) int."""
        return jnp.argmax(self.component_log_densities(points, uncertainties), axis=1)


@dataclasses.dataclass(frozen=True)
class MixtureFit:
    """What ``fit_uncertain_mixture`` did.

    Attributes:
        mixture: the chosen mixture (components with zero weight removed).
        message_lengths: {component count: message length (nats)} of each converged count.
        log_likelihood: the chosen mixture's ``sum_n ln p(x_n)``.
        iterations: EM sweeps per component count, in the order tried.
    """

    mixture: GaussianMixture
    message_lengths: dict
    log_likelihood: float
    iterations: tuple


def _uncertainties(points, uncertainties):
    if uncertainties is None:
        return jnp.zeros(points.shape + (points.shape[1],), points.dtype)
    return uncertainties


def _gaussian_log_density(x, mean, cov):
    """``ln N(x; mean, cov)`` of one point by Cholesky (a non-positive-definite ``cov`` gives -inf)."""
    d = x.shape[0]
    L = jnp.linalg.cholesky(cov)
    z = jax.scipy.linalg.solve_triangular(L, x - mean, lower=True)
    value = -0.5 * (d * jnp.log(2.0 * jnp.pi) + jnp.sum(z * z)) - jnp.sum(jnp.log(jnp.diag(L)))
    return jnp.where(jnp.isfinite(value), value, -jnp.inf)


def _joint_log_densities(weights, means, covariances, points, uncertainties):
    per_point = jax.vmap(lambda x, c: jax.vmap(lambda mu, s: _gaussian_log_density(x, mu, s + c))(means, covariances))
    log_w = jnp.where(weights > 0, jnp.log(jnp.maximum(weights, 1e-300)), -jnp.inf)
    return per_point(points, uncertainties) + log_w[None, :]


def _component_update(points, uncertainties, resp, mean, cov, floor, inner):
    """Eqs. 3 and 4 of 004 for one component with expected assignments ``resp`` (N,),
    alternated ``inner`` times from ``(mean, cov)``."""
    d = points.shape[1]

    def one(_, carry):
        mean, cov = carry
        a_inv = jax.vmap(lambda c: jnp.linalg.inv(cov + c))(uncertainties)  # (N, d, d)
        a_inv = 0.5 * (a_inv + jnp.swapaxes(a_inv, 1, 2))
        precision = jnp.einsum("n,nij->ij", resp, a_inv)
        mean = jnp.linalg.solve(precision, jnp.einsum("n,nij,nj->i", resp, a_inv, points))
        diff = points - mean
        scatter = diff[:, :, None] * diff[:, None, :] - uncertainties
        rhs = jnp.einsum("n,nij,njk,nkl->il", resp, a_inv, scatter, a_inv)
        # vec(A^-1 S A^-1) = (A^-1 kron A^-1) vec(S) for symmetric A^-1.
        operator = jnp.einsum("n,nik,njl->ijkl", resp, a_inv, a_inv).reshape(d * d, d * d)
        cov = jnp.linalg.solve(operator, rhs.reshape(d * d)).reshape(d, d)
        cov = 0.5 * (cov + cov.T)
        values, vectors = jnp.linalg.eigh(cov)
        cov = (vectors * jnp.maximum(values, floor)) @ vectors.T
        return mean, 0.5 * (cov + cov.T)

    return jax.lax.fori_loop(0, inner, one, (mean, cov))


def _parameters_per_component(d: int) -> int:
    return d + d * (d + 1) // 2


def _message_length(weights, total_log_likelihood, num_points, d):
    """Figueiredo-Jain's message length (their eq. 15), nats."""
    T = _parameters_per_component(d)
    alive = weights > 0
    k = jnp.sum(alive)
    n = num_points
    weight_terms = jnp.sum(jnp.where(alive, jnp.log(jnp.maximum(n * weights / 12.0, 1e-300)), 0.0))
    return 0.5 * T * weight_terms + 0.5 * k * jnp.log(n / 12.0) + 0.5 * k * (T + 1) - total_log_likelihood


@eqx.filter_jit
def _run_em(weights, means, covariances, points, uncertainties, floor, tolerance, max_sweeps, mml: bool, inner: int):
    """EM sweeps from the given mixture until the relative change of the objective (the message
    length, or the negative log-likelihood without ``mml``) is under ``tolerance``.

    Component-wise (CEM^2): each component's weight, mean and covariance are updated in turn, on
    responsibilities recomputed with the components updated before it. Returns the mixture,
    the objective and the sweeps made."""
    n, d = points.shape
    T = _parameters_per_component(d)
    M = weights.shape[0]

    def total_ll(w, mu, s):
        return jnp.sum(jax.nn.logsumexp(_joint_log_densities(w, mu, s, points, uncertainties), axis=1))

    def objective(w, mu, s):
        ll = total_ll(w, mu, s)
        return _message_length(w, ll, n, d) if mml else -ll

    def update_component(m, carry):
        w, mu, s = carry
        resp = jax.nn.softmax(_joint_log_densities(w, mu, s, points, uncertainties), axis=1)
        resp = jnp.where(jnp.isfinite(resp), resp, 0.0)
        support = jnp.sum(resp[:, m])
        if mml:
            others = jnp.sum(jnp.maximum(jnp.sum(resp, axis=0) - T / 2.0, 0.0) * (jnp.arange(M) != m) * (w > 0))
            new_m = jnp.maximum(support - T / 2.0, 0.0)
            w_m = jnp.where(w[m] > 0, new_m / jnp.maximum(new_m + others, 1e-300), 0.0)
        else:
            w_m = jnp.where(w[m] > 0, support / n, 0.0)
        w = w.at[m].set(w_m)
        w = w / jnp.maximum(jnp.sum(w), 1e-300)
        mean_m, cov_m = _component_update(points, uncertainties, resp[:, m], mu[m], s[m], floor, inner)
        keep = (w_m > 0) & (support > 1e-8) & jnp.all(jnp.isfinite(mean_m)) & jnp.all(jnp.isfinite(cov_m))
        mu = mu.at[m].set(jnp.where(keep, mean_m, mu[m]))
        s = s.at[m].set(jnp.where(keep, cov_m, s[m]))
        w = jnp.where((jnp.arange(M) == m) & ~keep, 0.0, w)
        w = w / jnp.maximum(jnp.sum(w), 1e-300)
        return w, mu, s

    def cond(carry):
        _, _, _, previous, current, sweep = carry
        change = jnp.abs(previous - current) / jnp.maximum(jnp.abs(current), 1.0)
        return (sweep < max_sweeps) & ((sweep < 2) | (change > tolerance))

    def body(carry):
        w, mu, s, _, current, sweep = carry
        w, mu, s = jax.lax.fori_loop(0, M, update_component, (w, mu, s))
        return w, mu, s, current, objective(w, mu, s), sweep + 1

    start = objective(weights, means, covariances)
    w, mu, s, _, value, sweeps = jax.lax.while_loop(cond, body, (weights, means, covariances, start, start, 0))
    return w, mu, s, value, sweeps, total_ll(w, mu, s)


def check_points(points, uncertainties) -> tuple[np.ndarray, np.ndarray]:
    """Validated float64 ``(N, d)`` points and ``(N, d, d)`` uncertainties (zeros if None)."""
    points = np.asarray(points, np.float64)
    if points.ndim != 2 or points.shape[0] < 2 or points.shape[1] < 1:
        raise ValueError(f"points must be (N >= 2, d >= 1), got shape {points.shape}")
    if not np.all(np.isfinite(points)):
        raise ValueError("points contain NaN or infinite values")
    n, d = points.shape
    if uncertainties is None:
        return points, np.zeros((n, d, d))
    uncertainties = np.asarray(uncertainties, np.float64)
    if uncertainties.shape != (n, d, d):
        raise ValueError(f"uncertainties must be ({n}, {d}, {d}), one covariance per point, got {uncertainties.shape}")
    if not np.all(np.isfinite(uncertainties)):
        raise ValueError("uncertainties contain NaN or infinite values")
    sym = 0.5 * (uncertainties + np.swapaxes(uncertainties, 1, 2))
    if np.min(np.linalg.eigvalsh(sym)) < -1e-9 * max(1.0, float(np.max(np.abs(sym)))):
        raise ValueError("every uncertainty must be a positive semi-definite covariance")
    return points, sym


def initial_mixture(key: PRNGKeyArray, points, num_components: int, *, spread: float = 0.1) -> GaussianMixture:
    """``num_components`` equal-weight Gaussians centred on distinct random points, each with
    the isotropic covariance ``spread`` times the data's mean variance (Figueiredo-Jain's start)."""
    points = jnp.asarray(points)
    n, d = points.shape
    if not 1 <= num_components <= n:
        raise ValueError(f"num_components must be between 1 and the {n} points, got {num_components}")
    chosen = jax.random.choice(key, n, (num_components,), replace=False)
    variance = jnp.mean(jnp.var(points, axis=0)) * spread
    covariances = jnp.broadcast_to(variance * jnp.eye(d, dtype=points.dtype), (num_components, d, d))
    return GaussianMixture(jnp.full(num_components, 1.0 / num_components, points.dtype), points[chosen], covariances)


def fit_uncertain_mixture(
    points, uncertainties=None, *, key: PRNGKeyArray, max_components: int = 20, min_components: int = 1,
    select: bool = True, initial: GaussianMixture | None = None, tolerance: float = 1e-5, max_sweeps: int = 300,
    inner: int = 3, floor: float | None = None,
) -> MixtureFit:
    """Fit the motion prototypes (module docstring).

    Args:
        points: (N, d) points, e.g. augmented latent points ``[x, x_dot]``.
        uncertainties: (N, d, d) each point's covariance ``C_n`` (None: zeros, ordinary EM).
        key: draws the initial means (unless ``initial`` is given).
        max_components, min_components: the range of component counts searched.
        select: True: Figueiredo-Jain's MML search over the counts; False: plain maximum
            likelihood EM with ``max_components`` fixed (components without support still die).
        initial: a starting mixture (its size replaces ``max_components``).
        tolerance: relative change of the objective that ends a run of sweeps.
        max_sweeps: cap on the sweeps per component count.
        inner: alternations of eqs. 3 and 4 per component update.
        floor: smallest covariance eigenvalue (None: 1e-6 times the data's mean variance).

    Returns:
        A ``MixtureFit``.

    Raises:
        ValueError: on bad shapes, non-finite values, uncertainties that are not covariances, or
            component counts outside ``1 <= min <= max <= N``.
    """
    points, uncertainties = check_points(points, uncertainties)
    n, d = points.shape
    if initial is not None:
        max_components = initial.num_components
    if not 1 <= min_components <= max_components <= n:
        raise ValueError(f"need 1 <= min_components ({min_components}) <= max_components ({max_components}) <= points ({n})")
    floor = float(np.mean(np.var(points, axis=0)) * 1e-6 + 1e-12) if floor is None else float(floor)
    x, c = jnp.asarray(points), jnp.asarray(uncertainties)
    mixture = initial_mixture(key, x, max_components) if initial is None else jax.tree.map(lambda a: jnp.asarray(a, x.dtype), initial)
    w, mu, s = mixture.weights, mixture.means, mixture.covariances
    lengths, sweeps_made, best = {}, [], None
    while True:
        w, mu, s, value, sweeps, ll = _run_em(w, mu, s, x, c, floor, tolerance, max_sweeps, select, inner)
        sweeps_made.append(int(sweeps))
        alive = np.asarray(w) > 0
        k = int(alive.sum())
        if k == 0:
            break
        if select:
            lengths[k] = float(value)
        if best is None or (select and float(value) < best[0]):
            best = (float(value), (w, mu, s), float(ll))
        if not select or k <= min_components:
            break
        weakest = int(np.argmin(np.where(alive, np.asarray(w), np.inf)))  # annihilate it and refit
        w = w.at[weakest].set(0.0)
        w = w / jnp.sum(w)
    if best is None:
        raise ValueError("every mixture component lost its support: too few points for a component "
                         f"({_parameters_per_component(d) // 2 + 1} or more are needed for d = {d})")
    w, mu, s = best[1]
    alive = np.asarray(w) > 0
    chosen = GaussianMixture(w[alive] / jnp.sum(w[alive]), mu[alive], s[alive])
    return MixtureFit(chosen, lengths, best[2], tuple(sweeps_made))
