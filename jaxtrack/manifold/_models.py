"""Pose manifolds: PCA, GPLVM, back-constrained GPLVM and GPDM, each an equinox Module with a
pure objective differentiated by autodiff (docs/papers.md).

- GPLVM (000 eqs. 13-16): maximise ``ln p(Y|Z) - 1/2 ||Z||_F^2`` over latent points Z and the
  kernel hyperparameters.
- BC-GPLVM (000 eqs. 21-22): ``Z = g(Y)``, ``g_i(y) = sum_t a_ti k_x(y, y_t) + b_i`` with
  ``k_x = exp(-gamma_x/2 ||y - y'||^2)``; the weights ``a, b`` are optimised instead of Z.
- GPDM (001 eqs. 5-11): the GPLVM likelihood with per-dimension scales ``W`` plus a GP on the
  latent dynamics ``x_t -> x_{t+1}`` (linear + RBF kernel) within each training sequence, and
  the ``prod 1/theta`` priors on the hyperparameters.

Training data are centred (and scaled per dimension to unit variance when ``scale=True``).
"""

from __future__ import annotations

import itertools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ._kernels import (
    LinearRBFKernel,
    RBFBiasKernel,
    gaussian_log_marginal,
    linear_rbf_kernel,
    rbf_bias_kernel,
    safe_cholesky,
    squared_distances,
)
from ._predictor import GPPredictor, full_gp_predictor
from ._serialise import AbstractSaveableManifold, register_manifold
from ._spectral import fit_spectral

MAX_TRAINING_MAGNITUDE = 1e6  # no joint angle (radians) or position (metres) comes near; squares of it stay finite


def check_training_data(Y, latent_dim: int, name: str = "training poses") -> np.ndarray:
    """Validate (N, D) training data for a latent dimension; raises ``ValueError`` clearly."""
    Y = np.asarray(Y, np.float64)
    if Y.ndim != 2:
        raise ValueError(f"{name} must be (frames, dims), got shape {Y.shape}")
    n, d = Y.shape
    if not np.all(np.isfinite(Y)):
        bad = np.argwhere(~np.isfinite(Y))[0]
        raise ValueError(f"{name} contain a non-finite value at frame {bad[0]}, dimension {bad[1]}")
    if Y.size and np.abs(Y).max() > MAX_TRAINING_MAGNITUDE:
        bad = np.unravel_index(np.argmax(np.abs(Y)), Y.shape)
        raise ValueError(f"{name} hold {Y[bad]:g} at frame {bad[0]}, dimension {bad[1]}: beyond "
                         f"{MAX_TRAINING_MAGNITUDE:g} (joint angles in radians, positions in metres), so not a pose")
    if latent_dim < 1:
        raise ValueError(f"latent_dim must be at least 1, got {latent_dim}")
    if latent_dim > d:
        raise ValueError(f"latent_dim {latent_dim} is larger than the data dimension {d}")
    if n <= latent_dim + 1:
        raise ValueError(f"{n} frames are too few for a {latent_dim}-D latent space (need more than {latent_dim + 1})")
    varying = np.ptp(Y, axis=0) > 0
    if not varying.any():
        raise ValueError(f"{name} are constant: every dimension has zero variance")
    return Y


def standardise(Y: np.ndarray, scale: bool):
    """Centre (and optionally scale per dimension) data; constant dimensions keep scale 1."""
    mean = Y.mean(axis=0)
    std = Y.std(axis=0)
    std = np.where(std > 1e-12, std, 1.0) if scale else np.ones_like(std)
    return (Y - mean) / std, mean, std


def pca(Y: Float[Array, "n d"], latent_dim: int) -> tuple[Float[Array, "n q"], Float[Array, "q d"]]:
    """Principal components of centred data: scores (n, q) and components (q, d)."""
    U, S, Vt = jnp.linalg.svd(Y - Y.mean(axis=0), full_matrices=False)
    # Deterministic signs: the largest entry of each component is positive.
    signs = jnp.sign(Vt[:latent_dim][jnp.arange(latent_dim), jnp.argmax(jnp.abs(Vt[:latent_dim]), axis=1)])
    return U[:, :latent_dim] * S[:latent_dim] * signs, Vt[:latent_dim] * signs[:, None]


