"""Particle filter core: resamplers, weights, and each tracker against a reference with a known
answer (Kalman filter, SIR)."""


import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.filters import (
    RESAMPLERS,
    choose_beta,
    continue_filter,
    effective_sample_size,
    normalise_log_weights,
    run_filter,
    survival_rate,
)
from jaxtrack.manifold import make_manifold_prior
from jaxtrack.tracking import make_apf, make_gpapf, make_latent_pf, make_mrpf, make_sir

from helpers import check_refinement_keeps_transition

# ----------------------------------------------------------------------------- resampling

@pytest.mark.parametrize("name", sorted(RESAMPLERS))
def test_resampler_counts_match_expected_values(name, getkey):
    weights = np.array([0.5, 0.25, 0.125, 0.0625, 0.0625, 0.0, 0.0, 0.0])
    log_w = jnp.log(jnp.asarray(weights))
    n = len(weights)
    keys = jax.random.split(getkey(), 4000)
    indices = jax.vmap(lambda k: RESAMPLERS[name](k, log_w))(keys)
    counts = np.stack([np.bincount(np.asarray(i), minlength=n) for i in indices])
    assert counts.sum(1).tolist() == [n] * len(keys)
    assert counts[:, 5:].sum() == 0  # zero weight: never selected
    mean = counts.mean(0)
    sem = counts.std(0) / np.sqrt(len(keys)) + 1e-9
    assert np.all(np.abs(mean - n * weights) < 5 * sem + 1e-9), (mean, n * weights)
    if name != "multinomial":  # low-variance schemes stay within one of N w_i
        assert np.all(np.abs(counts - n * weights) < 1.0 + 1e-9)


@pytest.mark.slow  # 9 s or more on 2 cores with an empty compilation cache (docs/testing.md, 2026-11-27)
def test_degenerate_weights_are_uniform_and_finite(getkey):
    for bad in (jnp.full(5, -jnp.inf), jnp.full(5, jnp.nan), jnp.array([jnp.nan, -jnp.inf, jnp.nan, -jnp.inf, -jnp.inf])):
        normalised, degenerate = normalise_log_weights(bad)
        assert bool(degenerate)
        np.testing.assert_allclose(normalised, -np.log(5) * np.ones(5))
        assert float(effective_sample_size(bad)) == pytest.approx(5.0)
        for resample in RESAMPLERS.values():
            idx = np.asarray(resample(getkey(), bad))
            assert idx.min() >= 0 and idx.max() < 5
    normalised, degenerate = normalise_log_weights(jnp.array([0.0, jnp.nan, -jnp.inf, 1.0]))
    assert not bool(degenerate)
    np.testing.assert_allclose(np.exp(normalised), [1 / (1 + np.e), 0, 0, np.e / (1 + np.e)], atol=1e-12)


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-27)
def test_choose_beta_hits_the_survival_target(getkey):
    log_lik = -50.0 * jax.random.uniform(getkey(), (300,)) ** 2
    beta = choose_beta(log_lik, 0.5)
    assert 0 < float(beta) < 1
    assert float(survival_rate(log_lik, beta)) == pytest.approx(0.5, abs=1e-3)
    assert float(choose_beta(jnp.zeros(10), 0.5)) == 1.0  # a flat likelihood survives at beta = 1


# ----------------------------------------------------------------------------- linear Gaussian

Q = np.array([0.3, 0.2])  # random-walk standard deviations
R = np.array([0.4, 0.5])  # observation standard deviations


def linear_gaussian_data(key, frames=25):
    k1, k2 = jax.random.split(key)
    x = jnp.cumsum(Q * jax.random.normal(k1, (frames, 2)), axis=0)
    return x, x + R * jax.random.normal(k2, (frames, 2))


def gaussian_likelihood(poses, y):
    return -0.5 * jnp.sum(((poses - y) / R) ** 2 + jnp.log(2 * jnp.pi * R**2), axis=1)


def kalman(x0, ys):
    """Exact filter means and log-evidence of the random walk x_t = x_{t-1} + N(0, Q^2), y_t = x_t + N(0, R^2)."""
    mean, var = np.asarray(x0, np.float64), np.zeros(2)
    means, log_evidence = [], 0.0
    for y in np.asarray(ys):
        var = var + Q**2
        s = var + R**2
        log_evidence += float(np.sum(-0.5 * ((y - mean) ** 2 / s + np.log(2 * np.pi * s))))
        gain = var / s
        mean, var = mean + gain * (y - mean), (1 - gain) * var
        means.append(mean)
    return np.array(means), log_evidence


def test_sir_matches_kalman_filter(getkey):
    _truth, ys = linear_gaussian_data(getkey())
    x0 = jnp.zeros(2)
    sir = make_sir(gaussian_likelihood, Q, 4000, dtype=jnp.float64)
    expected_means, expected_evidence = kalman(x0, ys)
    runs = [run_filter(sir, k, x0, ys)[1] for k in jax.random.split(getkey(), 4)]
    means = np.stack([np.asarray(r.estimate) for r in runs])
    evidence = np.array([float(r.log_evidence.sum()) for r in runs])
    posterior_sd = np.sqrt(np.array([0.3**2, 0.2**2]))  # loose bound on the filter sd
    assert np.abs(means.mean(0) - expected_means).max() < 0.05 * posterior_sd.max() + 0.02
    assert abs(evidence.mean() - expected_evidence) < max(4 * evidence.std(), 0.1)


