"""The active-set GPLVM of paper 003 (Algorithm 1, eqs. 1-5).

The kernel is learned on an active set I of the training points (003 eq. 1 on I: the GPLVM's
negative log posterior ``M/2 ln|K_II| + 1/2 sum_m Y_m^T K_II^-1 Y_m + 1/2 sum_i ||x_i||^2``),
chosen by the informative vector machine (IVM; Lawrence, Seeger and Herbrich 2003): greedily
the point whose inclusion reduces the posterior entropy most, which with Gaussian noise is the
point of largest current posterior variance (``0.5 ln(1 + s_j / sigma^2)`` grows with ``s_j``).
Every other point's latent position is then optimised on its own (vmapped) by 003 eq. 2,

    L'(x_j, y_j) = ||y_j - mu(x_j)||^2 / (2 sigma^2(x_j)) + M/2 ln sigma^2(x_j) + 1/2 ||x_j||^2,

with ``mu`` and ``sigma^2`` the active set's predictive mean and variance (eqs. 3-4). The
inverse map ``mu^-1(y)`` (eq. 5) is the same optimisation from the nearest training point
(``encode(..., method="likelihood")``). Initialisation by Isomap (003) or PCA.
"""

from __future__ import annotations

import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .._custom_types import Array, Float, Int
from ._kernels import RBFBiasKernel, rbf_bias_kernel
from ._models import _initial_latent, check_training_data, map_objective, standardise
from ._predictor import GPPredictor, full_gp_predictor
from ._serialise import AbstractSaveableManifold, register_manifold

INITIALISATIONS = ("isomap", "pca")
POINT_STEPS = 50  # BFGS iterations of eq. 2 per inactive point and round
POINT_TOLERANCE = 1e-6
POINT_CHUNK = 256  # points solved side by side (``optimise_points``)


@jax.jit
def _ivm_scores(kernel: RBFBiasKernel, latent, size_array):
    size = size_array.shape[0]
    n = latent.shape[0]

    def body(i, carry):
        rows, variance, chosen, taken = carry
        j = jnp.argmax(jnp.where(taken, -jnp.inf, variance))
        column = kernel(latent[j][None], latent)[0] - rows.T @ rows[:, j]
        row = column / jnp.sqrt(jnp.maximum(variance[j], 0.0) + kernel.noise)
        return rows.at[i].set(row), variance - row**2, chosen.at[i].set(j.astype(jnp.int32)), taken.at[j].set(True)

    start = (jnp.zeros((size, n), latent.dtype), kernel.diag(latent), jnp.zeros(size, jnp.int32), jnp.zeros(n, bool))
    return jax.lax.fori_loop(0, size, body, start)[2]


def ivm_select(kernel: RBFBiasKernel, latent: Float[Array, "n q"], size: int) -> Int[Array, " size"]:
    """The IVM's active set: ``size`` indices into ``latent``, in the order chosen (module
    docstring); jitted, one compile per (N, size)."""
    n = latent.shape[0]
    if not 1 <= size <= n:
        raise ValueError(f"the active set must hold 1 to {n} points, got {size}")
    return _ivm_scores(kernel, jnp.asarray(latent), jnp.zeros(size))


def point_objective(predictor: GPPredictor, x: Float[Array, " q"], y: Float[Array, " d"]) -> Float[Array, ""]:
    """003 eq. 2 for one point: ``x`` latent, ``y`` standardised data."""
    mean, variance = predictor(x[None])
    variance = variance[0] + predictor.noise
    residual = (predictor.mean + predictor.scale * y - mean[0]) / predictor.scale
    return jnp.sum(residual**2) / (2 * variance) + 0.5 * y.shape[0] * jnp.log(variance) + 0.5 * jnp.sum(x * x)


@eqx.filter_jit
def optimise_points(predictor: GPPredictor, start: Float[Array, "m q"], data: Float[Array, "m d"], steps: int = POINT_STEPS,
                    chunk: int = POINT_CHUNK):
    """Each point's latent position by 003 eq. 2 from ``start`` (BFGS, vmapped over ``chunk``
    points at a time).

    The chunks bound the memory: a vmapped BFGS loop carries the predictor's (D, D) matrices once
    per point it solves side by side, so all N points at once would hold N D^2 numbers (27 GB
    for 9,000 points and an active set of 600).
    """
    solver = optx.BFGS(rtol=POINT_TOLERANCE, atol=POINT_TOLERANCE)

    def solve(pair):
        x0, y = pair
        return optx.minimise(lambda x, y: point_objective(predictor, x, y), solver, x0, args=y, max_steps=steps, throw=False).value

    solved = jax.lax.map(solve, (start, data), batch_size=max(1, min(int(chunk), start.shape[0])))
    return jnp.where(jnp.all(jnp.isfinite(solved), axis=1, keepdims=True), solved, start)


