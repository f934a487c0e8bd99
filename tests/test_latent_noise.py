"""The GPDM latent noise refitted on validation motion (a scale mixture of the GPDM's
predictive sd): its EM fit against known mixtures, its draws against its density, its density
written out, and the default that is the GPDM's own noise bit for bit."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from jaxtrack.data import generate_motion
from jaxtrack.dynamics import (
    GPDMLatentDynamics,
    LatentNoiseMixture,
    fit_gpdm_latent_dynamics,
    fit_latent_dynamics,
    fit_mrpf_transition,
    fit_scale_mixture,
    gpdm_noise,
)
from jaxtrack.manifold import make_gpdm, make_manifold_prior

from helpers import check_refinement_keeps_transition


@pytest.fixture(scope="module")
def walk():
    motion = generate_motion("walk", "S1", num_frames=60, fps=30.0, key=jax.random.key(5), dtype=jnp.float64)
    return np.asarray(motion.pose)


@pytest.fixture(scope="module")
def gpdm_prior(walk):
    model = make_gpdm([walk[:25, 6:], walk[25:45, 6:]], 2)  # PCA-initialised, unfitted: the maps are what is tested
    return make_manifold_prior(model, walk.shape[1])


MIXTURE = LatentNoiseMixture(core=jnp.asarray(0.6), jump=jnp.asarray(5.0), jump_probability=jnp.asarray(0.25))


@pytest.mark.parametrize("dims", [2, 3])
def test_em_recovers_a_known_scale_mixture(dims):
    rng = np.random.default_rng(11)
    n = 40000
    jumps = rng.random(n) < 0.25
    scale = np.where(jumps, 5.0, 0.6)
    s = scale**2 * rng.chisquare(dims, n)
    fitted = fit_scale_mixture(s, dims)
    np.testing.assert_allclose(float(fitted.jump_probability), 0.25, atol=0.01)
    np.testing.assert_allclose(float(fitted.core), 0.6, rtol=0.02)
    np.testing.assert_allclose(float(fitted.jump), 5.0, rtol=0.03)
    # One component in the data: the second takes almost no weight or the same scale.
    single = fit_scale_mixture(0.8**2 * rng.chisquare(dims, n), dims)
    assert float(single.jump_probability) < 0.05 or float(single.jump) / float(single.core) < 1.2
    with pytest.raises(ValueError, match="finite non-negative"):
        fit_scale_mixture(np.array([1.0, np.nan, 2.0]), dims)
    with pytest.raises(ValueError, match="jump_probability"):
        LatentNoiseMixture(core=jnp.asarray(2.0), jump=jnp.asarray(1.0), jump_probability=jnp.asarray(0.1))


def test_mixture_draws_follow_its_density(gpdm_prior, walk, getkey):
    """GPDM latent dynamics with a mixture noise: the normalised squared steps of 40000 draws
    follow the mixture of scaled chi^2 (Kolmogorov-Smirnov), and ``log_transition`` is the
    mixture's density written out in NumPy."""
    s_global = jnp.full(6, 0.01)
    dynamics = GPDMLatentDynamics(gpdm_prior, s_global, noise=MIXTURE)
    start = dynamics.init(getkey(), jnp.asarray(walk[10]), 40000)
    drawn, correction = dynamics.propose(getkey(), start)
    np.testing.assert_array_equal(correction, np.zeros(40000))
    mean, variance = gpdm_prior.predict_latent(start[:1, 6:])
    s = np.sum((np.asarray(drawn[:, 6:]) - np.asarray(mean)) ** 2, axis=1) / float(variance[0])

    def cdf(x):
        return 0.75 * stats.chi2.cdf(x / 0.36, 2) + 0.25 * stats.chi2.cdf(x / 25.0, 2)

    assert stats.kstest(s, cdf).pvalue > 1e-3
    np.testing.assert_allclose(np.asarray(drawn[:, :6]).std(0), s_global, rtol=0.02)

    previous, states = start[:4], drawn[:4]
    m, v = gpdm_prior.predict_latent(previous[:, 6:])
    r2 = np.asarray(jnp.sum((states[:, 6:] - m) ** 2, 1))
    v = np.asarray(v)

    def component(weight, c):
        return np.log(weight) - 0.5 * r2 / (c**2 * v) - np.log(c**2 * v)  # q = 2: -q ln(c sd)

    latent = np.logaddexp(component(0.75, 0.6), component(0.25, 5.0))
    global_part = -0.5 * np.sum(((np.asarray(states[:, :6]) - np.asarray(previous[:, :6])) / 0.01) ** 2, 1)
    np.testing.assert_allclose(dynamics.log_transition(previous, states), global_part + latent, rtol=1e-9)