def test_a_filter_continued_from_its_state_is_the_same_filter(getkey):
    """``run_filter`` is ``init`` then ``continue_filter`` with the split keys; a stream tracked in
    two segments carries the particles across, and on the Kalman filter's data its estimates
    are as close to the Kalman means as one pass's."""
    _, ys = linear_gaussian_data(getkey())
    key, x0 = getkey(), jnp.zeros(2)
    sir = make_sir(gaussian_likelihood, Q, 2000, dtype=jnp.float64)
    state, whole = run_filter(sir, key, x0, ys)
    k_init, k_step = jax.random.split(key)
    again_state, again = continue_filter(sir, k_step, sir.init(k_init, x0), ys)
    np.testing.assert_array_equal(again.estimate, whole.estimate)
    assert jax.tree.all(jax.tree.map(lambda a, b: np.array_equal(a, b), again_state, state))
    first_state, first = run_filter(sir, key, x0, ys[:10])
    _, rest = continue_filter(sir, jax.random.fold_in(key, 1), first_state, ys[10:])
    expected, _ = kalman(x0, ys)
    streamed = np.concatenate([first.estimate, rest.estimate])
    # within 0.03-0.04 of the Kalman means at 2000 particles; restarted from x0 at frame 10 instead: 0.25-0.93
    assert np.abs(streamed - expected).max() < 0.07 and np.abs(streamed[10:11] - expected[10:11]).max() < 0.05
    with pytest.raises(ValueError, match="at least one frame"):
        continue_filter(sir, key, state, ys[:0])


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_same_key_same_result_jitted_or_not(getkey):
    _, ys = linear_gaussian_data(getkey(), frames=3)
    key = getkey()
    apf = make_apf(gaussian_likelihood, Q, 20, num_layers=2, dtype=jnp.float64)
    jitted = run_filter(apf, key, jnp.zeros(2), ys)[1]
    with jax.disable_jit():
        eager = run_filter(apf, key, jnp.zeros(2), ys)[1]
    np.testing.assert_allclose(jitted.estimate, eager.estimate, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(jitted.betas, eager.betas, rtol=1e-9)
    again = run_filter(apf, key, jnp.zeros(2), ys)[1]
    np.testing.assert_array_equal(again.estimate, jitted.estimate)


def test_apf_with_one_layer_and_beta_one_equals_sir(getkey):
    _, ys = linear_gaussian_data(getkey(), frames=10)
    key = getkey()
    sir = make_sir(gaussian_likelihood, Q, 200, dtype=jnp.float64)
    apf = make_apf(gaussian_likelihood, Q, 200, num_layers=1, fixed_betas=(1.0,), dtype=jnp.float64)
    a, b = run_filter(sir, key, jnp.zeros(2), ys), run_filter(apf, key, jnp.zeros(2), ys)
    np.testing.assert_allclose(a[1].estimate, b[1].estimate, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(a[1].log_evidence, b[1].log_evidence, rtol=1e-10)
    np.testing.assert_allclose(a[0].particles, b[0].particles, rtol=1e-10, atol=1e-12)


def test_apf_anneals_to_the_survival_target_and_tracks(getkey):
    _truth, ys = linear_gaussian_data(getkey(), frames=20)
    sharp = lambda poses, y: 25.0 * gaussian_likelihood(poses, y)  # noqa: E731  a peaky likelihood
    apf = make_apf(sharp, Q, 100, num_layers=5, dtype=jnp.float64)
    _, info = run_filter(apf, getkey(), jnp.zeros(2), ys)
    assert info.betas.shape == (20, 5) and np.all(np.asarray(info.betas) <= 1.0)
    np.testing.assert_allclose(np.asarray(info.survival)[np.asarray(info.betas) < 1], 0.5, atol=0.02)
    # the annealed estimate follows the sharp likelihood to the observations
    assert np.abs(np.asarray(info.estimate) - np.asarray(ys)).mean() < 0.1


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_partitioned_annealing_moves_each_layers_entries_only(getkey):
    """Partitions naming every entry in every layer are plain annealing, bit for bit; with a flat
    likelihood (weights equal, resampling a random permutation in distribution) a layer that
    perturbs entry 0 alone adds its shrunk variance to entry 0 and nothing to entry 1."""
    _, ys = linear_gaussian_data(getkey(), frames=6)
    key = getkey()
    plain = make_apf(gaussian_likelihood, Q, 100, num_layers=3, dtype=jnp.float64)
    every = make_apf(gaussian_likelihood, Q, 100, num_layers=3, partitions=((0, 1), (1, 0)), dtype=jnp.float64)
    a, b = run_filter(plain, key, jnp.zeros(2), ys), run_filter(every, key, jnp.zeros(2), ys)
    np.testing.assert_array_equal(a[1].estimate, b[1].estimate)
    np.testing.assert_array_equal(a[0].particles, b[0].particles)

    flat = lambda poses, y: jnp.zeros(poses.shape[0], poses.dtype)  # noqa: E731
    first_only = make_apf(flat, Q, 40000, num_layers=2, fixed_betas=(1.0, 1.0), partitions=((0,),), dtype=jnp.float64)
    state, _ = run_filter(first_only, getkey(), jnp.zeros(2), jnp.zeros((1, 2)))
    variance = np.var(np.asarray(state.particles), axis=0)
    np.testing.assert_allclose(variance, [Q[0] ** 2 * (1 + 0.5), Q[1] ** 2], rtol=0.05)  # decay 0.5: layer 1's variance is half


def test_partitions_are_checked_before_tracking():
    with pytest.raises(ValueError, match="partitions has 1 entries for the 2 layers after the first"):
        make_apf(gaussian_likelihood, Q, 10, num_layers=3, partitions=((0,),))
    with pytest.raises(ValueError, match=r"partitions\[0\] \(layer 1\) must be distinct non-negative state indices"):
        make_apf(gaussian_likelihood, Q, 10, num_layers=2, partitions=((0, 0),))
    with pytest.raises(ValueError, match="partitions name state entry 2, but the state has 2 entries"):
        run_filter(make_apf(gaussian_likelihood, Q, 10, num_layers=2, partitions=((2,),)), jax.random.key(0), jnp.zeros(2),
                   jnp.zeros((3, 2)))


def shifted_likelihood(poses, y):
    """A second Gaussian likelihood (the observation read 0.5 higher), standing in for a coarse level."""
    return gaussian_likelihood(poses, y + 0.5)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_coarse_to_fine_layers_score_with_the_coarse_likelihood(getkey):
    """Coarse-to-fine annealing: a coarse likelihood equal to the fine one is plain annealing, bit
    for bit; every layer coarse is plain annealing on the coarse likelihood, bit for bit; and with
    the first layer coarse the last layer's weights are the fine likelihood's, tempered."""
    from jaxtrack.likelihood import FunctionLikelihood

    _, ys = linear_gaussian_data(getkey(), frames=5)
    key = getkey()
    fine, coarse = FunctionLikelihood(gaussian_likelihood), FunctionLikelihood(shifted_likelihood)
    plain = make_apf(gaussian_likelihood, Q, 200, num_layers=3, dtype=jnp.float64)
    on_coarse = make_apf(shifted_likelihood, Q, 200, num_layers=3, dtype=jnp.float64)
    same = make_apf(gaussian_likelihood, Q, 200, num_layers=3, coarse_likelihood=fine, coarse_layers=2, dtype=jnp.float64)
    all_coarse = make_apf(gaussian_likelihood, Q, 200, num_layers=3, coarse_likelihood=coarse, coarse_layers=3, dtype=jnp.float64)
    for a, b in ((plain, same), (on_coarse, all_coarse)):
        (state_a, info_a), (state_b, info_b) = run_filter(a, key, jnp.zeros(2), ys), run_filter(b, key, jnp.zeros(2), ys)
        np.testing.assert_array_equal(info_a.estimate, info_b.estimate)
        np.testing.assert_array_equal(state_a.particles, state_b.particles)

    first_coarse = make_apf(gaussian_likelihood, Q, 200, num_layers=3, coarse_likelihood=coarse, coarse_layers=1, dtype=jnp.float64)
    state, info = run_filter(first_coarse, key, jnp.zeros(2), ys)
    weights = np.asarray(state.log_weights) - np.logaddexp.reduce(np.asarray(state.log_weights))
    expected = float(info.betas[-1, -1]) * np.asarray(gaussian_likelihood(state.particles, ys[-1]))
    np.testing.assert_allclose(weights, expected - np.logaddexp.reduce(expected), atol=1e-9)
    assert not np.allclose(np.asarray(info.estimate), np.asarray(run_filter(plain, key, jnp.zeros(2), ys)[1].estimate))


def test_coarse_layers_are_checked_before_tracking():
    from jaxtrack.likelihood import FunctionLikelihood

    with pytest.raises(ValueError, match=r"coarse_layers must be an integer in \[0, 3\]"):
        make_apf(gaussian_likelihood, Q, 10, num_layers=3, coarse_likelihood=FunctionLikelihood(gaussian_likelihood),
                 coarse_layers=4)
    with pytest.raises(ValueError, match="coarse_layers=1 needs a coarse_likelihood"):
        make_apf(gaussian_likelihood, Q, 10, num_layers=3, coarse_layers=1)
    with pytest.raises(TypeError, match="coarse_likelihood"):  # the type check, or check_coarse_layers without it
        make_apf(gaussian_likelihood, Q, 10, num_layers=3, coarse_likelihood=gaussian_likelihood, coarse_layers=1)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_apf_final_layer_is_a_layer_after_the_annealing_and_traces_the_likelihood_once(getkey):
    """The final full-pose layer (001 Alg. 3), run inside the annealing scan, equals the APF
    without it followed by one ``smc_layer`` of the final dynamics on the annealed particles'
    poses: the same carried particles and weights, the estimate the final layer's weighted
    mean; and the likelihood is traced once per step (one copy for XLA to compile)."""
    from jaxtrack.dynamics import PoseRandomWalk
    from jaxtrack.filters import APF, FilterState, WeightedMean, smc_layer, systematic
    from jaxtrack.likelihood import FunctionLikelihood

    traces = []

    def counted(poses, y):
        traces.append(1)
        return 4.0 * gaussian_likelihood(poses, y)

    plain = make_apf(counted, Q, 64, num_layers=3, dtype=jnp.float64)
    final = PoseRandomWalk(jnp.array([0.05, 0.04]))
    with_final = APF(plain.dynamics, plain.likelihood, 64, 3, final_layer=final)
    _, ys = linear_gaussian_data(getkey(), frames=2)
    state = with_final.init(getkey(), jnp.zeros(2))
    state = FilterState(state.particles + 0.3 * jax.random.normal(getkey(), state.particles.shape), state.log_weights)
    key = getkey()
    step = eqx.filter_jit(lambda f, k, s, y: f.step(k, s, y))
    new_state, info = step(with_final, key, state, ys[1])
    assert len(traces) == 1
    anneal_key, final_key = jax.random.split(key)
    reference, reference_info = step(plain, anneal_key, state, ys[1])
    moved, weights, last = smc_layer(tuple(jax.random.split(final_key)), plain.dynamics.to_pose(reference.particles),
                                     reference.log_weights, move=final.propose,
                                     log_likelihood=lambda x: FunctionLikelihood(counted)(final.to_pose(x), ys[1]),
                                     resample=systematic, temper=lambda log_lik: choose_beta(log_lik, 0.5))
    np.testing.assert_allclose(new_state.particles, reference.particles, rtol=1e-12)
    np.testing.assert_allclose(new_state.log_weights, reference.log_weights, rtol=1e-12)
    np.testing.assert_allclose(info.estimate, WeightedMean()(weights, moved, final), rtol=1e-12)
    np.testing.assert_allclose(info.betas, reference_info.betas, rtol=1e-12)
    assert info.betas.shape == (3,) and bool(info.degenerate) == bool(reference_info.degenerate | last.degenerate)


def test_all_minus_infinity_weights_do_not_leak_nans(getkey):
    _, ys = linear_gaussian_data(getkey(), frames=5)
    impossible = lambda poses, y: jnp.full(poses.shape[0], -jnp.inf)  # noqa: E731
    for tracker in (make_sir(impossible, Q, 20, dtype=jnp.float64), make_apf(impossible, Q, 20, num_layers=2, dtype=jnp.float64)):
        state, info = run_filter(tracker, getkey(), jnp.zeros(2), ys)
        for leaf in (info.estimate, info.ess, info.betas, info.survival, state.particles, state.log_weights):
            assert not np.any(np.isnan(np.asarray(leaf)))
        assert bool(np.all(np.asarray(info.degenerate)))
        np.testing.assert_allclose(info.ess, 20.0)


def test_bad_filter_arguments():
    with pytest.raises(ValueError, match=r"scales must have shape \(D,\)"):
        make_sir(gaussian_likelihood, jnp.ones((2, 2)), 10)
    with pytest.raises(ValueError, match="num_particles must be a positive integer"):
        make_sir(gaussian_likelihood, Q, 0)
    with pytest.raises(ValueError, match="unknown resampler 'magic'"):
        make_sir(gaussian_likelihood, Q, 10, resampler="magic")
    with pytest.raises(ValueError, match="fixed_betas has 1 entries for 3 layers"):
        make_apf(gaussian_likelihood, Q, 10, num_layers=3, fixed_betas=(1.0,))
    sir = make_sir(gaussian_likelihood, Q, 10)
    with pytest.raises(ValueError, match="initial_pose contains NaN"):
        run_filter(sir, jax.random.key(0), jnp.array([0.0, jnp.nan]), jnp.zeros((3, 2)))
    with pytest.raises(ValueError, match="at least one frame"):
        run_filter(sir, jax.random.key(0), jnp.zeros(2), jnp.zeros((0, 2)))


# ----------------------------------------------------------------------------- manifold trackers

@pytest.fixture(scope="module")
def walk_prior():
    from jaxtrack.data import generate_motion
    from jaxtrack.manifold import make_bc_gplvm

    motion = generate_motion("walk", "S1", num_frames=60, fps=30.0, key=jax.random.key(5), dtype=jnp.float64)
    poses = np.asarray(motion.pose)
    model = make_bc_gplvm(poses[:40, 6:], 2)  # PCA-initialised, unfitted: enough to exercise the filters
    return make_manifold_prior(model, poses.shape[1]), poses


def pose_likelihood(poses, target):
    """A Gaussian likelihood around a target pose (a stand-in for the silhouette likelihood)."""
    return -0.5 * jnp.sum(((poses - target) / 0.05) ** 2, axis=1)


# "prior": moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-28)
@pytest.mark.parametrize("proposal", ["product", pytest.param("prior", marks=pytest.mark.slow)])
def test_mrpf_with_a_flat_manifold_term_equals_sir(walk_prior, getkey, proposal):
    prior, poses = walk_prior
    key = getkey()
    s_xx = np.full(32, 0.02)
    sir = make_sir(pose_likelihood, s_xx, 100, dtype=jnp.float64)
    mrpf = make_mrpf(pose_likelihood, prior, s_xx, s_xz=0.1, s_zx=1e8, num_particles=100, dtype=jnp.float64, proposal=proposal)
    observations = jnp.asarray(poses[41:49])
    a, b = run_filter(sir, key, jnp.asarray(poses[40]), observations), run_filter(mrpf, key, jnp.asarray(poses[40]), observations)
    np.testing.assert_allclose(a[1].estimate, b[1].estimate, rtol=1e-9, atol=1e-10)
    # and a tight manifold term changes the answer
    tight = make_mrpf(pose_likelihood, prior, s_xx, s_xz=0.1, s_zx=0.01, num_particles=100, dtype=jnp.float64, proposal=proposal)
    c = run_filter(tight, key, jnp.asarray(poses[40]), observations)
    assert np.abs(np.asarray(c[1].estimate) - np.asarray(a[1].estimate)).max() > 1e-4


@pytest.mark.slow  # 9 s or more on 2 cores with an empty compilation cache (docs/testing.md, 2026-11-27)
def test_mrpf_with_an_overflowing_manifold_scale_stays_finite(walk_prior, getkey):
    """A manifold scale that overflows float32 (a fitted s_zx the data leave unbounded) makes the
    float32 MRPF exactly SIR, with no NaN (a Bandai run once gave s_zx = 2e47)."""
    prior, poses = walk_prior
    key = getkey()
    s_xx = np.full(32, 0.02)
    s_zx = np.full(26, 0.05)
    s_zx[0] = 2e47
    observations = jnp.asarray(poses[41:45], jnp.float32)
    mrpf = make_mrpf(pose_likelihood, prior, s_xx, s_xz=0.1, s_zx=s_zx, num_particles=50)
    state, info = run_filter(mrpf, key, jnp.asarray(poses[40], jnp.float32), observations)
    assert np.all(np.isfinite(np.asarray(info.estimate))) and np.all(np.isfinite(np.asarray(state.particles)))
    flat = make_mrpf(pose_likelihood, prior, s_xx, s_xz=0.1, s_zx=np.full(26, 2e47), num_particles=50)
    sir = make_sir(pose_likelihood, s_xx, 50)
    a = run_filter(flat, key, jnp.asarray(poses[40], jnp.float32), observations)[1].estimate
    b = run_filter(sir, key, jnp.asarray(poses[40], jnp.float32), observations)[1].estimate
    np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-6)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_mrpf_product_proposal_samples_the_transition(walk_prior, getkey):
    """With a flat image likelihood, one MRPF step with the product proposal is a sample of
    000 eqs. 27-28: its moments match a direct Monte-Carlo of z ~ N(g(x0), s_xz^2),
    x ~ N(m(z), v); its weights stay uniform, while Alg. 1's eq. 30 weights do not."""
    prior, poses = walk_prior
    flat = lambda x, obs: jnp.zeros(x.shape[0], x.dtype)  # noqa: E731
    s_xx, s_xz, s_zx = np.full(32, 0.05), 0.05, np.full(26, 0.03)
    start = jnp.asarray(poses[40])
    n = 40000
    mrpf = make_mrpf(flat, prior, s_xx, s_xz=s_xz, s_zx=s_zx, num_particles=n, dtype=jnp.float64)
    state, info = run_filter(mrpf, getkey(), start, jnp.zeros((1, 1)))
    x = np.asarray(mrpf.dynamics.to_pose(state.particles))
    assert state.particles.shape == (n, 32 + 2)  # the state carries the latent draw
    np.testing.assert_allclose(float(info.ess[0]), n, rtol=1e-9)
    # the reference, written out from the equations
    z = np.asarray(prior.encode(start[None, 6:]))[0] + s_xz * np.asarray(jax.random.normal(getkey(), (n, 2), jnp.float64))
    mu = np.asarray(prior.decode_mean(jnp.asarray(z)))
    var_xx, var_zx = 0.05**2, 0.03**2
    m = (var_zx * np.asarray(start[6:]) + var_xx * mu) / (var_xx + var_zx)
    reference = m + np.sqrt(var_xx * var_zx / (var_xx + var_zx)) * np.asarray(jax.random.normal(getkey(), m.shape, jnp.float64))
    angles = x[:, 6:]
    sem = np.sqrt(angles.var(0) / n + reference.var(0) / n)
    assert np.all(np.abs(angles.mean(0) - reference.mean(0)) < 5 * sem), np.max(np.abs(angles.mean(0) - reference.mean(0)) / sem)
    np.testing.assert_allclose(angles.var(0), reference.var(0), rtol=0.05)
    np.testing.assert_allclose(x[:, :6].std(0), 0.05, rtol=0.03)  # global entries: eq. 29 only
    printed = make_mrpf(flat, prior, s_xx, s_xz=s_xz, s_zx=s_zx, num_particles=n, dtype=jnp.float64, proposal="prior")
    assert float(run_filter(printed, getkey(), start, jnp.zeros((1, 1)))[1].ess[0]) < 0.5 * n
    with pytest.raises(ValueError, match="proposal must be one of"):
        make_mrpf(flat, prior, s_xx, 0.05, s_zx, 10, proposal="optimal")


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_latent_filters_follow_the_manifold(walk_prior, getkey):
    """GPAPF and LatentPF estimate poses on the manifold close to the observed target poses."""
    prior, poses = walk_prior
    observations = jnp.asarray(poses[40:50])
    recon_error = np.abs(np.asarray(prior.decode_mean(prior.encode(observations[:, 6:]))) - np.asarray(observations[:, 6:])).mean()
    for tracker in (
        make_gpapf(pose_likelihood, prior, np.full(6, 0.02), np.full(2, 0.2), 60, 3, dtype=jnp.float64),
        make_gpapf(pose_likelihood, prior, np.full(6, 0.02), np.full(2, 0.2), 60, 3, s_final=np.full(32, 0.01), dtype=jnp.float64),
        make_latent_pf(pose_likelihood, prior, np.full(6, 0.02), np.full(2, 0.2), 200, dtype=jnp.float64),
    ):
        _state, info = run_filter(tracker, getkey(), observations[0], observations)
        error = np.abs(np.asarray(info.estimate) - np.asarray(observations)).mean()
        assert np.all(np.isfinite(np.asarray(info.estimate)))
        assert error < 3 * recon_error + 0.01, (type(tracker).__name__, error, recon_error)
    with pytest.raises(ValueError, match="needs a back-constrained manifold"):
        from jaxtrack.manifold import make_gplvm

        plain = make_manifold_prior(make_gplvm(poses[:40, 6:], 2), 32)
        make_mrpf(pose_likelihood, plain, 0.02, 0.1, 0.1, 10)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_dynamics_fitted_on_validation(walk_prior, getkey):
    """Each dynamics fits its own parameters: the RMS step for the pose walk, the global RMS step
    and the training latent RMS step for the latent walk, and MRPF's joint fit."""
    from jaxtrack.dynamics import fit_latent_random_walk, fit_mrpf_transition, fit_pose_random_walk

    prior, poses = walk_prior
    walk = fit_pose_random_walk(poses[40:])
    steps = np.diff(poses[40:], axis=0)
    np.testing.assert_allclose(walk.scales, np.maximum(np.sqrt((steps**2).mean(0)), 1e-3))
    latent = fit_latent_random_walk(prior, poses[40:])
    np.testing.assert_allclose(latent.s_global, walk.scales[:6])
    train_steps = np.diff(np.asarray(prior.training_latent), axis=0)
    np.testing.assert_allclose(latent.s_latent, np.maximum(np.sqrt((train_steps**2).mean(0)), 1e-3))
    mrpf = fit_mrpf_transition(prior, poses[40:], key=getkey())
    assert mrpf.s_xz.shape == (2,) and mrpf.s_zx.shape == (26,) and mrpf.proposal == "product"
    np.testing.assert_array_equal(mrpf.s_xx[:6], walk.scales[:6])  # global entries: eq. 29 only
    assert np.all(np.asarray(mrpf.s_zx) >= 1e-3) and np.all(np.isfinite(np.asarray(mrpf.s_xx)))
    assert np.all(np.asarray(mrpf.s_xx[6:]) <= 10 * np.asarray(walk.scales[6:]) + 1e-12)
    printed = fit_mrpf_transition(prior, poses[40:], key=getkey(), proposal="prior")
    np.testing.assert_allclose(printed.s_xx, walk.scales)  # Alg. 1 as printed keeps the separate fit
    with pytest.raises(ValueError, match=r"validation poses must be \(T >= 2, 32\)"):
        fit_pose_random_walk([poses[:1]])
    with pytest.raises(ValueError, match=r"validation poses must be \(T >= 2, 32\)"):
        fit_latent_random_walk(prior, poses[:1])
    with pytest.raises(ValueError, match="proposal must be one of"):
        fit_mrpf_transition(prior, poses[40:], key=getkey(), proposal="optimal")


def eq28_pairs(key, s_xx, s_zx, t):
    """(previous, mu, current), each (t, A) float64: previous poses, manifold means near them and
    current poses drawn from 000 eq. 28 normalised, with scales s_xx, s_zx (A,)."""
    keys = jax.random.split(key, 3)
    a = len(s_xx)
    previous = np.asarray(jax.random.normal(keys[0], (t, a), jnp.float64)) * 0.3
    mu = previous + 0.1 * np.asarray(jax.random.normal(keys[1], (t, a), jnp.float64))
    total = s_xx**2 + s_zx**2
    mean = (s_zx**2 * previous + s_xx**2 * mu) / total
    current = mean + np.sqrt(s_xx**2 * s_zx**2 / total) * np.asarray(jax.random.normal(keys[2], (t, a), jnp.float64))
    return previous, mu, current


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_transition_scales_recover_the_generating_ones(getkey):
    """Pose pairs drawn from 000 eq. 28 (normalised) with known s_xx, s_zx: the maximum-likelihood
    fit recovers them, the objective's autodiff gradient vanishes there, and moving any log-scale
    by +-0.05 lowers it."""
    from jaxtrack.dynamics import fit_transition_scales, transition_log_likelihood

    t, a = 4000, 3
    s_xx, s_zx = np.array([0.05, 0.02, 0.08]), np.array([0.02, 0.04, 0.01])
    previous, mu, current = eq28_pairs(getkey(), s_xx, s_zx, t)
    fit_xx, fit_zx = fit_transition_scales([(previous, current)], [mu[None]], np.full(a, 0.03), np.full(a, 0.03), floor=1e-6)
    np.testing.assert_allclose(fit_xx, s_xx, rtol=0.08)
    np.testing.assert_allclose(fit_zx, s_zx, rtol=0.08)
    objective = lambda log_s: transition_log_likelihood(previous, current, mu[None], jnp.exp(log_s[:a]), jnp.exp(log_s[a:]))  # noqa: E731
    at = jnp.log(jnp.concatenate([jnp.asarray(fit_xx), jnp.asarray(fit_zx)]))
    assert float(jnp.max(jnp.abs(jax.grad(objective)(at)))) < 1e-4
    for i in range(2 * a):
        for step in (-0.05, 0.05):
            assert float(objective(at.at[i].add(step))) < float(objective(at))


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_tied_transition_scales_share_one_pair_per_group(walk_prior, getkey):
    """Angles 0 and 2 drawn with the same eq. 28 scales and tied: the fit recovers that pair once
    for both and angle 1's own; it scores at least the untied fit's scales pooled per group.
    ``mirrored_groups`` pairs the HumanEva skeleton's left and right angles; MRPF's fit ties
    them, and bad groups are refused."""
    from jaxtrack.body import humaneva_skeleton, mirrored_groups
    from jaxtrack.dynamics import fit_mrpf_transition, fit_transition_scales, transition_log_likelihood

    t, a = 4000, 3
    s_xx, s_zx = np.array([0.05, 0.02, 0.05]), np.array([0.02, 0.04, 0.02])
    previous, mu, current = eq28_pairs(getkey(), s_xx, s_zx, t)
    groups = np.array([0, 1, 0])
    start = np.full(a, 0.03)
    tied_xx, tied_zx = fit_transition_scales([(previous, current)], [mu[None]], start, start, floor=1e-6, groups=groups)
    assert tied_xx[0] == tied_xx[2] and tied_zx[0] == tied_zx[2]
    np.testing.assert_allclose(tied_xx, s_xx, rtol=0.08)
    np.testing.assert_allclose(tied_zx, s_zx, rtol=0.08)
    free_xx, free_zx = fit_transition_scales([(previous, current)], [mu[None]], start, start, floor=1e-6)
    pool = lambda v: np.sqrt(np.array([(v[0] ** 2 + v[2] ** 2) / 2, v[1] ** 2, (v[0] ** 2 + v[2] ** 2) / 2]))  # noqa: E731
    score = lambda xx, zx: float(transition_log_likelihood(previous, current, mu[None], xx, zx))  # noqa: E731
    assert score(tied_xx, tied_zx) >= score(pool(free_xx), pool(free_zx)) - 1e-9

    names = humaneva_skeleton().dof_names[3:]
    mirrored = mirrored_groups(names)
    assert mirrored.max() + 1 == 16
    assert mirrored[names.index("lshoulder_flex")] == mirrored[names.index("rshoulder_flex")]
    assert mirrored[names.index("lknee_flex")] == mirrored[names.index("rknee_flex")]
    assert len({mirrored[names.index(n)] for n in ("spine_flex", "neck_twist", "lhip_flex")}) == 3
    prior, poses = walk_prior
    mrpf = fit_mrpf_transition(prior, poses[40:], key=getkey(), tied=mirrored, samples=8)
    for left, right in (("lhip_flex", "rhip_flex"), ("lelbow_flex", "relbow_flex")):
        i, j = names.index(left), names.index(right)
        assert mrpf.s_zx[i] == mrpf.s_zx[j] and mrpf.s_xx[6 + i] == mrpf.s_xx[6 + j]
    with pytest.raises(ValueError, match="tied must be 26 integer group ids"):
        fit_mrpf_transition(prior, poses[40:], key=getkey(), tied=mirrored[:5])
    with pytest.raises(ValueError, match=r"tied must number its groups 0\.\.G-1"):
        fit_mrpf_transition(prior, poses[40:], key=getkey(), tied=mirrored + 1)



@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_manifold_weight_raises_eq30_to_its_power(walk_prior, getkey):
    """``manifold_weight`` lambda: the same fit (same key) with eq. 30's scales over sqrt(lambda),
    eq. 29's unchanged; so the transition's density is eq. 29 times eq. 30 to the power lambda,
    normalised (the draw's mean moves towards mu(z) by the pull s_xx^2 / (s_xx^2 + s_zx^2 / lambda));
    scales at the floor stay there.
    Non-positive or non-finite weights are refused before anything is fitted."""
    from jaxtrack.dynamics import fit_mrpf_transition

    prior, poses = walk_prior
    key = getkey()
    plain = fit_mrpf_transition(prior, poses[40:], key=key, samples=8)
    weighted = fit_mrpf_transition(prior, poses[40:], key=key, samples=8, manifold_weight=4.0)
    np.testing.assert_array_equal(weighted.s_xx, plain.s_xx)
    np.testing.assert_allclose(weighted.s_zx, np.maximum(plain.s_zx / 2.0, 1e-3), rtol=1e-12)
    previous = jnp.asarray(poses[40:43])
    mean_mu = prior.decode_mean(prior.encode(jnp.asarray(poses[41:44, 6:])))
    g = prior.global_dims
    for transition in (plain, weighted):
        mean, sd = transition._product(previous, mean_mu)
        xx, zx = plain.s_xx[g:] ** 2, transition.s_zx**2  # the normalised product of eq. 29 and eq. 30 ** lambda, by hand
        np.testing.assert_allclose(mean[:, g:], (zx * previous[:, g:] + xx * mean_mu) / (xx + zx), rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(sd[g:], np.sqrt(xx * zx / (xx + zx)), rtol=1e-6)
    for bad in (0.0, -1.0, float("inf"), float("nan")):
        with pytest.raises(ValueError, match="manifold_weight must be positive and finite"):
            fit_mrpf_transition(prior, poses[40:], key=key, manifold_weight=bad)

# ----------------------------------------------------------------------------- the SMC layer and its pieces

def test_smc_layer_weights_are_tempered_likelihood_plus_correction(getkey):
    """One layer by hand: with identity resampling, the moved particles are what ``move`` gave,
    and the new log-weights are ``beta * l + correction`` normalised."""
    from jaxtrack.filters import layer_keys, smc_layer

    particles = jax.random.normal(getkey(), (6, 2), jnp.float64)
    correction = jnp.linspace(-1.0, 0.0, 6)

    def move(key, x):
        return x + 1.0, correction

    def log_likelihood(x):
        return -jnp.sum(x**2, axis=1)

    def keep(key, log_weights):
        return jnp.arange(log_weights.shape[0])

    moved, log_weights, info = smc_layer(
        layer_keys(getkey(), 0), particles, jnp.zeros(6), move=move, log_likelihood=log_likelihood, resample=keep,
        temper=lambda l: jnp.asarray(0.3, l.dtype),
    )
    np.testing.assert_allclose(moved, particles + 1.0)
    expected = 0.3 * log_likelihood(particles + 1.0) + correction
    np.testing.assert_allclose(log_weights, expected - jax.nn.logsumexp(expected), rtol=1e-12)
    assert float(info.beta) == pytest.approx(0.3) and not bool(info.degenerate)
    np.testing.assert_allclose(info.ess, 1.0 / np.sum(np.exp(2 * np.asarray(log_weights))), rtol=1e-12)
    np.testing.assert_allclose(info.log_evidence, jax.nn.logsumexp(log_likelihood(particles + 1.0)) - np.log(6), rtol=1e-12)


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-28)
def test_latent_condensation_is_sir_is_one_layer_apf(walk_prior, getkey):
    """003 Alg. 2 (LatentPF) is SIR over latent states, and APF with one layer and beta = 1 is
    the same filter: equal particles for the same key."""
    from jaxtrack.filters import APF, SIR, StateMean

    prior, poses = walk_prior
    latent_pf = make_latent_pf(pose_likelihood, prior, np.full(6, 0.02), np.full(2, 0.2), 80, dtype=jnp.float64)
    sir = SIR(latent_pf.dynamics, latent_pf.likelihood, 80, estimator=StateMean())
    apf = APF(latent_pf.dynamics, latent_pf.likelihood, 80, 1, fixed_betas=(1.0,), estimator=StateMean())
    key, observations = getkey(), jnp.asarray(poses[40:46])
    results = [run_filter(f, key, observations[0], observations) for f in (latent_pf, sir, apf)]
    for state, info in results[1:]:
        np.testing.assert_allclose(state.particles, results[0][0].particles, rtol=1e-12)
        np.testing.assert_allclose(info.estimate, results[0][1].estimate, rtol=1e-12)


@pytest.mark.slow  # moved to the slow suite for the default suite's 10 minutes
def test_runs_vmapped_over_keys_equal_separate_runs(walk_prior, getkey):
    """``jax.vmap`` of ``run_filter`` over keys gives each run's own result (MRPF and GPAPF with
    its final layer), and jit equals no jit (MRPF; the APF's is tested above)."""
    prior, poses = walk_prior
    observations = jnp.asarray(poses[41:43])
    trackers = (
        make_mrpf(pose_likelihood, prior, np.full(32, 0.02), 0.1, np.full(26, 0.05), 30, dtype=jnp.float64),
        make_gpapf(pose_likelihood, prior, np.full(6, 0.02), np.full(2, 0.2), 20, 2, s_final=np.full(32, 0.01), dtype=jnp.float64),
    )
    keys = jax.random.split(getkey(), 3)
    for number, tracker in enumerate(trackers):
        _, batched = jax.vmap(lambda k, t=tracker: run_filter(t, k, jnp.asarray(poses[40]), observations))(keys)
        for i, key in enumerate(keys):
            _, single = run_filter(tracker, key, jnp.asarray(poses[40]), observations)
            np.testing.assert_allclose(batched.estimate[i], single.estimate, rtol=1e-9, atol=1e-12)
        if number:
            continue
        with jax.disable_jit():
            _, eager = run_filter(tracker, keys[0], jnp.asarray(poses[40]), observations)
        np.testing.assert_allclose(eager.estimate, batched.estimate[0], rtol=1e-8, atol=1e-10)


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-27)
def test_estimators(walk_prior, getkey):
    from jaxtrack.dynamics import make_pose_random_walk
    from jaxtrack.filters import BestParticle, ProjectedMean, StateMean, WeightedMean, make_estimator

    prior, poses = walk_prior
    states = jnp.asarray(poses[:5])
    log_weights = jnp.log(jnp.array([0.1, 0.2, 0.4, 0.2, 0.1]))
    walk = make_pose_random_walk(np.full(32, 0.1), dtype=jnp.float64)
    np.testing.assert_allclose(WeightedMean()(log_weights, states, walk), np.exp(log_weights) @ np.asarray(states))
    np.testing.assert_allclose(BestParticle()(log_weights, states, walk), states[2])
    np.testing.assert_allclose(StateMean()(log_weights, states, walk), np.exp(log_weights) @ np.asarray(states))
    projected = ProjectedMean(prior)(log_weights, states, walk)
    mean = np.exp(log_weights) @ np.asarray(states)
    np.testing.assert_allclose(projected[:6], mean[:6])
    np.testing.assert_allclose(projected[6:], prior.decode_mean(prior.encode(jnp.asarray(mean[None, 6:])))[0])
    with pytest.raises(ValueError, match="projects onto a manifold"):
        make_estimator("data_mean")
    with pytest.raises(ValueError, match="estimator must be one of"):
        make_estimator("median")


