"""The jitted fit (one ``lax.while_loop`` of L-BFGS: ours, one evaluation per iteration, and
optax's) and the derivative rules that make it fast: the Gaussian log-density's rule against autodiff through the Cholesky factorisation,
the jittered Cholesky's rule against JAX's, and the fit against reference optimisers."""

import logging

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
import scipy.optimize
from jax.flatten_util import ravel_pytree

from jaxtrack.data import generate_motion
from jaxtrack.manifold import cholesky_inverse, fit_model, gaussian_log_marginal, make_gplvm, safe_cholesky


def _plain_log_marginal(K, Y, columns):
    """000 eq. 15 written the obvious way: autodiff differentiates through the factorisation."""
    L = jnp.linalg.cholesky(K)
    alpha = jax.scipy.linalg.cho_solve((L, True), Y) * columns
    count = jnp.sum(columns)
    return (-0.5 * count * Y.shape[0] * jnp.log(2 * jnp.pi) - count * jnp.sum(jnp.log(jnp.diag(L)))
            - 0.5 * jnp.sum(Y * alpha))


def _spd(key, n):
    A = jax.random.normal(key, (n, n), jnp.float64)
    return A @ A.T / n + 0.5 * jnp.eye(n, dtype=jnp.float64)


@pytest.fixture(autouse=True)
def _float64():
    with jax.enable_x64(True):
        yield


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_log_marginal_rule_equals_autodiff_through_the_cholesky_in_both_modes(getkey):
    n, d = 9, 4
    K, Y = _spd(getkey(), n), jax.random.normal(getkey(), (n, d), jnp.float64)
    dK = jax.random.normal(getkey(), (n, n), jnp.float64)
    dK = dK + dK.T
    dY = jax.random.normal(getkey(), (n, d), jnp.float64)
    for columns in (jnp.ones(d), jnp.array([1.0, 0.0, 1.0, 1.0])):
        rule = lambda K, Y, c=columns: gaussian_log_marginal(K, Y, c)  # noqa: E731
        plain = lambda K, Y, c=columns: _plain_log_marginal(K, Y, c)  # noqa: E731
        assert float(rule(K, Y)) == pytest.approx(float(plain(K, Y)), rel=1e-13)
        for a, b in zip(jax.grad(rule, argnums=(0, 1))(K, Y), jax.grad(plain, argnums=(0, 1))(K, Y)):
            np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)
        forward = jax.jvp(rule, (K, Y), (dK, dY))[1]
        assert float(forward) == pytest.approx(float(jax.jvp(plain, (K, Y), (dK, dY))[1]), rel=1e-10)
        # second order too (the rule is written in differentiable JAX operations)
        hvps = [jax.grad(lambda K, f=f: jax.jvp(lambda K: f(K, Y), (K,), (dK,))[1])(K) for f in (rule, plain)]
        np.testing.assert_allclose(hvps[0], hvps[1], rtol=1e-8, atol=1e-10)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