def map_objective(kernel: RBFBiasKernel, Z: Float[Array, "n q"], Y: Float[Array, "n d"]) -> Float[Array, ""]:
    """``ln p(Y|Z) - 1/2 ||Z||_F^2`` (000 eqs. 15-16), shared by the GPLVM and the BC-GPLVM."""
    return gaussian_log_marginal(kernel.gram(Z), Y) - 0.5 * jnp.sum(Z * Z)


class PCAModel(eqx.Module):
    """Linear baseline: ``y = mean + scale * (z @ components)``."""

    components: Float[Array, "q d"]
    mean: Float[Array, " d"]
    scale: Float[Array, " d"]

    def encode(self, Y):
        return ((Y - self.mean) / self.scale) @ self.components.T

    def decode(self, Z):
        return self.mean + self.scale * (Z @ self.components)


def fit_pca(Y, latent_dim: int, *, scale: bool = False) -> PCAModel:
    """A fitted ``PCAModel`` (closed form)."""
    Y = check_training_data(Y, latent_dim)
    Yn, mean, std = standardise(Y, scale)
    _, components = pca(jnp.asarray(Yn), latent_dim)
    return PCAModel(components=components, mean=jnp.asarray(mean), scale=jnp.asarray(std))


def _initial_latent(Yn, latent_dim):
    scores, _ = pca(jnp.asarray(Yn), latent_dim)
    return scores / jnp.std(scores[:, 0])  # unit scale, matching the ||Z||^2 / 2 prior


@register_manifold
class GPLVM(AbstractSaveableManifold):
    """GPLVM with RBF + bias kernel (000 eqs. 13-16).

    Attributes:
        latent: (N, q) latent points Z.
        kernel: kernel and noise hyperparameters.
        data: (N, D) standardised training data (fixed during fitting).
        mean, scale: (D,) the standardisation, to map predictions back to poses.
    """

    latent: Float[Array, "n q"]
    kernel: RBFBiasKernel
    data: Float[Array, "n d"]
    mean: Float[Array, " d"]
    scale: Float[Array, " d"]

    def training_latent(self):
        return self.latent

    def objective(self):
        """``ln p(Y|Z) - 1/2 ||Z||_F^2`` (000 eq. 16), to be maximised."""
        return map_objective(self.kernel, self.latent, self.data)

    def predictor(self) -> GPPredictor:
        """The predictive distribution (000 eqs. 23-26), precomputed."""
        return full_gp_predictor(self.kernel, self.latent, self.data, self.mean, self.scale)

    def trainable(self):
        spec = jax.tree.map(lambda _: False, self)
        return eqx.tree_at(lambda m: (m.latent, m.kernel), spec, (True, jax.tree.map(lambda _: True, self.kernel)))

    def back_constraint(self):
        return None

    def header(self) -> dict:
        return {}

    @classmethod
    def template(cls, header, dtype):
        n, d, q = header["frames"], header["dims"], header["latent_dim"]
        z = lambda *shape: jnp.zeros(shape, dtype)  # noqa: E731
        return cls(latent=z(n, q), kernel=rbf_bias_kernel(dtype=dtype), data=z(n, d), mean=z(d), scale=z(d))


class KernelBackConstraint(eqx.Module):
    """``z = k_x(y, Y_train) A + b`` with ``k_x = exp(-gamma_x/2 ||y - y'||^2)`` (000 eq. 22).

    ``inputs`` (standardised training poses) and ``gamma_x`` are fixed; ``weights`` and ``bias``
    are learned.
    """

    weights: Float[Array, "n q"]
    bias: Float[Array, " q"]
    inputs: Float[Array, "n d"]
    gamma_x: Float[Array, ""]

    def __call__(self, Y: Float[Array, "m d"]) -> Float[Array, "m q"]:
        K = jnp.exp(-0.5 * self.gamma_x * squared_distances(Y, self.inputs))
        return K @ self.weights + self.bias

    def trainable(self):
        spec = jax.tree.map(lambda _: False, self)
        return eqx.tree_at(lambda b: (b.weights, b.bias), spec, (True, True))