def test_filters_refuse_parts_of_the_wrong_kind():
    from jaxtrack.dynamics import make_pose_random_walk
    from jaxtrack.filters import APF, SIR
    from jaxtrack.likelihood import as_likelihood

    walk = make_pose_random_walk(Q)
    likelihood = as_likelihood(gaussian_likelihood)
    with pytest.raises(TypeError, match="likelihood"):
        SIR(walk, gaussian_likelihood, 10)
    with pytest.raises(TypeError, match="dynamics"):
        SIR(Q, likelihood, 10)
    with pytest.raises(ValueError, match="variance_decay"):
        APF(walk, likelihood, 10, 2, variance_decay=0.0)
    with pytest.raises(ValueError, match=r"scales must have shape \(D,\)"):
        make_pose_random_walk(jnp.ones((2, 2)))
    with pytest.raises(ValueError, match="finite and non-negative"):
        make_pose_random_walk(np.array([0.1, -1.0]))
    with pytest.raises(TypeError, match="AbstractFilter"):
        run_filter(lambda *a: None, jax.random.key(0), jnp.zeros(2), jnp.zeros((3, 2)))


def test_changing_array_settings_does_not_recompile(getkey):
    """Scales are traced leaves: a second tracker with other scales (or another key) reuses the
    compiled scan; the likelihood function is traced once."""
    from jaxtrack.likelihood import FunctionLikelihood

    traces = []

    def counting_likelihood(poses, y):
        traces.append(1)
        return gaussian_likelihood(poses, y)

    _, ys = linear_gaussian_data(getkey(), frames=4)
    likelihood = FunctionLikelihood(counting_likelihood)
    for scales in (Q, 2 * Q, 0.5 * Q):
        tracker = make_sir(likelihood, scales, 16, dtype=jnp.float64)
        run_filter(tracker, getkey(), jnp.zeros(2), ys)
    assert len(traces) == 1