@pytest.mark.parametrize(("n", "block"), [(6, 128), (37, 8), (300, 128), (301, 64)])
def test_cholesky_inverse_equals_the_inverse_at_every_depth_of_its_recursion(getkey, n, block):
    K = _spd(getkey(), n)
    inverse = cholesky_inverse(jnp.linalg.cholesky(K), block=block)
    reference = np.linalg.inv(np.asarray(K))
    np.testing.assert_allclose(inverse, reference, rtol=1e-9, atol=1e-9 * np.abs(reference).max())
    np.testing.assert_allclose(inverse, inverse.T, rtol=0, atol=1e-12 * np.abs(reference).max())
    np.testing.assert_allclose(jax.jit(cholesky_inverse, static_argnames="block")(jnp.linalg.cholesky(K), block=block), inverse,
                               rtol=1e-12, atol=1e-12 * np.abs(reference).max())


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_log_marginal_rule_holds_where_the_inverse_recurses(getkey):
    n, d = 300, 3  # beyond one block of ``cholesky_inverse``
    K, Y = _spd(getkey(), n), jax.random.normal(getkey(), (n, d), jnp.float64)
    rule = jax.grad(gaussian_log_marginal, argnums=(0, 1))(K, Y)
    plain = jax.grad(lambda K, Y: _plain_log_marginal(K, Y, jnp.ones(d)), argnums=(0, 1))(K, Y)
    for a, b in zip(rule, plain):
        np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-10 * np.abs(np.asarray(b)).max())


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_safe_cholesky_differentiates_like_jax_cholesky_and_survives_a_singular_matrix(getkey):
    K = _spd(getkey(), 7)
    dK = jax.random.normal(getkey(), (7, 7), jnp.float64)
    dK = dK + dK.T
    L, dL = jax.jvp(safe_cholesky, (K,), (dK,))
    L0, dL0 = jax.jvp(jnp.linalg.cholesky, (K,), (dK,))
    np.testing.assert_allclose(L, L0, rtol=1e-13)
    np.testing.assert_allclose(dL, dL0, rtol=1e-9, atol=1e-12)
    u = jax.random.normal(getkey(), (7, 7), jnp.float64)
    np.testing.assert_allclose(jax.grad(lambda K: jnp.sum(u * safe_cholesky(K)))(K),
                               jax.grad(lambda K: jnp.sum(u * jnp.linalg.cholesky(K)))(K), rtol=1e-9, atol=1e-12)
    singular = jnp.ones((7, 7), jnp.float64)  # rank one: the first rungs fail
    factor = safe_cholesky(singular)
    assert np.all(np.isfinite(np.asarray(factor)))
    np.testing.assert_allclose(factor @ factor.T, singular, atol=1e-3)
    assert np.all(np.isfinite(np.asarray(jax.grad(lambda K: jnp.sum(jnp.log(jnp.diag(safe_cholesky(K)))))(singular))))
    batch = jnp.stack([K, singular, 2 * K])
    np.testing.assert_allclose(jax.vmap(safe_cholesky)(batch), jnp.stack([safe_cholesky(m) for m in batch]), rtol=1e-12)


def _small_gplvm(frames=30):
    Y = generate_motion("walk", "S1", num_frames=frames, fps=30.0, key=jax.random.key(3), dtype=jnp.float64).pose[:, 6:]
    return make_gplvm(np.asarray(Y), 2)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_jitted_fit_takes_the_same_steps_as_a_python_loop_of_optax_lbfgs():
    """``optimiser="optax"`` against optax L-BFGS steps driven from Python. Same start, same steps."""
    model = _small_gplvm()
    fitted, info = fit_model(model, max_steps=25, tolerance=0.0, optimiser="optax")
    params, static = eqx.partition(model, model.trainable())
    loss = lambda p: -eqx.combine(p, static).objective()  # noqa: E731
    optimiser = optax.lbfgs()
    state = optimiser.init(params)
    value_and_grad = optax.value_and_grad_from_state(loss)

    @jax.jit
    def step(params, state):
        value, grad = value_and_grad(params, state=state)
        updates, state = optimiser.update(grad, state, params, value=value, grad=grad, value_fn=loss)
        return optax.apply_updates(params, updates), state

    for _ in range(25):
        params, state = step(params, state)
    reference = eqx.combine(params, static)
    assert info.steps == 25 and info.trace.shape == (25,) and info.evaluations >= 25
    assert info.objective == pytest.approx(float(reference.objective()), rel=1e-9)
    np.testing.assert_allclose(fitted.latent, reference.latent, rtol=1e-6, atol=1e-7)
    assert info.trace[-1] == pytest.approx(info.objective, rel=1e-12)


