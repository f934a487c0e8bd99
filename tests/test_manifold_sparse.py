"""Sparse (inducing point) GPLVM and the MLP back-constraint."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.data import generate_motion
from jaxtrack.manifold import (
    MLPBackConstraint,
    fit_model,
    gaussian_log_marginal,
    load_model,
    make_bc_gplvm,
    make_gplvm,
    make_sparse_gplvm,
    predict,
    save_model,
    sparse_log_marginal,
)

from helpers import finite_difference_check


@pytest.fixture(scope="module")
def walk_angles():
    walk = generate_motion("walk", "S2", num_frames=90, fps=30.0, key=jax.random.key(3), dtype=jnp.float64)
    return np.asarray(walk.pose[:, 6:])


def numpy_bound(Z, U, Y, beta, gamma, beta0, noise, approximation):
    """Titsias's bound written directly: ln N(Y | 0, Q + s2 I) - D/(2 s2) tr(K - Q)."""
    k = lambda a, b: beta * np.exp(-0.5 * gamma * ((a[:, None] - b[None]) ** 2).sum(-1)) + beta0  # noqa: E731
    Kuu = k(U, U)
    Kuu = Kuu + 1e-8 * np.mean(np.diag(Kuu)) * np.eye(len(U))
    Q = k(Z, U) @ np.linalg.solve(Kuu, k(U, Z))
    n, d = Y.shape
    C = Q + noise * np.eye(n)
    value = -0.5 * n * d * np.log(2 * np.pi) - 0.5 * d * np.linalg.slogdet(C)[1] - 0.5 * np.trace(np.linalg.solve(C, Y @ Y.T))
    if approximation == "vfe":
        value -= 0.5 * d * np.trace(k(Z, Z) - Q) / noise
    return value


@pytest.mark.parametrize("approximation", ["vfe", "dtc"])
def test_bound_equals_dense_numpy(walk_angles, getkey, approximation):
    model = make_sparse_gplvm(walk_angles[:40], 2, num_inducing=7, approximation=approximation)
    model = eqx.tree_at(lambda m: m.inducing, model, jax.random.normal(getkey(), (7, 2)))
    k = model.kernel
    args = [np.asarray(model.latent), np.asarray(model.inducing), np.asarray(model.data)]
    expected = numpy_bound(*args, *(float(v) for v in (k.beta, k.gamma, k.beta0, k.noise)), approximation)
    value = sparse_log_marginal(model.kernel, model.inducing, model.latent, model.data, approximation)
    assert float(value) == pytest.approx(expected, rel=1e-9)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_bound_is_exact_with_all_points_and_below_otherwise(walk_angles):
    Y = walk_angles[:20]
    full = make_gplvm(Y, 2)
    sparse = make_sparse_gplvm(Y, 2, num_inducing=20)
    sparse = eqx.tree_at(lambda m: m.inducing, sparse, full.latent)  # U = Z
    exact = gaussian_log_marginal(full.kernel.gram(full.latent), full.data)
    assert float(sparse_log_marginal(sparse.kernel, sparse.inducing, sparse.latent, sparse.data)) == pytest.approx(float(exact), rel=1e-6)
    fewer = make_sparse_gplvm(Y, 2, num_inducing=5)
    assert float(sparse_log_marginal(fewer.kernel, fewer.inducing, fewer.latent, fewer.data)) < float(exact)
    # with U = Z the sparse predictive equals the exact one
    z = jnp.linspace(-2.0, 2.0, 14).reshape(7, 2)
    (m1, v1), (m2, v2) = sparse.predictor()(z), full.predictor()(z)
    np.testing.assert_allclose(m1, m2, atol=1e-4)
    np.testing.assert_allclose(v1, v2, atol=1e-5)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_sparse_and_mlp_gradients_match_finite_differences(walk_angles, getkey):
    Y = walk_angles[:30]
    from jaxtrack.manifold import make_sparse_bc_gplvm

    models = (make_sparse_gplvm(Y, 2, num_inducing=8), make_bc_gplvm(Y, 2, back_constraint="mlp", hidden=8, key=getkey()),
              make_sparse_bc_gplvm(Y, 2, num_inducing=8))
    for model in models:
        params, static = eqx.partition(model, model.trainable())
        flat, unravel = jax.flatten_util.ravel_pytree(params)
        f = lambda v, static=static, unravel=unravel: eqx.combine(unravel(v), static).objective()  # noqa: E731
        finite_difference_check(f, flat, jax.random.normal(getkey(), flat.shape), rtol=1e-5, atol=1e-6)


@pytest.mark.slow
def test_sparse_fit_reconstructs_better_than_pca(walk_angles):
    from jaxtrack.manifold import fit_pca

    Y = walk_angles
    model = make_sparse_gplvm(Y, 2, num_inducing=20)
    fitted, info = fit_model(model, max_steps=200)
    assert info.objective > float(model.objective()) + 100
    recon, _ = predict(fitted, fitted.latent)
    linear = fit_pca(Y, 2)
    pca_err = np.abs(np.asarray(linear.decode(linear.encode(jnp.asarray(Y)))) - Y).mean()
    assert np.abs(np.asarray(recon) - Y).mean() < 0.5 * pca_err