# ----------------------------------------------------------------------------- gradient-refined particles


def kalman_posterior(x0, ys):
    """Final filtering mean and variance of the linear-Gaussian model of ``kalman``."""
    mean, var = np.asarray(x0, np.float64), np.zeros(2)
    for y in np.asarray(ys):
        var = var + Q**2
        gain = var / (var + R**2)
        mean, var = mean + gain * (y - mean), (1 - gain) * var
    return mean, var


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
@pytest.mark.parametrize(("step_size", "adapt"), [(0.5, True), (3.0, False)])
def test_mala_refined_sir_keeps_the_kalman_posterior(getkey, step_size, adapt):
    """Resample-move with MALA leaves the filtering posterior unchanged: the refined SIR's final
    particles have the Kalman filter's mean and variance, even with a step so large that most
    moves are rejected (the Metropolis test corrects it), while unadjusted Langevin with the
    same step does not."""
    from jaxtrack.filters import LangevinRefinement

    _truth, ys = linear_gaussian_data(getkey(), frames=12)
    x0 = jnp.zeros(2)
    mean, var = kalman_posterior(x0, ys)
    refine = LangevinRefinement(num_steps=3, step_size=step_size, adapt=adapt)
    sir = make_sir(gaussian_likelihood, Q, 20000, dtype=jnp.float64)
    refined = eqx.tree_at(lambda f: f.refine, sir, refine, is_leaf=lambda x: x is None)
    state, info = run_filter(refined, getkey(), x0, ys)
    particles = np.asarray(state.particles)  # uniformly weighted after the move
    np.testing.assert_allclose(particles.mean(0), mean, atol=0.05 * np.sqrt(var.max()))
    np.testing.assert_allclose(particles.var(0), var, rtol=0.06)
    rate = np.asarray(info.refine.acceptance)
    assert rate.shape == (12, 3) and np.all((rate > 0) & (rate <= 1))
    if not adapt:
        assert rate.mean() < 0.5  # the large step is mostly rejected, and still exact
        unadjusted = eqx.tree_at(lambda f: f.refine, sir, LangevinRefinement(3, step_size, metropolis=False, adapt=False),
                                 is_leaf=lambda x: x is None)
        biased = np.asarray(run_filter(unadjusted, getkey(), x0, ys)[0].particles)
        assert np.abs(biased.var(0) / var - 1).max() > 0.2