def test_gpdm_noise_is_the_gpdms_own_draw(gpdm_prior, walk, getkey):
    """The default (``latent_noise="gpdm"``) draws exactly ``mean + [s_global, sigma_X] * N(0, 1)``
    from the proposal's key, as before the mixture existed; an unknown fit is refused."""
    dynamics = fit_gpdm_latent_dynamics(gpdm_prior, walk[45:])
    assert float(dynamics.noise.jump_probability) == 0.0 and float(dynamics.noise.core) == 1.0
    start = dynamics.init(getkey(), jnp.asarray(walk[10]), 50)
    key = getkey()
    drawn, _ = dynamics.propose(key, start)
    mean, variance = gpdm_prior.predict_latent(start[:, 6:])
    scales = jnp.concatenate([jnp.broadcast_to(dynamics.s_global, (50, 6)), jnp.broadcast_to(jnp.sqrt(variance)[:, None], (50, 2))], 1)
    expected = jnp.concatenate([start[:, :6], mean], 1) + scales * jax.random.normal(key, start.shape, start.dtype)
    np.testing.assert_array_equal(drawn, expected)
    for fit in (fit_gpdm_latent_dynamics, fit_latent_dynamics):
        with pytest.raises(ValueError, match="latent_noise must be one of"):
            fit(gpdm_prior, walk[45:], latent_noise="student")
    with pytest.raises(ValueError, match="latent_noise must be one of"):
        fit_mrpf_transition(gpdm_prior, walk[45:], key=getkey(), latent_proposal="gpdm", latent_noise="student")
    assert float(gpdm_noise().jump) == 1.0


def test_noise_fitted_on_validation_motion(gpdm_prior, walk, getkey):
    """``latent_noise="validation"`` fits a valid mixture on the validation poses' projected
    steps, for the GPDM's latent dynamics and MRPF's GPDM proposal alike."""
    fitted = fit_gpdm_latent_dynamics(gpdm_prior, walk[45:], latent_noise="validation")
    noise = fitted.noise
    assert 0.0 <= float(noise.jump_probability) < 1.0 and 0.0 < float(noise.core) <= float(noise.jump)
    mrpf = fit_mrpf_transition(gpdm_prior, walk[45:], key=getkey(), latent_proposal="gpdm", latent_noise="validation")
    np.testing.assert_allclose(float(mrpf.latent_noise.core), float(noise.core), rtol=1e-6)
    # Fewer validation steps than the fit needs: the GPDM's own noise.
    assert float(fit_gpdm_latent_dynamics(gpdm_prior, walk[50:55], latent_noise="validation").noise.jump_probability) == 0.0


@pytest.mark.slow
def test_refinement_keeps_the_mixture_transition_invariant(gpdm_prior, walk, getkey):
    """MALA moves targeting the mixture's ``log_transition`` alone keep a sample of ``propose``."""
    dynamics = GPDMLatentDynamics(gpdm_prior, jnp.full(6, 0.01), noise=MIXTURE)
    check_refinement_keeps_transition(dynamics, jnp.asarray(walk[40]), getkey)


def test_mixture_same_key_same_result_jitted_or_not(gpdm_prior, walk, getkey):
    dynamics = GPDMLatentDynamics(gpdm_prior, jnp.full(6, 0.01), noise=MIXTURE)
    start = dynamics.init(getkey(), jnp.asarray(walk[10]), 64)
    key = getkey()
    jitted = eqx.filter_jit(lambda d, k, x: d.propose(k, x))(dynamics, key, start)[0]
    with jax.disable_jit():
        eager = dynamics.propose(key, start)[0]
    np.testing.assert_allclose(jitted, eager, rtol=1e-9, atol=1e-12)  # XLA fuses the GP prediction differently
    np.testing.assert_array_equal(dynamics.propose(key, start)[0], dynamics.propose(key, start)[0])