def _reference_lbfgs(value_and_grad, x, steps, memory):
    """L-BFGS written plainly in NumPy, one evaluation at a time in a Python loop: the weak
    Wolfe conditions, from the unit quasi-Newton step back by safeguarded quadratic
    interpolation, forward by doubling, then bisection; two-loop recursion."""
    pairs, losses = [], []
    loss, grad = value_and_grad(x)
    direction, alpha = -grad, min(1.0, 1.0 / np.linalg.norm(grad))
    low, high = 0.0, np.inf
    while len(losses) < steps:
        trial = x + alpha * direction
        new_loss, new_grad = value_and_grad(trial)
        slope = grad @ direction
        armijo = np.isfinite(new_loss) and new_loss <= loss + 1e-4 * alpha * slope
        if not (armijo and new_grad @ direction >= 0.9 * slope):
            if armijo:
                low = alpha
            else:
                high = alpha
            quadratic = -slope * alpha**2 / (2 * (new_loss - loss - slope * alpha))
            shrunk = quadratic if np.isfinite(new_loss) and 0.1 * alpha < quadratic < 0.5 * alpha else 0.5 * alpha
            alpha = (0.5 * (low + high) if low > 0 else shrunk) if np.isfinite(high) else 2 * alpha
            continue
        s, y = trial - x, new_grad - grad
        pairs = (pairs + [(s, y)])[-memory:]
        x, loss, grad = trial, new_loss, new_grad
        losses.append(loss)
        low, high = 0.0, np.inf
        q, alphas = grad.copy(), []
        for s_i, y_i in reversed(pairs):
            a = (s_i @ q) / (s_i @ y_i)
            q -= a * y_i
            alphas.append(a)
        s_n, y_n = pairs[-1]
        r = (s_n @ y_n) / (y_n @ y_n) * q
        for (s_i, y_i), a in zip(pairs, reversed(alphas)):
            r += (a - (y_i @ r) / (s_i @ y_i)) * s_i
        direction, alpha = (-r, 1.0) if -r @ grad < 0 else (-grad, min(1.0, 1.0 / np.linalg.norm(grad)))
    return x, np.array(losses)


@pytest.mark.parametrize("memory", [3, pytest.param(10, marks=pytest.mark.slow)])  # each 8-10 s cold; one in the default suite
def test_jitted_lbfgs_takes_the_steps_of_a_plain_numpy_lbfgs(memory):
    """The default optimiser (one evaluation per ``lax.while_loop`` iteration, its line search
    a state of the loop) against the same algorithm written plainly: the same 25 steps. With 3
    pairs the memory wraps round."""
    model = _small_gplvm()
    fitted, info = fit_model(model, max_steps=25, tolerance=0.0, memory=memory)
    params, static = eqx.partition(model, model.trainable())
    flat, unravel = ravel_pytree(params)
    jitted = jax.jit(jax.value_and_grad(lambda x: -eqx.combine(unravel(x), static).objective()))
    x, losses = _reference_lbfgs(lambda x: tuple(np.asarray(v, np.float64) for v in jitted(x)), np.asarray(flat), 25, memory)
    assert info.steps == 25 and info.evaluations >= 26
    np.testing.assert_allclose(-info.trace, losses, rtol=1e-9)
    np.testing.assert_allclose(fitted.latent, unravel(jnp.asarray(x)).latent, rtol=1e-6, atol=1e-8)
    # with a progress bar the loop runs in pieces of 7, 14, 21 and 25 steps: the same run exactly
    pieces, pieces_info = fit_model(model, max_steps=25, tolerance=0.0, memory=memory, progress=True, report_every=7)
    np.testing.assert_array_equal(pieces_info.trace, info.trace)
    np.testing.assert_array_equal(pieces.latent, fitted.latent)
    assert pieces_info.evaluations == info.evaluations
    with pytest.raises(ValueError, match="optimiser must be one of"):
        fit_model(model, optimiser="adam")
    with pytest.raises(ValueError, match="memory must be a positive integer"):
        fit_model(model, memory=0)