@pytest.mark.slow
def test_refined_filters_same_key_same_result_jitted_or_not(walk_prior, getkey):
    from jaxtrack.filters import LangevinRefinement

    prior, poses = walk_prior
    observations = jnp.asarray(poses[41:43])
    refine = LangevinRefinement(num_steps=2)
    trackers = [
        make_sir(pose_likelihood, np.full(32, 0.02), 30, dtype=jnp.float64),
        make_apf(pose_likelihood, np.full(32, 0.02), 20, num_layers=2, dtype=jnp.float64),
        make_mrpf(pose_likelihood, prior, np.full(32, 0.02), s_xz=0.1, s_zx=0.05, num_particles=30, dtype=jnp.float64),
    ]
    key = getkey()
    for tracker in trackers:
        tracker = eqx.tree_at(lambda f: f.refine, tracker, refine, is_leaf=lambda x: x is None)
        jitted = run_filter(tracker, key, jnp.asarray(poses[40]), observations)[1]
        with jax.disable_jit():
            eager = run_filter(tracker, key, jnp.asarray(poses[40]), observations)[1]
        np.testing.assert_allclose(jitted.estimate, eager.estimate, rtol=1e-7, atol=1e-9)
        assert np.all(np.isfinite(np.asarray(jitted.estimate)))
        unrefined = run_filter(eqx.tree_at(lambda f: f.refine, tracker, None), key, jnp.asarray(poses[40]), observations)[1]
        assert not np.allclose(unrefined.estimate, jitted.estimate)  # the moves did something


