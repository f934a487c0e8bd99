"""The dynamics that move: the Kalman-tracked velocity (any tracker) and the GPDM's latent
dynamics (GPAPF on its paper's manifold), with their noise refitted on validation motion (a
scale mixture of the GPDM's predictive sd: its EM fit against known mixtures, its draws
against its density, and the default that is the GPDM's own noise bit for bit), against
references with known answers."""


import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

from jaxtrack.data import generate_motion
from jaxtrack.dynamics import (
    REST_PROBABILITY,
    GPDMLatentDynamics,
    LatentNoiseMixture,
    LatentRandomWalk,
    ManifoldRegularisedTransition,
    PoseRandomWalk,
    StateVelocity,
    fit_gpdm_latent_dynamics,
    fit_latent_dynamics,
    fit_mrpf_transition,
    fit_pose_random_walk,
    fit_root_velocity,
    fit_scale_mixture,
    fit_state_velocity,
    gpdm_noise,
    heading_to_world,
    world_to_heading,
)
from jaxtrack.filters import APF, SIR, LangevinRefinement, StateMean, run_filter
from jaxtrack.manifold import make_bc_gplvm, make_manifold_prior

from helpers import check_refinement_keeps_transition


def circle(frames, speed, radius, bounce=0.0):
    """Poses (frames, 8) running anticlockwise round a circle, facing along it."""
    angle = speed * np.arange(frames) / radius
    heading = angle + np.pi / 2
    pose = np.zeros((frames, 8))
    pose[:, 0], pose[:, 1] = radius * np.cos(angle), radius * np.sin(angle)
    pose[:, 2] = 1.0 + bounce * np.sin(np.arange(frames))
    pose[:, 3] = heading
    return pose


def test_heading_frame_round_trip_and_fit_of_a_circle(getkey):
    velocity = np.asarray(jax.random.normal(getkey(), (50, 6)))
    yaw = np.asarray(jax.random.uniform(getkey(), (50,), minval=-4, maxval=4))
    np.testing.assert_allclose(world_to_heading(np.asarray(heading_to_world(jnp.asarray(velocity), jnp.asarray(yaw))), yaw), velocity,
                               atol=1e-12)
    # Running round a circle is a constant heading-frame velocity: forward speed and turn rate.
    poses = circle(200, speed=0.05, radius=1.5)
    fit = fit_root_velocity(poses, floor=1e-9)
    np.testing.assert_allclose(np.asarray(fit.initial_speed)[[0, 3]], [0.05, 0.05 / 1.5], rtol=1e-3)
    assert np.all(np.asarray(fit.acceleration)[[0, 1, 3]] < 1e-6)  # no change of velocity
    with pytest.raises(ValueError, match="at least 3 frames"):
        fit_root_velocity(poses[:2])
    with pytest.raises(ValueError, match="global entries"):
        fit_root_velocity(poses[:, :4])