def kernel_back_constraint(Y: Float[Array, "n d"], latent: Float[Array, "n q"], gamma_x: float | None = None) -> KernelBackConstraint:
    """The kernel back-constraint over the (standardised) training poses ``Y`` whose weights
    are solved so that ``g(Y)`` starts at ``latent`` (least squares, a 1e-6 jitter).
    ``gamma_x`` None: ``1 / (mean squared distance between the poses)``."""
    if gamma_x is None:
        gamma_x = 1.0 / float(jnp.mean(squared_distances(Y, Y)))
    if not gamma_x > 0:
        raise ValueError(f"gamma_x must be positive, got {gamma_x}")
    Kx = jnp.exp(-0.5 * gamma_x * squared_distances(Y, Y))
    L = safe_cholesky(Kx + 1e-6 * jnp.eye(Kx.shape[0], dtype=Y.dtype))
    weights = jax.scipy.linalg.cho_solve((L, True), latent.astype(Y.dtype))
    return KernelBackConstraint(weights=weights, bias=jnp.zeros(latent.shape[1], Y.dtype), inputs=Y,
                                gamma_x=jnp.asarray(gamma_x, Y.dtype))


class MLPBackConstraint(eqx.Module):
    """``z = y P + b + MLP(y)``: a linear map (initialised to the PCA projection) plus a tanh
    multilayer perceptron whose last layer starts at zero, so fitting starts from PCA
    (the multilayer-perceptron back-constraint of Lawrence and Quinonero-Candela 2006)."""

    projection: Float[Array, "d q"]
    bias: Float[Array, " q"]
    mlp: eqx.nn.MLP

    def __call__(self, Y: Float[Array, "m d"]) -> Float[Array, "m q"]:
        return Y @ self.projection + self.bias + jax.vmap(self.mlp)(Y)

    def trainable(self):
        return jax.tree.map(eqx.is_inexact_array, self)


@register_manifold
class BCGPLVM(AbstractSaveableManifold):
    """Back-constrained GPLVM (000 eqs. 21-22): the latent points are ``g(Y)``."""

    back: KernelBackConstraint | MLPBackConstraint
    kernel: RBFBiasKernel
    data: Float[Array, "n d"]
    mean: Float[Array, " d"]
    scale: Float[Array, " d"]

    @property
    def latent(self):
        return self.back(self.data)

    @property
    def latent_dim(self) -> int:
        # From the shapes: evaluating g(Y) for it would run the float64 map outside float64 mode.
        return int(self.back.bias.shape[0])

    def training_latent(self):
        return self.latent

    def objective(self):
        """000 eq. 16 with ``Z = g(Y)``, to be maximised over the back-constraint."""
        return map_objective(self.kernel, self.latent, self.data)

    def predictor(self) -> GPPredictor:
        return full_gp_predictor(self.kernel, self.latent, self.data, self.mean, self.scale)

    def trainable(self):
        spec = jax.tree.map(lambda _: False, self)
        return eqx.tree_at(lambda m: (m.back, m.kernel), spec, (self.back.trainable(), jax.tree.map(lambda _: True, self.kernel)))

    def back_constraint(self):
        """``g``: standardised poses -> latent points (000 eq. 22)."""
        return self.back

    def header(self) -> dict:
        if isinstance(self.back, MLPBackConstraint):
            return {"back_constraint": "mlp", "mlp_hidden": int(self.back.mlp.width_size), "mlp_depth": int(self.back.mlp.depth)}
        return {"back_constraint": "kernel"}

    @classmethod
    def template(cls, header, dtype):
        n, d, q = header["frames"], header["dims"], header["latent_dim"]
        z = lambda *shape: jnp.zeros(shape, dtype)  # noqa: E731
        if header.get("back_constraint", "kernel") == "mlp":
            # This key only shapes the template; every leaf is then read from the file.
            mlp = eqx.nn.MLP(d, q, header["mlp_hidden"], header["mlp_depth"], activation=jnp.tanh, key=jax.random.key(0), dtype=dtype)
            back = MLPBackConstraint(projection=z(d, q), bias=z(q), mlp=mlp)
        else:
            back = KernelBackConstraint(weights=z(n, q), bias=z(q), inputs=z(n, d), gamma_x=z())
        return cls(back=back, kernel=rbf_bias_kernel(dtype=dtype), data=z(n, d), mean=z(d), scale=z(d))