class _KernelOnly(eqx.Module):
    """A GPLVM whose latent points stay where PCA put them: kernel hyperparameters by maximum
    likelihood, a small problem with a well-defined optimum (the full GP-LVM objective has
    long flat valleys in which any two optimisers stop at different places)."""

    model: object

    def objective(self):
        return self.model.objective()

    def trainable(self):
        spec = jax.tree.map(lambda _: False, self)
        return eqx.tree_at(lambda m: m.model.kernel, spec, jax.tree.map(lambda _: True, self.model.kernel))


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
@pytest.mark.parametrize("optimiser", ["lbfgs", "optax"])
def test_converged_fit_reaches_the_optimum_scipy_reaches(optimiser):
    """Run to convergence from the same start, the jitted fit (either optimiser) and SciPy's
    L-BFGS-B on the same objective end at the same optimum (objective and identifiable
    hyperparameters)."""
    problem = _KernelOnly(_small_gplvm(40))
    fitted, info = fit_model(problem, max_steps=500, tolerance=1e-13, optimiser=optimiser)
    params, static = eqx.partition(problem, problem.trainable())
    flat, unravel = ravel_pytree(params)
    value_and_grad = jax.jit(jax.value_and_grad(lambda x: -eqx.combine(unravel(x), static).objective()))
    result = scipy.optimize.minimize(lambda x: tuple(np.asarray(v, np.float64) for v in value_and_grad(x)), np.asarray(flat),
                                     jac=True, method="L-BFGS-B", options={"maxiter": 5000, "ftol": 1e-15, "gtol": 1e-10})
    assert info.steps < 500 and info.objective == pytest.approx(-float(result.fun), rel=1e-9)
    ours = np.asarray(ravel_pytree(eqx.partition(fitted, fitted.trainable())[0])[0])  # log beta, gamma, beta0, noise
    # the data are centred, so the bias variance beta0 has no optimum: both drive it to ~0
    np.testing.assert_allclose(ours[[0, 1, 3]], result.x[[0, 1, 3]], rtol=1e-4)
    assert ours[2] < -20 and result.x[2] < -20


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-27)
def test_fit_stops_at_a_target_objective():
    model = _small_gplvm()
    _, full = fit_model(model, max_steps=60, tolerance=0.0)
    target = float(full.trace[29])
    _, info = fit_model(model, max_steps=60, tolerance=0.0, target=target)
    assert info.steps == 30 and info.objective >= target and info.objective == pytest.approx(full.trace[29], rel=1e-12)
    with pytest.raises(ValueError, match="target must be a finite number"):
        fit_model(model, target=float("inf"))


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-28)
def test_fit_reports_progress_between_pieces_of_the_loop(capsys, caplog):
    # Every piece runs the one compiled loop: the state the loop starts from has the types the
    # loop returns (a weakly typed counter in the start made the second piece a second program).
    for optimiser in ("lbfgs", "optax"):
        caplog.clear()
        with jax.log_compiles(), caplog.at_level(logging.WARNING):
            _, info = fit_model(_small_gplvm(), max_steps=20, tolerance=0.0, progress=True, report_every=5,
                                optimiser=optimiser)
        err = capsys.readouterr().err
        assert "fitting GPLVM" in err and "20/20" in err and f"{info.objective:.6g}" in err
        assert info.steps == 20
        loops = [r for r in caplog.records if r.getMessage().startswith("Compiling") and "_advance" in r.getMessage()]
        assert len(loops) == 1, [r.getMessage()[:80] for r in loops]
    with pytest.raises(ValueError, match="report_every must be a positive integer"):
        fit_model(_small_gplvm(), report_every=0)
    with pytest.raises(ValueError, match="tolerance must be a finite number"):
        fit_model(_small_gplvm(), tolerance=float("nan"))


def test_a_model_with_non_finite_parameters_is_never_saved(tmp_path):
    from jaxtrack.manifold import ModelFileError, save_model

    Y = np.random.default_rng(0).normal(size=(12, 4))
    model = make_gplvm(Y, 2)
    broken = eqx.tree_at(lambda m: m.latent, model, model.latent.at[3, 1].set(jnp.nan))
    with pytest.raises(ModelFileError, match=r"not saved: the model's \.latent are not finite"):
        save_model(tmp_path / "m.eqx", broken)
    assert not (tmp_path / "m.eqx").exists()
    # Training data far beyond any pose is refused before fitting, naming where.
    Y[5, 2] = 1e300
    with pytest.raises(ValueError, match="hold 1e\\+300 at frame 5, dimension 2"):
        make_gplvm(Y, 2)