@pytest.mark.slow
def test_refinement_moves_leave_each_transition_invariant(walk_prior, getkey):
    """``log_transition`` is the density ``propose`` draws from: MALA moves targeting it alone
    keep a sample of the transition a sample of it (for every dynamics that can be refined)."""
    from jaxtrack.dynamics import AutoregressivePoseDynamics, LatentRandomWalk, ManifoldRegularisedTransition, PoseRandomWalk

    prior, poses = walk_prior
    d = 32
    cases = [
        PoseRandomWalk(jnp.full(d, 0.05)),
        AutoregressivePoseDynamics(damping=jnp.full(d, 0.8), scales=jnp.full(d, 0.03), initial_speed=jnp.full(d, 0.05)),
        LatentRandomWalk(prior, jnp.full(6, 0.02), jnp.full(2, 0.2)),
        ManifoldRegularisedTransition(prior, jnp.full(d, 0.05), jnp.full(2, 0.1), jnp.full(26, 0.03)),
    ]
    for dynamics in cases:
        check_refinement_keeps_transition(dynamics, jnp.asarray(poses[40]), getkey)


def test_refinement_with_an_impossible_likelihood_leaks_no_nans(getkey):
    from jaxtrack.filters import LangevinRefinement

    impossible = lambda x, y: jnp.full(x.shape[0], -jnp.inf, x.dtype)  # noqa: E731
    sir = make_sir(impossible, Q, 50, dtype=jnp.float64)
    refined = eqx.tree_at(lambda f: f.refine, sir, LangevinRefinement(2), is_leaf=lambda x: x is None)
    _, info = run_filter(refined, getkey(), jnp.zeros(2), jnp.zeros((3, 2)))
    assert np.all(np.isfinite(np.asarray(info.estimate)))
    assert np.all(np.asarray(info.refine.acceptance) == 0)