def velocity_entries(dynamics, states):
    """(inner, v, mean, var, anchor, seen) of ``StateVelocity`` states."""
    k, inner = dynamics.size, states.shape[1] - 4 * dynamics.size - 1
    cuts = np.cumsum([inner, k, k, k, k])
    return np.split(np.asarray(states), cuts, axis=1)


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-27)
def test_velocity_moves_particles_round_the_circle(getkey):
    """A known velocity (zero spread, no noise) carries a state round the circle."""
    poses = jnp.asarray(circle(30, speed=0.05, radius=1.5))
    dynamics = StateVelocity(PoseRandomWalk(jnp.zeros(8)), jnp.zeros(6), jnp.zeros(6))
    state = dynamics.init(getkey(), poses[0], 1)
    mean_at = 8 + 6
    state = state.at[0, mean_at : mean_at + 6].set(jnp.array([0.05, 0.0, 0.0, 0.05 / 1.5, 0.0, 0.0]))
    for _ in range(1, 30):
        state, correction = dynamics.propose(getkey(), state)
        np.testing.assert_array_equal(correction, [0.0])
    # The midpoint of each chord is missed by the first-order step; a turn of 1.9 deg/frame
    # drifts by under a millimetre a frame.
    assert np.abs(np.asarray(dynamics.to_pose(state)[0] - poses[29]))[:2].max() < 0.03
    np.testing.assert_allclose(dynamics.to_pose(state)[0, 3], poses[29, 3], atol=1e-9)
    with pytest.raises(ValueError, match="already carries"):
        StateVelocity(dynamics, jnp.zeros(6), jnp.zeros(6))
    with pytest.raises(ValueError, match="at least the 6 global entries"):
        StateVelocity(PoseRandomWalk(jnp.zeros(8)), jnp.zeros(4), jnp.zeros(4))


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_velocity_belief_is_a_kalman_filter_of_the_steps(getkey):
    """Each particle's velocity belief after a path of chosen positions equals a scalar Kalman
    filter, written out in NumPy, of the path's heading-frame steps; the draws have its spread
    and annealing moves leave it alone."""
    a, s0, q = np.array([0.01, 0.02, 0.005, 0.03, 0.01, 0.01]), np.full(6, 0.05), np.array([0.1, 0.1, 0.05, 0.2, 0.1, 0.1])
    dynamics = StateVelocity(PoseRandomWalk(jnp.full(8, 0.3)), jnp.asarray(a), jnp.asarray(s0), jnp.asarray(q))
    path = circle(12, speed=0.04, radius=1.2, bounce=0.02) + 0.01 * np.asarray(jax.random.normal(getkey(), (12, 8)))
    state = dynamics.init(getkey(), jnp.asarray(path[0]), 3)
    mean, var = np.zeros(6), s0**2  # the reference: nothing seen before the first step
    for t in range(1, 12):
        state, _ = dynamics.propose(getkey(), state)
        if t > 1:  # the step into frame t-1 is observed now
            step = path[t - 1, :6] - path[t - 2, :6]
            yaw = path[t - 2, 3]
            seen = np.r_[np.cos(yaw) * step[0] + np.sin(yaw) * step[1], -np.sin(yaw) * step[0] + np.cos(yaw) * step[1], step[2:]]
            gain = var / (var + q**2)
            mean, var = mean + gain * (seen - mean), (1 - gain) * var + a**2
        _, _, got_mean, got_var, anchor, flag = velocity_entries(dynamics, state)
        np.testing.assert_allclose(got_mean, np.tile(mean, (3, 1)), rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(got_var, np.tile(var, (3, 1)), rtol=1e-10)
        np.testing.assert_allclose(anchor, np.tile(path[t - 1, :6], (3, 1)))
        assert np.all(flag == 1.0)
        state = state.at[:, :8].set(jnp.asarray(path[t]))  # the position the likelihood chose
    # The belief never collapses: 20000 copies of one resampled particle draw velocities with
    # the predictive spread, and annealing moves change only the pose.
    copies = jnp.tile(state[:1], (20000, 1))
    drawn = dynamics.propose(getkey(), copies)[0]
    _, v, _, var_next, _, _ = velocity_entries(dynamics, drawn)
    np.testing.assert_allclose(v.std(0), np.sqrt(var_next[0]), rtol=0.03)
    moved = dynamics.perturb(getkey(), drawn, 0.5)
    np.testing.assert_array_equal(moved[:, 8:], drawn[:, 8:])
    np.testing.assert_allclose(np.asarray(moved[:, :8] - drawn[:, :8]).std(0), 0.15, rtol=0.03)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_velocity_log_transition_is_the_proposal_density(getkey):
    """The drawn velocity and the inner step are independent Gaussians: ``log_transition``
    matches the density of what ``propose`` drew, computed by hand."""
    dynamics = StateVelocity(PoseRandomWalk(jnp.full(8, 0.1)), jnp.full(6, 0.02), jnp.full(6, 0.05))
    np.testing.assert_allclose(dynamics.displacement_noise, np.full(6, 0.1))  # the inner walk's, by default
    previous = dynamics.init(getkey(), jnp.asarray(circle(1, 0.05, 1.5)[0]), 7)
    previous = dynamics.propose(getkey(), previous)[0].at[:, :8].add(0.03)  # one step seen
    drawn = dynamics.propose(getkey(), previous)[0]
    v, mean, var = (velocity_entries(dynamics, drawn)[i] for i in (1, 2, 3))
    shifted = previous[:, :8].at[:, :6].add(heading_to_world(jnp.asarray(v), previous[:, 3]))
    expected = -0.5 * jnp.sum(((drawn[:, :8] - shifted) / 0.1) ** 2, 1) - 0.5 * np.sum((v - mean) ** 2 / var + np.log(var), 1)
    np.testing.assert_allclose(dynamics.log_transition(previous, drawn), expected, rtol=1e-12)
    scales = np.asarray(dynamics.noise_scales())
    assert scales.shape == drawn.shape[1:] and np.all(scales[8:14] > 0) and np.all(scales[14:] == 0)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_velocity_that_may_restart_from_rest(getkey):
    """With ``rest_probability`` p a particle draws its velocity from ``N(0, acceleration^2)``
    with probability p, else from its belief: 40000 draws have the mixture's moments and mass
    near zero, ``log_transition`` is the mixture density written out, and p = 0 draws bit for bit
    what the belief alone draws."""
    a, s0 = np.full(6, 0.004), np.full(6, 0.05)
    make = lambda p: StateVelocity(PoseRandomWalk(jnp.full(8, 0.1)), jnp.asarray(a), jnp.asarray(s0), rest_probability=p)  # noqa: E731
    plain, mixed = make(0.0), make(0.25)
    start = plain.init(getkey(), jnp.asarray(circle(1, 0.05, 1.5)[0]), 1)
    previous = plain.propose(getkey(), start)[0].at[:, :6].add(jnp.asarray([0.04, 0.01, 0.0, 0.02, 0.0, 0.0]))  # a step seen
    copies = jnp.tile(previous, (40000, 1))
    key = getkey()
    _, v, mean, var, _, _ = velocity_entries(mixed, mixed.propose(key, copies)[0])
    m, s2 = mean[0], var[0]
    spread = 0.75 * (s2 + m**2) + 0.25 * a**2 - (0.75 * m) ** 2  # the mixture's variance
    np.testing.assert_array_less(np.abs(v.mean(0) - 0.75 * m), 4 * np.sqrt(spread / 40000))
    np.testing.assert_allclose(v.var(0), spread, rtol=0.05)
    near_zero = np.all(np.abs(v) < 4 * a, axis=1).mean()  # the rest component (the belief's mass there is nil)
    assert abs(near_zero - 0.25) < 0.01, near_zero
    before = jnp.tile(previous, (5, 1))
    drawn = mixed.propose(getkey(), before)[0]
    v, mean, var = (velocity_entries(mixed, drawn)[i] for i in (1, 2, 3))
    shifted = before[:, :8].at[:, :6].add(heading_to_world(jnp.asarray(v), before[:, 3]))
    inner = -0.5 * np.sum(((np.asarray(drawn[:, :8]) - np.asarray(shifted)) / 0.1) ** 2, 1)
    belief = -0.5 * np.sum((v - mean) ** 2 / var + np.log(var), 1)
    rest = -0.5 * np.sum(v**2 / a**2 + np.log(a**2), 1)
    expected = inner + np.log(0.75 * np.exp(belief) + 0.25 * np.exp(rest))
    np.testing.assert_allclose(mixed.log_transition(before, drawn), expected, rtol=1e-10)
    np.testing.assert_array_equal(make(0.0).propose(key, copies)[0], plain.propose(key, copies)[0])
    assert fit_root_velocity(circle(20, 0.05, 1.5)).wrap(PoseRandomWalk(jnp.full(8, 0.1))).rest_probability == REST_PROBABILITY
    with pytest.raises(ValueError, match="rest_probability"):
        make(1.0)
    with pytest.raises(ValueError, match="acceleration > 0"):
        StateVelocity(PoseRandomWalk(jnp.full(8, 0.1)), jnp.zeros(6), jnp.asarray(s0), rest_probability=0.25)


def test_each_dynamics_says_which_entries_move(gpdm_prior, walk):
    """``fit_state_velocity`` fits the entries a dynamics supports: the root for a pose random
    walk and the GPDM (whose latent dynamics are its own), root and latent point for a latent
    random walk."""
    from jaxtrack.dynamics import fit_latent_random_walk

    assert fit_state_velocity(PoseRandomWalk(jnp.full(32, 0.1)), walk).acceleration.shape == (6,)
    assert fit_state_velocity(fit_gpdm_latent_dynamics(gpdm_prior, walk[45:]), walk).acceleration.shape == (6,)
    latent_walk = fit_latent_random_walk(gpdm_prior, walk[45:])
    fit = fit_state_velocity(latent_walk, walk)
    assert fit.acceleration.shape == (8,)
    latent = np.asarray(gpdm_prior.encode(jnp.asarray(walk[:, 6:])))
    steps = np.diff(latent, axis=0)
    np.testing.assert_allclose(fit.initial_speed[6:], np.sqrt(np.mean(steps**2, 0)), rtol=1e-9)


def test_gpdm_latent_dynamics_predict_as_the_dynamics_gp(gpdm_prior):
    """The predictive map equals the GP formula written out in NumPy (001 eqs. 7-9)."""
    dyn = gpdm_prior.latent_dynamics
    X = np.asarray(gpdm_prior.training_latent)
    ins = np.r_[0:24, 25:44]
    outs = ins + 1
    kernel = dyn.kernel
    a1, a2, a3 = (float(jnp.exp(v)) for v in (kernel.log_a1, kernel.log_a2, kernel.log_a3))

    def k(a, b):
        return a1 * np.exp(-0.5 * a2 * ((a[:, None] - b[None]) ** 2).sum(-1)) + a3 * a @ b.T

    K = k(X[ins], X[ins]) + float(kernel.noise) * np.eye(len(ins))
    query = X[[3, 30]] + 0.1
    kq = k(query, X[ins])
    mean, variance = gpdm_prior.predict_latent(jnp.asarray(query))
    np.testing.assert_allclose(mean, kq @ np.linalg.solve(K, X[outs]), rtol=1e-6, atol=1e-9)
    expected = np.diag(k(query, query)) - np.sum(kq * np.linalg.solve(K, kq.T).T, 1) + float(kernel.noise)
    np.testing.assert_allclose(variance, expected, rtol=1e-6)
    no_dynamics = make_manifold_prior(make_bc_gplvm(np.asarray(gpdm_prior.training_poses()), 2), 32)
    with pytest.raises(ValueError, match="no latent dynamics"):
        no_dynamics.predict_latent(jnp.zeros((1, 2)))
    with pytest.raises(ValueError, match="no latent dynamics"):
        GPDMLatentDynamics(no_dynamics, jnp.full(6, 0.01))
    # fit_latent_dynamics picks the manifold's own: GPDM dynamics, else the random walk.
    walk = np.asarray(gpdm_prior.training_poses())
    poses = np.concatenate([np.zeros((len(walk), 6)), walk], 1)
    assert isinstance(fit_latent_dynamics(gpdm_prior, poses), GPDMLatentDynamics)
    assert isinstance(fit_latent_dynamics(no_dynamics, poses), LatentRandomWalk)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_gpdm_particles_follow_the_predictive_distribution(gpdm_prior, walk, getkey):
    dynamics = fit_gpdm_latent_dynamics(gpdm_prior, walk[45:])
    start = dynamics.init(getkey(), jnp.asarray(walk[10]), 40000)
    drawn, correction = dynamics.propose(getkey(), start)
    np.testing.assert_array_equal(correction, np.zeros(40000))
    mean, variance = gpdm_prior.predict_latent(start[:1, 6:])
    np.testing.assert_allclose(np.asarray(drawn[:, 6:]).mean(0), mean[0], atol=4 * float(jnp.sqrt(variance[0])) / 200)
    np.testing.assert_allclose(np.asarray(drawn[:, 6:]).std(0), float(jnp.sqrt(variance[0])), rtol=0.02)
    np.testing.assert_allclose(np.asarray(drawn[:, :6]).std(0), dynamics.s_global, rtol=0.02)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_gpdm_gpapf_with_one_layer_and_beta_one_is_latent_sir(gpdm_prior, walk, getkey):
    """An annealed filter with one layer at beta = 1 is the SIR filter of the same dynamics:
    with the same key, the same particles, weights and estimates."""
    dynamics = fit_gpdm_latent_dynamics(gpdm_prior, walk[45:])

    def likelihood(poses, target):
        return -0.5 * jnp.sum(((poses - target) / 0.1) ** 2, axis=1)

    from jaxtrack.likelihood import as_likelihood

    lik = as_likelihood(likelihood)
    apf = APF(dynamics, lik, 64, num_layers=1, fixed_betas=(1.0,), estimator=StateMean())
    sir = SIR(dynamics, lik, 64, estimator=StateMean())
    key = getkey()
    observations = jnp.asarray(walk[11:16])
    final_apf, info_apf = run_filter(apf, key, jnp.asarray(walk[10]), observations)
    final_sir, info_sir = run_filter(sir, key, jnp.asarray(walk[10]), observations)
    np.testing.assert_allclose(final_apf.particles, final_sir.particles, rtol=1e-12)
    np.testing.assert_allclose(info_apf.estimate, info_sir.estimate, rtol=1e-12)
    np.testing.assert_allclose(info_apf.log_evidence, info_sir.log_evidence, rtol=1e-12)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_mrpf_on_a_gpdm_draws_its_latent_points_from_the_gpdm_dynamics(gpdm_prior, walk, getkey):
    """MRPF's GPDM latent proposal: z_t ~ N(mu_X(z_{t-1}), sigma_X^2 I) from the particle's own
    latent point (001 eqs. 7-9), then eq. 28; log_transition is the density it draws from."""
    with pytest.raises(ValueError, match="latent_proposal='gpdm'"):
        fit_mrpf_transition(gpdm_prior, walk[45:], key=getkey())
    with pytest.raises(ValueError, match="latent_proposal must be one of"):
        fit_mrpf_transition(gpdm_prior, walk[45:], key=getkey(), latent_proposal="walk")
    mrpf = fit_mrpf_transition(gpdm_prior, walk[45:], key=getkey(), latent_proposal="gpdm")
    assert isinstance(mrpf, ManifoldRegularisedTransition) and mrpf.latent_proposal == "gpdm"
    _, variance = gpdm_prior.predict_latent(gpdm_prior.encode(jnp.asarray(walk[45:-1, 6:])))
    np.testing.assert_allclose(mrpf.s_xz, np.sqrt(np.mean(np.asarray(variance))), rtol=1e-6)
    start = mrpf.init(getkey(), jnp.asarray(walk[10]), 40000)
    start = start.at[:, 32:].set(start[:, 32:] + 0.3)  # a latent point away from the pose's own
    drawn, correction = mrpf.propose(getkey(), start)
    np.testing.assert_array_equal(correction, np.zeros(40000))
    mean, variance = gpdm_prior.predict_latent(start[:1, 32:])
    sd = float(jnp.sqrt(variance[0]))
    np.testing.assert_allclose(np.asarray(drawn[:, 32:]).mean(0), mean[0], atol=4 * sd / 200)
    np.testing.assert_allclose(np.asarray(drawn[:, 32:]).std(0), sd, rtol=0.02)
    # The density: latent part with its per-particle normaliser, pose part eq. 28.
    previous, states = start[:3], drawn[:3]
    mean3, var3 = gpdm_prior.predict_latent(previous[:, 32:])
    latent_part = np.asarray(-0.5 * jnp.sum((states[:, 32:] - mean3) ** 2, 1) / var3 - jnp.log(var3))
    pose_mean, pose_sd = mrpf._product(previous[:, :32], gpdm_prior.decode_mean(states[:, 32:]))
    pose_part = np.asarray(-0.5 * jnp.sum(((states[:, :32] - pose_mean) / pose_sd) ** 2, 1))
    np.testing.assert_allclose(mrpf.log_transition(previous, states), latent_part + pose_part, rtol=1e-9)


@pytest.mark.slow
def test_new_dynamics_same_key_same_result_jitted_or_not(gpdm_prior, walk, getkey):
    from jaxtrack.likelihood import as_likelihood

    lik = as_likelihood(lambda poses, target: -0.5 * jnp.sum(((poses - target) / 0.1) ** 2, axis=1))
    gpdm = fit_gpdm_latent_dynamics(gpdm_prior, walk[45:])
    velocity = fit_root_velocity(walk[45:])
    trackers = [
        SIR(velocity.wrap(PoseRandomWalk(jnp.full(32, 0.02))), lik, 30),
        APF(velocity.wrap(gpdm), lik, 20, num_layers=2, estimator=StateMean()),
        SIR(gpdm, lik, 30, refine=LangevinRefinement(1)),
        SIR(velocity.wrap(fit_mrpf_transition(gpdm_prior, walk[45:], key=getkey(), latent_proposal="gpdm")), lik, 30),
    ]
    key = getkey()
    observations = jnp.asarray(walk[11:13])
    for tracker in trackers:
        jitted = run_filter(tracker, key, jnp.asarray(walk[10]), observations)[1]
        with jax.disable_jit():
            eager = run_filter(tracker, key, jnp.asarray(walk[10]), observations)[1]
        np.testing.assert_allclose(jitted.estimate, eager.estimate, rtol=1e-7, atol=1e-9)
        assert np.all(np.isfinite(np.asarray(jitted.estimate)))


@pytest.mark.slow
def test_refinement_keeps_the_new_transitions_invariant(gpdm_prior, walk, getkey):
    """MALA moves targeting ``log_transition`` alone keep a sample of ``propose`` a sample of it."""
    cases = [
        StateVelocity(PoseRandomWalk(jnp.full(32, 0.05)), jnp.full(6, 0.01), jnp.full(6, 0.03)),
        StateVelocity(PoseRandomWalk(jnp.full(32, 0.05)), jnp.full(6, 0.01), jnp.full(6, 0.03), rest_probability=0.25),
        fit_gpdm_latent_dynamics(gpdm_prior, walk[45:]),
        # The unfitted GPDM's eq. 28 scales sit at the floor, a ridge no diagonal MALA crosses:
        # moderate scales, the latent draw of the GPDM.
        ManifoldRegularisedTransition(gpdm_prior, jnp.full(32, 0.05), jnp.full(2, 0.1), jnp.full(26, 0.05), latent_proposal="gpdm"),
    ]
    for dynamics in cases:
        check_refinement_keeps_transition(dynamics, jnp.asarray(walk[40]), getkey)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_gpdm_trackers_start_at_the_projection_of_the_first_pose(gpdm_prior, walk):
    """Every dynamics on a GPDM starts its particles at the latent point ``encode`` gives, the
    projection onto the mean surface: for another subject's pose the decoded start is no farther
    (in joint angles) than the nearest training pose's latent point. (That it is nearer than 003
    eq. 5 on a fitted manifold: ``test_manifold.py::test_inverse_mapping``.)"""
    other = np.asarray(generate_motion("walk", "S2", num_frames=30, fps=30.0, key=jax.random.key(8), dtype=jnp.float64).pose)
    pose = jnp.asarray(other[12])
    angles = pose[None, 6:]
    projected = gpdm_prior.encode(angles)
    decoded = lambda z: np.asarray(gpdm_prior.decode_mean(z))[0]  # noqa: E731
    distance = lambda z: float(np.linalg.norm(decoded(z) - np.asarray(angles[0])))  # noqa: E731
    training = np.asarray(gpdm_prior.training_poses())
    nearest = gpdm_prior.training_latent[int(np.argmin(((training - np.asarray(angles)) ** 2).sum(1)))][None]
    assert distance(projected) <= distance(nearest) + 1e-9
    starts = {
        "gpdm": fit_gpdm_latent_dynamics(gpdm_prior, walk[45:]),
        "latent random walk": fit_latent_dynamics(make_manifold_prior(make_bc_gplvm(walk[:45, 6:], 2), walk.shape[1]), walk[45:]),
        "mrpf": fit_mrpf_transition(gpdm_prior, walk[45:], key=jax.random.key(0), proposal="product", latent_proposal="gpdm"),
    }
    for name, dynamics in starts.items():
        state = dynamics.init(jax.random.key(1), pose, 3)
        if name == "gpdm":
            np.testing.assert_allclose(state[0, 6:], projected[0], atol=1e-9, err_msg=name)
            np.testing.assert_allclose(dynamics.to_pose(state[:1])[0, 6:], decoded(projected), atol=1e-9, err_msg=name)
        elif name == "mrpf":
            np.testing.assert_allclose(state[0, pose.shape[0]:], projected[0], atol=1e-9, err_msg=name)
        else:  # a BC-GPLVM encodes by its back-constraint, whatever the method
            manifold = dynamics.manifold
            np.testing.assert_allclose(state[0, 6:], manifold.encode(angles)[0], atol=1e-9, err_msg=name)
            np.testing.assert_allclose(manifold.encode(angles, method="likelihood"), manifold.encode(angles), atol=1e-12)


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


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
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


@pytest.mark.slow  # 9 s or more on 2 cores with an empty compilation cache (docs/testing.md, 2026-11-27)
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


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
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


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-27)
def test_gpapf_fits_its_latent_noise_on_the_validation_motion(gpdm_prior, walk, getkey):
    """GPAPF's default latent dynamics carry the mixture fitted on the validation motion (its
    default since 2026-11-25), not the GPDM's own noise, and its final layer is unchanged."""
    from jaxtrack.tracking import MotionData, get_tracker

    motion = MotionData(training=(np.asarray(walk[:45]),), validation=(np.asarray(walk[45:]),), manifold=gpdm_prior)
    latent, final = get_tracker("gpapf").fit(getkey(), motion)
    expected = fit_gpdm_latent_dynamics(gpdm_prior, walk[45:], latent_noise="validation").noise
    for field in ("core", "jump", "jump_probability"):
        np.testing.assert_allclose(float(getattr(latent.noise, field)), float(getattr(expected, field)), rtol=1e-12)
    assert float(latent.noise.core) != 1.0 or float(latent.noise.jump_probability) != 0.0  # not the GPDM's own
    np.testing.assert_allclose(np.asarray(final.scales), 0.5 * np.asarray(fit_pose_random_walk([walk[45:]]).scales), rtol=1e-12)


@pytest.mark.slow
def test_refinement_keeps_the_mixture_transition_invariant(gpdm_prior, walk, getkey):
    """MALA moves targeting the mixture's ``log_transition`` alone keep a sample of ``propose``."""
    dynamics = GPDMLatentDynamics(gpdm_prior, jnp.full(6, 0.01), noise=MIXTURE)
    check_refinement_keeps_transition(dynamics, jnp.asarray(walk[40]), getkey)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_mixture_same_key_same_result_jitted_or_not(gpdm_prior, walk, getkey):
    dynamics = GPDMLatentDynamics(gpdm_prior, jnp.full(6, 0.01), noise=MIXTURE)
    start = dynamics.init(getkey(), jnp.asarray(walk[10]), 64)
    key = getkey()
    jitted = eqx.filter_jit(lambda d, k, x: d.propose(k, x))(dynamics, key, start)[0]
    with jax.disable_jit():
        eager = dynamics.propose(key, start)[0]
    np.testing.assert_allclose(jitted, eager, rtol=1e-9, atol=1e-12)  # XLA fuses the GP prediction differently
    np.testing.assert_array_equal(dynamics.propose(key, start)[0], dynamics.propose(key, start)[0])