@register_manifold
class GPDM(AbstractSaveableManifold):
    """Gaussian process dynamical model (001 eqs. 5-11).

    Attributes:
        latent: (N, q) latent trajectory X, sequences stacked in time order.
        kernel: the pose kernel (RBF + bias, noise).
        dynamics: the latent dynamics kernel (linear + RBF, noise).
        log_w: (D,) log per-dimension output scales W.
        data, mean, scale: as for ``GPLVM``.
        sequence_starts: first frame of each training sequence (static), ending with N.
    """

    latent: Float[Array, "n q"]
    kernel: RBFBiasKernel
    dynamics: LinearRBFKernel
    log_w: Float[Array, " d"]
    data: Float[Array, "n d"]
    mean: Float[Array, " d"]
    scale: Float[Array, " d"]
    sequence_starts: tuple[int, ...] = eqx.field(static=True)

    def training_latent(self):
        return self.latent

    def _transitions(self):
        """Indices of (x_t, x_{t+1}) pairs that stay inside one sequence, and the first frames."""
        starts = self.sequence_starts
        inputs, outputs = [], []
        for begin, end in itertools.pairwise(starts):
            inputs += list(range(begin, end - 1))
            outputs += list(range(begin + 1, end))
        return np.array(inputs), np.array(outputs), np.array(starts[:-1])

    def objective(self):
        """Log posterior (negative of 001 eq. 11, up to a constant), to be maximised."""
        X, Y = self.latent, self.data
        n, _d = Y.shape
        q = X.shape[1]
        w = jnp.exp(self.log_w)
        # ln p(Y | X, beta, W) (001 eq. 6): the GP likelihood of Y W, plus N ln|W|. A pose entry
        # that never moves in the training data (zero once centred, to rounding) is left out: its term
        # N ln w_d grows without bound in w_d (the fit ran off to noise 1e-14 on CMU walks,
        # which hold one such entry); its prediction is its constant mean.
        moving = (jnp.max(jnp.abs(Y), axis=0) > 1e-9).astype(Y.dtype)
        log_lik = gaussian_log_marginal(self.kernel.gram(X), Y * w, moving) + n * jnp.sum(moving * self.log_w)
        # ln p(X | alpha) (001 eqs. 7-8): first frames ~ N(0, I), transitions ~ GP.
        ins, outs, firsts = self._transitions()
        x_in, x_out = X[ins], X[outs]
        log_dyn = gaussian_log_marginal(self.dynamics.gram(x_in), x_out) if len(ins) else 0.0
        log_first = -0.5 * jnp.sum(X[firsts] ** 2) - 0.5 * q * len(firsts) * jnp.log(2 * jnp.pi)
        # p(theta) proportional to prod 1/theta (001 eqs. 10-11: + sum ln alpha_i + sum ln beta_i
        # in the negative log posterior), where alpha_4 and beta_3 are the noise *precisions*:
        # our kernels hold the noise variance, so its term has the opposite sign. (With the sign
        # of a variance the prior rewarded shrinking the pose kernel's scale and noise together,
        # a direction in which the likelihood with free W is flat: the fit collapsed onto
        # noise ~ 1e-14 and a dynamics GP of variance 1e24 on CMU walks.) Scaling the pose
        # kernel, its noise and W^2 together by s now changes the objective only by the bias
        # term's prior, -ln s.
        log_prior = -(self.kernel.log_beta + self.kernel.log_gamma + self.kernel.log_beta0 - self.kernel.log_noise)
        log_prior = log_prior - (self.dynamics.log_a1 + self.dynamics.log_a2 + self.dynamics.log_a3 - self.dynamics.log_noise)
        return log_lik + log_dyn + log_first + log_prior

    def predictor(self) -> GPPredictor:
        """Pose predictions; the output scales W cancel in the mean (``K^-1 Y W / W``)."""
        return full_gp_predictor(self.kernel, self.latent, self.data, self.mean, self.scale)

    def latent_dynamics(self) -> GPPredictor:
        """The dynamics GP's predictive map (001 eqs. 7-9): ``x_{t-1} -> x_t``'s mean
        ``k(x, X_in) K_X^-1 X_out`` and variance, from the within-sequence transitions."""
        ins, outs, _ = self._transitions()
        X = self.latent
        q = X.shape[1]
        return full_gp_predictor(self.dynamics, X[ins], X[outs], jnp.zeros(q, X.dtype), jnp.ones(q, X.dtype))

    def trainable(self):
        spec = jax.tree.map(lambda _: False, self)
        return eqx.tree_at(
            lambda m: (m.latent, m.kernel, m.dynamics, m.log_w),
            spec,
            (True, jax.tree.map(lambda _: True, self.kernel), jax.tree.map(lambda _: True, self.dynamics), True),
        )

    def back_constraint(self):
        return None

    def header(self) -> dict:
        return {"sequence_starts": [int(s) for s in self.sequence_starts]}

    @classmethod
    def template(cls, header, dtype):
        n, d, q = header["frames"], header["dims"], header["latent_dim"]
        z = lambda *shape: jnp.zeros(shape, dtype)  # noqa: E731
        return cls(
            latent=z(n, q), kernel=rbf_bias_kernel(dtype=dtype), dynamics=linear_rbf_kernel(dtype=dtype), log_w=z(d),
            data=z(n, d), mean=z(d), scale=z(d), sequence_starts=tuple(header["sequence_starts"]),
        )