def test_refinement_needs_a_transition_density():
    from jaxtrack.dynamics import AbstractDynamics
    from jaxtrack.filters import SIR, LangevinRefinement
    from jaxtrack.likelihood import as_likelihood

    class Opaque(AbstractDynamics):
        def init(self, key, pose, num_particles):
            return jnp.broadcast_to(pose, (num_particles, pose.shape[0]))

        def to_pose(self, states):
            return states

        def propose(self, key, previous):
            return previous, jnp.zeros(previous.shape[0])

        def perturb(self, key, states, factor):
            return states

    with pytest.raises(ValueError, match="defines no transition density"):
        SIR(Opaque(), as_likelihood(gaussian_likelihood), 10, refine=LangevinRefinement())
    with pytest.raises(ValueError, match="num_steps must be a positive integer"):
        LangevinRefinement(num_steps=0)


# ----------------------------------------------------------------------------- contracts and chunked runs


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_chunked_run_equals_one_scan_and_reports_each_chunk(getkey):
    """``chunk_frames`` tracks a few frames at a time with the state carried: the same per-frame
    keys, so the same result as one scan, and ``on_chunk`` sees the estimates so far."""
    _, ys = linear_gaussian_data(getkey(), frames=7)
    key = getkey()
    apf = make_apf(gaussian_likelihood, Q, 30, num_layers=2, dtype=jnp.float64)
    whole = run_filter(apf, key, jnp.zeros(2), ys)
    seen = []
    chunked = run_filter(apf, key, jnp.zeros(2), ys, chunk_frames=3, on_chunk=lambda done, infos: seen.append((done, infos.estimate)))
    np.testing.assert_array_equal(chunked[1].estimate, whole[1].estimate)
    np.testing.assert_array_equal(chunked[0].particles, whole[0].particles)
    assert [done for done, _ in seen] == [3, 6, 7]
    for done, estimate in seen:
        np.testing.assert_array_equal(estimate, whole[1].estimate[:done])
    with pytest.raises(ValueError, match="chunk_frames must be a positive integer"):
        run_filter(apf, key, jnp.zeros(2), ys, chunk_frames=0)