@pytest.mark.slow
def test_mlp_back_constraint_starts_at_pca_and_fits(walk_angles, getkey):
    Y = walk_angles[:60]
    pca_start = make_gplvm(Y, 2).latent
    mlp_bc = make_bc_gplvm(Y, 2, back_constraint="mlp", hidden=16, key=getkey())
    assert isinstance(mlp_bc.back, MLPBackConstraint)
    np.testing.assert_allclose(mlp_bc.latent, pca_start, atol=1e-8)
    fitted, info = fit_model(mlp_bc, max_steps=150)
    assert info.objective > float(mlp_bc.objective()) + 10
    np.testing.assert_allclose(fitted.encode(jnp.asarray(Y)), fitted.latent, atol=1e-10)
    with pytest.raises(ValueError, match="explicit PRNG key"):
        make_bc_gplvm(Y, 2, back_constraint="mlp")
    with pytest.raises(ValueError, match="back_constraint must be one of"):
        make_bc_gplvm(Y, 2, back_constraint="rbf")
    with pytest.raises(ValueError, match="num_inducing must be between 1 and the 60"):
        make_sparse_gplvm(Y, 2, num_inducing=61)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_save_load_sparse_and_mlp(walk_angles, getkey, tmp_path):
    Y = walk_angles[:30]
    models = (
        make_sparse_gplvm(Y, 2, num_inducing=6, approximation="dtc"),
        make_bc_gplvm(Y, 2, back_constraint="mlp", hidden=8, depth=2, key=getkey()),
    )
    for model in models:
        path = tmp_path / "model.eqx"
        save_model(path, model)
        back, _header = load_model(path)
        assert type(back) is type(model)
        assert float(back.objective()) == pytest.approx(float(model.objective()), rel=1e-12)
        z = jnp.ones((3, 2))
        np.testing.assert_allclose(predict(back, z)[0], predict(model, z)[0])
    assert back.back.mlp.depth == 2


def test_sparse_bc_gplvm_is_the_sparse_bound_at_the_back_constrained_points(walk_angles, getkey):
    """Its objective is the sparse GPLVM's at ``Z = g(Y)`` (the dense NumPy bound minus the
    prior), it starts at the PCA points, ``g`` encodes the training poses to them, and its kind
    builds it with at most one inducing point per frame."""
    from jaxtrack.manifold import SparseBCGPLVM, get_manifold_kind, make_sparse_bc_gplvm

    Y = walk_angles[:30]
    model = make_sparse_bc_gplvm(Y, 2, num_inducing=6)
    start = make_sparse_gplvm(Y, 2, num_inducing=6).latent
    np.testing.assert_allclose(model.training_latent(), start, atol=1e-3)  # g is solved with a 1e-6 jitter
    moved = eqx.tree_at(lambda m: (m.back.weights, m.inducing), model,
                        (model.back.weights + 0.05 * jax.random.normal(getkey(), model.back.weights.shape),
                         jax.random.normal(getkey(), (6, 2))))
    Z, k = np.asarray(moved.training_latent()), moved.kernel
    expected = numpy_bound(Z, np.asarray(moved.inducing), np.asarray(moved.data), *(float(v) for v in (k.beta, k.gamma, k.beta0, k.noise)),
                           "vfe") - 0.5 * np.sum(Z**2)
    assert float(moved.objective()) == pytest.approx(expected, rel=1e-9)
    np.testing.assert_allclose(moved.encode(jnp.asarray(Y)), Z, atol=1e-10)
    params, _ = eqx.partition(moved, moved.trainable())
    assert params.data is None and params.back.inputs is None  # the poses and g's centres are fixed (gradients: the slow test)
    kind = get_manifold_kind("sparse-bc-gplvm")
    built = kind.build([Y[:10], Y[10:]], 3)
    assert isinstance(built, SparseBCGPLVM) and built.inducing.shape == (30, 3) and built.latent_dim == 3  # M clipped to N


@pytest.mark.slow
def test_sparse_bc_gplvm_fits_saves_and_carries_vlmm_prototypes(walk_angles, getkey, tmp_path):
    """Fitting raises the bound well above the start and keeps ``g(Y)`` on the latent points;
    the file round-trips; 004's prototype uncertainties are computed through its ``g``."""
    from jaxtrack.dynamics import latent_uncertainties
    from jaxtrack.manifold import make_manifold_prior, make_sparse_bc_gplvm

    Y = walk_angles
    model = make_sparse_bc_gplvm(Y, 2, num_inducing=20)
    fitted, info = fit_model(model, max_steps=150)
    assert info.objective > float(model.objective()) + 100
    recon, _ = predict(fitted, fitted.training_latent())
    assert np.abs(np.asarray(recon) - Y).mean() < 0.05
    path = tmp_path / "sparse_bc.eqx"
    save_model(path, fitted)
    back, header = load_model(path)
    assert header["inducing"] == 20 and float(back.objective()) == pytest.approx(float(fitted.objective()), rel=1e-12)
    with jax.enable_x64(True):
        C = latent_uncertainties(make_manifold_prior(back, 6 + back.data_dim), getkey(), samples=50)
    assert C.shape == (len(Y), 4, 4) and np.all(np.isfinite(C)) and np.all(np.linalg.eigvalsh(C[:, :2, :2]) > 0)