def make_gplvm(Y, latent_dim: int = 2, *, scale: bool = False, dtype=jnp.float64) -> GPLVM:
    """A GPLVM initialised from PCA (latent points) and data-scaled hyperparameters."""
    Y = check_training_data(Y, latent_dim)
    Yn, mean, std = standardise(Y, scale)
    return GPLVM(
        latent=jnp.asarray(_initial_latent(Yn, latent_dim), dtype),
        kernel=rbf_bias_kernel(beta=float(np.mean(Yn.var(axis=0))) + 1e-3, gamma=1.0, beta0=1e-2, noise=1e-2, dtype=dtype),
        data=jnp.asarray(Yn, dtype),
        mean=jnp.asarray(mean, dtype),
        scale=jnp.asarray(std, dtype),
    )


BACK_CONSTRAINTS = ("kernel", "mlp")


def make_bc_gplvm(
    Y,
    latent_dim: int = 2,
    *,
    back_constraint: str = "kernel",
    gamma_x: float | None = None,
    hidden: int = 32,
    depth: int = 1,
    key=None,
    scale: bool = False,
    dtype=jnp.float64,
) -> BCGPLVM:
    """A back-constrained GPLVM whose back-constraint reproduces the PCA initialisation.

    Args:
        back_constraint: "kernel" (000 eq. 22) or "mlp" (``MLPBackConstraint``).
        gamma_x: inverse width of the kernel back-constraint (000 fixes it: 1e-4 in its pose
            units); default ``1 / (mean squared distance between training poses)``.
        hidden, depth: width and number of hidden layers of the MLP back-constraint.
        key: PRNG key for the MLP's initial weights (required for "mlp").
    """
    if back_constraint not in BACK_CONSTRAINTS:
        raise ValueError(f"back_constraint must be one of {BACK_CONSTRAINTS}, got {back_constraint!r}")
    Y = check_training_data(Y, latent_dim)
    Yn, mean, std = standardise(Y, scale)
    Yj = jnp.asarray(Yn, dtype)
    Z0 = _initial_latent(Yn, latent_dim).astype(dtype)
    if back_constraint == "kernel":
        back = kernel_back_constraint(Yj, Z0, gamma_x)
    else:
        if key is None:
            raise ValueError("the MLP back-constraint needs an explicit PRNG key: pass key=... for its initial weights")
        projection = jnp.linalg.lstsq(Yj, Z0)[0]
        mlp = eqx.nn.MLP(Yj.shape[1], latent_dim, hidden, depth, activation=jnp.tanh, key=key, dtype=dtype)
        last = mlp.layers[-1]
        mlp = eqx.tree_at(lambda m: (m.layers[-1].weight, m.layers[-1].bias), mlp, (jnp.zeros_like(last.weight), jnp.zeros_like(last.bias)))
        back = MLPBackConstraint(projection=projection, bias=jnp.zeros(latent_dim, dtype), mlp=mlp)
    return BCGPLVM(
        back=back,
        kernel=rbf_bias_kernel(beta=float(np.mean(Yn.var(axis=0))) + 1e-3, gamma=1.0, beta0=1e-2, noise=1e-2, dtype=dtype),
        data=Yj,
        mean=jnp.asarray(mean, dtype),
        scale=jnp.asarray(std, dtype),
    )