@pytest.mark.parametrize(("bad", "message"), [
    (lambda poses, y: jnp.zeros((poses.shape[0], 2)), r"the likelihood FunctionLikelihood returned shape \(16, 2\) for 16 particles"),
    (lambda poses, y: jnp.zeros(()), r"the likelihood FunctionLikelihood returned shape \(\) for 16 particles"),
    (lambda poses, y: jnp.zeros(poses.shape[0], jnp.int32), "the likelihood FunctionLikelihood returned int32 values"),
])
def test_a_likelihood_that_breaks_its_contract_is_named_before_running(bad, message, getkey):
    from jaxtrack.errors import TrackingError
    from jaxtrack.likelihood import FunctionLikelihood

    _, ys = linear_gaussian_data(getkey(), frames=2)
    for tracker in (make_sir(FunctionLikelihood(bad), Q, 16, dtype=jnp.float64),
                    make_apf(FunctionLikelihood(bad), Q, 16, num_layers=2, dtype=jnp.float64)):
        with pytest.raises(TrackingError, match=message):
            run_filter(tracker, getkey(), jnp.zeros(2), ys)


def test_a_filters_matrix_products_are_traced_at_full_float32_precision():
    """``run_filter`` traces every product at ``Precision.HIGHEST``, so a GPU does not run a
    filter's float32 products in TF32 (the manifold trackers lost the demo's people that way on
    an H100); the user's own default is left as it was."""
    import re

    from jaxtrack.dynamics import PoseRandomWalk
    from jaxtrack.filters import SIR
    from jaxtrack.likelihood import as_likelihood

    weights = jnp.ones((4, 3), jnp.float32)
    likelihood = as_likelihood(lambda poses, observation: -jnp.sum((poses @ weights - observation) ** 2, axis=1))
    tracker = SIR(PoseRandomWalk(jnp.full(4, 0.1, jnp.float32)), likelihood, 16)
    text = str(jax.make_jaxpr(lambda key: run_filter(tracker, key, jnp.zeros(4, jnp.float32), jnp.zeros((3, 3), jnp.float32))[1].estimate)(
        jax.random.key(0)))
    precisions = set(re.findall(r"precision=\(?([A-Za-z.]+)", text))
    assert precisions == {"Precision.HIGHEST"}, precisions
    outside = str(jax.make_jaxpr(lambda poses: poses @ weights)(jnp.zeros((2, 4), jnp.float32)))
    assert "HIGHEST" not in outside