@register_manifold
class ActiveSetGPLVM(AbstractSaveableManifold):
    """GPLVM whose kernel is learned on an IVM active set (module docstring).

    Attributes:
        latent: (N, q) every training point's latent position.
        active: (D,) the active set's indices into the training points.
        kernel: RBF + bias kernel and noise (003 sec. 3.1.1).
        data, mean, scale: the standardised training data and its standardisation.
    """

    latent: Float[Array, "n q"]
    active: Int[Array, " m"]
    kernel: RBFBiasKernel
    data: Float[Array, "n d"]
    mean: Float[Array, " d"]
    scale: Float[Array, " d"]

    def training_latent(self):
        return self.latent

    def objective(self):
        """003 eq. 1 on the active set, negated (to be maximised)."""
        return map_objective(self.kernel, self.latent[self.active], self.data[self.active])

    def trainable(self):
        spec = jax.tree.map(lambda _: False, self)
        return eqx.tree_at(lambda m: (m.latent, m.kernel), spec, (True, jax.tree.map(lambda _: True, self.kernel)))

    def predictor(self) -> GPPredictor:
        """The active set's predictive map (003 eqs. 3-4)."""
        return full_gp_predictor(self.kernel, self.latent[self.active], self.data[self.active], self.mean, self.scale)

    def back_constraint(self):
        return None

    def header(self) -> dict:
        return {"active": int(self.active.shape[0])}

    @classmethod
    def template(cls, header, dtype):
        n, d, q = header["frames"], header["dims"], header["latent_dim"]
        z = lambda *shape: jnp.zeros(shape, dtype)  # noqa: E731
        return cls(latent=z(n, q), active=jnp.zeros(header["active"], jnp.int32), kernel=rbf_bias_kernel(dtype=dtype),
                   data=z(n, d), mean=z(d), scale=z(d))

    def fit(self, *, iterations: int = 3, max_steps: int = 200, point_steps: int = POINT_STEPS, progress: bool = False, **options):
        """003 Algorithm 1: ``fit_active_set(self, ...)``."""
        return fit_active_set(self, iterations=iterations, max_steps=max_steps, point_steps=point_steps, progress=progress, **options)


def fit_active_set(model: ActiveSetGPLVM, *, iterations: int = 3, max_steps: int = 200, point_steps: int = POINT_STEPS,
                   progress: bool = False, **options):
    """003 Algorithm 1, ``iterations`` rounds of: select the active set (IVM), maximise eq. 1 on
    it over the kernel and the active latent points (``fit_model``, ``max_steps`` L-BFGS steps),
    select again, and optimise every inactive point by eq. 2. Returns ``(model, FitInfo)`` of
    the last eq.-1 fit."""
    from ._fit import fit_model

    size = model.active.shape[0]
    info = None
    for _ in range(max(1, int(iterations))):
        model = eqx.tree_at(lambda m: m.active, model, ivm_select(model.kernel, model.latent, size))
        model, info = fit_model(model, max_steps=max_steps, progress=progress, **options)
        active = ivm_select(model.kernel, model.latent, size)
        model = eqx.tree_at(lambda m: m.active, model, active)
        inactive = np.setdiff1d(np.arange(model.latent.shape[0]), np.asarray(active))
        if inactive.size:
            solved = optimise_points(model.predictor(), model.latent[inactive], model.data[inactive], point_steps)
            model = eqx.tree_at(lambda m: m.latent, model, model.latent.at[inactive].set(solved))
    return model, info


def isomap(Y: np.ndarray, latent_dim: int, neighbours: int = 10) -> np.ndarray | None:
    """Isomap coordinates (N, q) of the rows of ``Y`` (geodesic distances on the k-nearest-
    neighbour graph, then classical scaling), or None where the graph is not connected."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components, shortest_path

    Y = np.asarray(Y, np.float64)
    n = Y.shape[0]
    squared = np.maximum(np.sum(Y**2, 1)[:, None] + np.sum(Y**2, 1)[None] - 2 * Y @ Y.T, 0.0)
    k = min(neighbours, n - 1)
    nearest = np.argsort(squared, axis=1)[:, 1 : k + 1]
    rows = np.repeat(np.arange(n), k)
    graph = csr_matrix((np.sqrt(squared[rows, nearest.ravel()]) + 1e-12, (rows, nearest.ravel())), shape=(n, n))
    graph = graph.maximum(graph.T)
    if connected_components(graph, directed=False)[0] > 1:
        return None
    geodesic = shortest_path(graph, method="D", directed=False)
    centring = np.eye(n) - 1.0 / n
    gram = -0.5 * centring @ (geodesic**2) @ centring
    values, vectors = np.linalg.eigh(gram)
    order = np.argsort(values)[::-1][:latent_dim]
    return vectors[:, order] * np.sqrt(np.maximum(values[order], 0.0))


def make_active_set_gplvm(Y, latent_dim: int = 2, *, active: int = 200, init: str = "isomap", neighbours: int = 10,
                          scale: bool = False, dtype=jnp.float64) -> ActiveSetGPLVM:
    """An unfitted active-set GPLVM of training data ``Y`` (N, D).

    Args:
        active: the active set's size D (at most N).
        init: "isomap" (003; PCA with a warning where the neighbour graph is not connected) or "pca".
        neighbours: Isomap's k.
        scale: standardise each dimension as well as centring it.
    """
    if init not in INITIALISATIONS:
        raise ValueError(f"init must be one of {INITIALISATIONS}, got {init!r}")
    Y = check_training_data(Y, latent_dim)
    size = int(active)
    if not 1 <= size <= Y.shape[0]:
        raise ValueError(f"the active set must hold 1 to {Y.shape[0]} points (the training frames), got {size}")
    Yn, mean, std = standardise(Y, scale)
    latent = isomap(Yn, latent_dim, neighbours) if init == "isomap" else None
    if latent is None:
        if init == "isomap":
            warnings.warn("Isomap's neighbour graph is not connected: initialising by PCA", stacklevel=2)
        latent = np.asarray(_initial_latent(Yn, latent_dim))
    else:
        latent = latent / np.std(latent[:, 0])
    kernel = rbf_bias_kernel(dtype=dtype)
    return ActiveSetGPLVM(latent=jnp.asarray(latent, dtype), active=ivm_select(kernel, jnp.asarray(latent, dtype), size),
                          kernel=kernel, data=jnp.asarray(Yn, dtype), mean=jnp.asarray(mean, dtype), scale=jnp.asarray(std, dtype))