GPDM_STARTS = ("pca", "gle")


def make_gpdm(sequences, latent_dim: int = 3, *, scale: bool = True, init: str = "pca", dtype=jnp.float64) -> GPDM:
    """A GPDM over one or more training sequences (list of (T_i, D) arrays).

    ``init`` picks the latent trajectory the fit starts from: "pca" (the principal components,
    as 001 does) or "gle" (002's Generalised Laplacian Eigenmap of the sequences, scaled as the
    PCA start). Where a half-cycle feature outweighs the stride's quarter-phase partner, a 2-D
    PCA start folds each gait cycle into a thin loop, phase phi beside phase pi - phi (the demo's
    motion does; the CMU walk does not); the GLE's temporal and stylistic graph lays each cycle
    out as a circle (docs/trackers.md, "Where a 2-D GPDM starts"). A sequence in which no repeated cycle
    is found is one piece of the GLE's graph; ``fit_spectral``'s errors name what is too short.
    """
    if init not in GPDM_STARTS:
        raise ValueError(f"init must be one of {GPDM_STARTS}, got {init!r}")
    if isinstance(sequences, np.ndarray) and sequences.ndim == 2:
        sequences = [sequences]
    sequences = [np.asarray(s, np.float64) for s in sequences]
    if not sequences or any(s.ndim != 2 or s.shape[0] < 2 for s in sequences):
        raise ValueError("GPDM needs one or more (T, D) sequences with at least 2 frames each")
    if len({s.shape[1] for s in sequences}) != 1:
        raise ValueError(f"sequences differ in dimension: {[s.shape[1] for s in sequences]}")
    Y = check_training_data(np.concatenate(sequences), latent_dim)
    Yn, mean, std = standardise(Y, scale)
    starts = tuple(int(v) for v in np.cumsum([0] + [s.shape[0] for s in sequences]))
    if init == "gle":
        spectral = np.asarray(fit_spectral(sequences, "gle", latent_dim=latent_dim).latent, np.float64)
        latent = spectral / np.std(spectral[:, 0])  # unit scale, as the PCA start
    else:
        latent = _initial_latent(Yn, latent_dim)
    return GPDM(
        latent=jnp.asarray(latent, dtype),
        kernel=rbf_bias_kernel(beta=1.0, gamma=1.0, beta0=1e-2, noise=1e-2, dtype=dtype),
        dynamics=linear_rbf_kernel(dtype=dtype),
        log_w=jnp.zeros(Y.shape[1], dtype),
        data=jnp.asarray(Yn, dtype),
        mean=jnp.asarray(mean, dtype),
        scale=jnp.asarray(std, dtype),
        sequence_starts=starts,
    )


def predict(model, Z: Float[Array, "m q"]) -> tuple[Float[Array, "m d"], Float[Array, " m"]]:
    """GP predictive mean (in pose units) and variance at latent points (000 eqs. 23-26).

    ``mu(z) = mean + scale * (k(z, Z) K^-1 Y)``; ``var(z) = k(z, z) - k(z, Z) K^-1 k(Z, z)``
    (the per-dimension variance in standardised units; add ``kernel.noise`` for a new pose).
    Refactorises the covariance on every call: filters use ``model.predictor()`` once instead.
    """
    return model.predictor()(Z)
