"""Paper 004's dynamics: the uncertain-EM motion prototypes with MML selection, the VLMM (suffix
tree and automaton) and the VLMM-PF's transition."""

import itertools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.dynamics import (
    GaussianMixture,
    SuffixTree,
    VLMMDynamics,
    augmented_latent,
    compile_automaton,
    fit_step_scale,
    fit_suffix_tree,
    fit_uncertain_mixture,
    fit_vlmm,
)


def _clusters(seed, d=4, n=150, k=4, spread=0.5, scale=6.0):
    rng = np.random.default_rng(seed)
    centres = scale * rng.standard_normal((k, d))
    return np.concatenate([c + spread * rng.standard_normal((n, d)) for c in centres]), centres


def _reference_em(x, weights, means, covs, sweeps):
    """Ordinary EM, dense NumPy, all components updated together."""
    n, d = x.shape
    for _ in range(sweeps):
        log_p = np.stack([np.log(w) - 0.5 * (d * np.log(2 * np.pi) + np.linalg.slogdet(s)[1]
                                             + np.einsum("ni,ij,nj->n", x - m, np.linalg.inv(s), x - m))
                          for w, m, s in zip(weights, means, covs)], axis=1)
        resp = np.exp(log_p - log_p.max(1, keepdims=True))
        resp /= resp.sum(1, keepdims=True)
        nk = resp.sum(0)
        weights = nk / n
        means = (resp.T @ x) / nk[:, None]
        covs = np.stack([((x - m).T * r) @ (x - m) / s for m, r, s in zip(means, resp.T, nk)])
    return weights, means, covs


def test_mixture_without_uncertainty_is_ordinary_em():
    with jax.enable_x64(True):
        x, centres = _clusters(0, d=3, n=120, k=3)
        start = GaussianMixture(jnp.full(3, 1 / 3), jnp.asarray(centres + 0.3), jnp.broadcast_to(jnp.eye(3), (3, 3, 3)))
        fit = fit_uncertain_mixture(x, key=jax.random.key(0), initial=start, select=False, tolerance=1e-12, max_sweeps=500)
        w, m, s = _reference_em(x, np.full(3, 1 / 3), centres + 0.3, np.broadcast_to(np.eye(3), (3, 3, 3)), 300)
    order = [int(np.argmin(np.linalg.norm(np.asarray(fit.mixture.means) - mu, axis=1))) for mu in m]
    np.testing.assert_allclose(np.asarray(fit.mixture.weights)[order], w, atol=1e-6)
    np.testing.assert_allclose(np.asarray(fit.mixture.means)[order], m, atol=1e-6)
    np.testing.assert_allclose(np.asarray(fit.mixture.covariances)[order], s, atol=1e-6)


def test_uncertain_points_pull_the_mean_less():
    """004 eq. 3: a point weighs in by (Sigma + C_n)^-1, so uncertain points move the mean less."""
    with jax.enable_x64(True):
        rng = np.random.default_rng(1)
        x = np.concatenate([rng.standard_normal((100, 2)), 4.0 + rng.standard_normal((20, 2))])
        start = GaussianMixture(jnp.ones(1), jnp.zeros((1, 2)), jnp.eye(2)[None])
        plain = fit_uncertain_mixture(x, key=jax.random.key(0), initial=start, select=False)
        c = np.zeros((120, 2, 2))
        c[100:] = 50.0 * np.eye(2)  # the outlying points are very uncertain
        uncertain = fit_uncertain_mixture(x, c, key=jax.random.key(0), initial=start, select=False)
    np.testing.assert_allclose(np.asarray(plain.mixture.means[0]), x.mean(0), atol=1e-6)
    shift_plain = np.linalg.norm(np.asarray(plain.mixture.means[0]) - x[:100].mean(0))
    shift_uncertain = np.linalg.norm(np.asarray(uncertain.mixture.means[0]) - x[:100].mean(0))
    assert shift_uncertain < 0.2 * shift_plain
    # and the covariance is that of the certain points, not inflated by the uncertain ones
    assert np.trace(np.asarray(uncertain.mixture.covariances[0])) < 0.6 * np.trace(np.asarray(plain.mixture.covariances[0]))


def test_uncertain_covariance_solves_eq4():
    """The fixed point of eq. 4: sum_n P A^-1 Sigma A^-1 = sum_n P A^-1 ((x - mu)(x - mu)^T - C_n) A^-1."""
    with jax.enable_x64(True):
        rng = np.random.default_rng(2)
        x = rng.standard_normal((200, 2)) @ np.array([[2.0, 0.0], [0.5, 1.0]])
        c = np.stack([np.diag(rng.uniform(0.0, 0.5, 2)) for _ in range(200)])
        fit = fit_uncertain_mixture(x, c, key=jax.random.key(0), initial=GaussianMixture(jnp.ones(1), jnp.zeros((1, 2)), jnp.eye(2)[None]),
                                    select=False, tolerance=1e-14, max_sweeps=2000)
    mu, sigma = np.asarray(fit.mixture.means[0]), np.asarray(fit.mixture.covariances[0])
    a_inv = np.linalg.inv(sigma[None] + c)
    lhs = np.einsum("nij,jk,nkl->il", a_inv, sigma, a_inv)
    d = x - mu
    rhs = np.einsum("nij,njk,nkl->il", a_inv, d[:, :, None] * d[:, None, :] - c, a_inv)
    np.testing.assert_allclose(lhs, rhs, rtol=1e-5, atol=1e-8)
    np.testing.assert_allclose(mu, np.linalg.solve(a_inv.sum(0), np.einsum("nij,nj->i", a_inv, x)), atol=1e-8)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_mml_selects_the_true_number_of_components(seed):
    with jax.enable_x64(True):
        x, _ = _clusters(seed, d=4, n=150, k=4)
        fit = fit_uncertain_mixture(x, key=jax.random.key(seed), max_components=10)
    assert fit.mixture.num_components == 4
    assert min(fit.message_lengths, key=fit.message_lengths.get) == 4


@pytest.mark.slow  # 6-7 s cold; the default suite is at its 5-minute limit
def test_mixture_survives_collapse_and_refuses_bad_input():
    with jax.enable_x64(True):
        x = np.concatenate([np.zeros((5, 2)), np.ones((40, 2)) + 0.1 * np.random.default_rng(0).standard_normal((40, 2))])
        # a component started on five identical points collapses: it dies, without NaNs
        start = GaussianMixture(jnp.full(2, 0.5), jnp.array([[0.0, 0.0], [1.0, 1.0]]), jnp.broadcast_to(jnp.eye(2), (2, 2, 2)))
        fit = fit_uncertain_mixture(x, key=jax.random.key(0), initial=start, select=True)
    assert np.all(np.isfinite(np.asarray(fit.mixture.means))) and np.all(np.isfinite(np.asarray(fit.mixture.covariances)))
    assert np.all(np.linalg.eigvalsh(np.asarray(fit.mixture.covariances)) > 0)
    with pytest.raises(ValueError, match="NaN"):
        fit_uncertain_mixture(np.full((10, 2), np.nan), key=jax.random.key(0))
    with pytest.raises(ValueError, match="positive semi-definite"):
        fit_uncertain_mixture(np.zeros((10, 2)), -np.ones((10, 2, 2)), key=jax.random.key(0))
    with pytest.raises(ValueError, match="one covariance per point"):
        fit_uncertain_mixture(np.zeros((10, 2)), np.zeros((9, 2, 2)), key=jax.random.key(0))


def _variable_order_source(length, seed):
    """Three labels: after (0, 0) mostly 1, after (1, 0) mostly 0, after 1 mostly 2, else mostly 0."""
    table = {"00": [0.05, 0.9, 0.05], "10": [0.8, 0.1, 0.1], "1": [0.15, 0.15, 0.7], "": [0.6, 0.2, 0.2]}

    def law(history):
        key = "".join(map(str, history[-2:]))
        return table[key] if key in ("00", "10") else table["1"] if history[-1] == 1 else table[""]

    rng = np.random.default_rng(seed)
    labels = [0, 0]
    for _ in range(length):
        labels.append(int(rng.choice(3, p=law(labels))))
    return np.array(labels), law


def test_vlmm_recovers_a_variable_order_source():
    labels, law = _variable_order_source(20000, 0)
    _vlmm, tree = fit_vlmm([labels], max_memory=4, threshold=2e-3)
    assert tree.depth == 2  # the source's longest memory, found (not the maximum allowed)
    for context in [(0, 0), (1, 0), (2, 0), (1,), (2,), (0, 1), (2, 1)]:
        expected = np.asarray(law(list(context)))
        count = sum(1 for t in range(len(labels) - 1) if tuple(labels[max(0, t + 1 - len(context)):t + 1]) == context)
        # within four binomial standard errors of the true probabilities
        assert np.all(np.abs(tree.predict(context) - expected) <= 4 * np.sqrt(expected * (1 - expected) / count) + 2e-3)


def test_automaton_equals_the_suffix_tree_on_every_context():
    labels, _ = _variable_order_source(5000, 1)
    tree = fit_suffix_tree([labels], max_memory=3, threshold=1e-4)
    vlmm = compile_automaton(tree, [labels])
    for length in range(6):
        for history in itertools.product(range(3), repeat=length):
            state = 0
            for label in history:
                state = int(vlmm.transition[state, label])
            np.testing.assert_allclose(np.asarray(vlmm.output[state]), tree.predict(history), rtol=1e-6)
    np.testing.assert_allclose(float(jnp.sum(vlmm.initial)), 1.0, rtol=1e-6)
    # the jitted run visits the same states as the host-side loop
    states = np.asarray(eqx.filter_jit(type(vlmm).run)(vlmm, jnp.asarray(labels[:50])))
    state = 0
    for t, label in enumerate(labels[:50]):
        state = int(vlmm.transition[state, label])
        assert states[t] == state


def test_vlmm_refuses_bad_labels():
    with pytest.raises(ValueError, match="at least two labels"):
        fit_vlmm([np.array([1])])
    with pytest.raises(ValueError, match="negative"):
        fit_vlmm([np.array([0, -1, 2])])
    with pytest.raises(ValueError, match="integers"):
        fit_vlmm([np.array([0.5, 1.0])])
    # a sequence shorter than the memory still gives a (shallow) model
    vlmm, tree = fit_vlmm([np.array([0, 1, 0])], max_memory=5, min_count=1)
    assert tree.depth <= 2 and np.all(np.isfinite(np.asarray(vlmm.output)))


class _LatentOnly:
    """What the transition reads of a manifold: its split of the state."""

    global_dims, latent_dim = 6, 2


def _two_prototype_dynamics(switch_probability):
    """Two prototypes far apart and an automaton that leaves each with ``switch_probability``;
    built without a fitted manifold (the transition never decodes)."""
    prototypes = GaussianMixture(jnp.full(2, 0.5), jnp.array([[0.0, 0.0, 0.1, 0.0], [5.0, 5.0, -0.1, 0.0]]),
                                 jnp.broadcast_to(0.01 * jnp.eye(4), (2, 4, 4)))
    stay = 1.0 - switch_probability
    contexts = {(): np.array([0.5, 0.5]), (0,): np.array([stay, 1 - stay]), (1,): np.array([1 - stay, stay])}
    vlmm = compile_automaton(SuffixTree(2, contexts, 1))
    dynamics = object.__new__(VLMMDynamics)
    for name, value in {"manifold": _LatentOnly(), "prototypes": prototypes, "vlmm": vlmm, "s_global": jnp.full(6, 0.01),
                            "step_scale": jnp.asarray(0.5)}.items():
        object.__setattr__(dynamics, name, value)
    return dynamics


@pytest.mark.slow  # 6-7 s cold; the default suite is at its 5-minute limit
def test_vlmm_transition_switches_at_gamma_rate():
    dynamics = _two_prototype_dynamics(0.2)
    vlmm = dynamics.vlmm
    n = 20000
    state = int(vlmm.transition[0, 0])
    states = jnp.tile(jnp.concatenate([jnp.zeros(6), jnp.zeros(2), jnp.array([0.1, 0.0]), jnp.array([state, 0.0])]), (n, 1))
    new, log_w = eqx.filter_jit(VLMMDynamics.propose)(dynamics, jax.random.key(0), states)
    labels = np.asarray(new[:, -1])
    assert np.all(np.asarray(log_w) == 0)
    switched = labels == 1
    assert abs(switched.mean() - 0.2) < 4 * np.sqrt(0.2 * 0.8 / n)
    # a switch draws from the new prototype; a stay takes the local second-order step
    np.testing.assert_allclose(np.asarray(new[switched, 6:10]).mean(0), [5.0, 5.0, -0.1, 0.0], atol=0.01)
    stay = np.asarray(new[~switched, 6:10])
    np.testing.assert_allclose(stay.mean(0), [0.1, 0.0, 0.1, 0.0], atol=0.01)
    # x_t = x_{t-1} + x_dot_t + lambda d_x: x's sd is lambda * sqrt(0.01 + 0.01) (x_dot's noise carried into x)
    np.testing.assert_allclose(stay[:, 0].std(), 0.5 * np.sqrt(0.02), rtol=0.05)
    np.testing.assert_array_equal(np.asarray(new[:, -2]).astype(int), np.asarray(vlmm.transition[state])[labels.astype(int)])


def test_step_scale_and_augmented_latent():
    latent = np.cumsum(np.ones((10, 2)), axis=0)
    augmented = augmented_latent(latent, [0, 5, 10])
    np.testing.assert_allclose(augmented[:, 2:], 1.0)
    rng = np.random.default_rng(0)
    velocity = 1.0 + 0.2 * rng.standard_normal((400, 1))
    latent = np.cumsum(velocity, axis=0)
    augmented = augmented_latent(latent)
    mixture = GaussianMixture(jnp.ones(1), jnp.zeros((1, 2)), jnp.asarray([[[1.0, 0.0], [0.0, 0.04]]]))
    # the velocity's steps have sd 0.2 * sqrt(2) against a prototype velocity sd of 0.2
    assert fit_step_scale(mixture, augmented, np.zeros(400, int)) == pytest.approx(np.sqrt(2), rel=0.1)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_vlmmpf_tracks_and_never_leaks_nans():
    """VLMM-PF end to end on a small walk: the same key gives the same track, the error is that
    of a tracker (not of a lost one), and a blind likelihood leaves no NaN anywhere."""
    from jaxtrack.evaluation import mean_joint_error_mm
    from jaxtrack.filters import run_filter
    from jaxtrack.likelihood import as_likelihood
    from jaxtrack.tracking import Budget, build_tracker, fit_manifold, fit_tracker, get_tracker, motion_data, track

    from helpers import small_tracking_inputs

    key = jax.random.key(0)
    scene, train_poses, validation_poses = small_tracking_inputs(12)
    model, _, starts = fit_manifold(train_poses, 3, 30, kind="bc-gplvm")
    recipe = get_tracker("vlmmpf")
    fitted = fit_tracker(recipe, key, motion_data(train_poses, validation_poses, model, starts))
    assert isinstance(fitted, VLMMDynamics) and fitted.prototypes.num_components >= 1
    tracker = build_tracker(recipe, fitted, scene.likelihood, Budget(200), velocity_from=validation_poses)
    _, joints, _ = track(tracker, jax.random.key(3), scene)
    _, joints_again, _ = track(tracker, jax.random.key(3), scene)
    np.testing.assert_array_equal(np.asarray(joints), np.asarray(joints_again))
    assert float(mean_joint_error_mm(joints, scene.truth_joints)) < 80.0
    blind = as_likelihood(lambda poses, observation: jnp.full(poses.shape[0], -jnp.inf, poses.dtype))
    state, info = run_filter(build_tracker(recipe, fitted, blind, Budget(50)), jax.random.key(1), scene.initial_pose, scene.observations)
    assert bool(np.all(np.asarray(info.degenerate)))
    assert all(not np.any(np.isnan(np.asarray(leaf))) for leaf in jax.tree.leaves((state, info))
               if jnp.issubdtype(jnp.asarray(leaf).dtype, jnp.floating))


def _walk_and_jog_files(folder) -> list[str]:
    """Sequence files of a synthetic walk and jog (40 frames at 30 Hz each) in ``folder``."""
    from jaxtrack.data import generate_motion, motion_sequence
    from jaxtrack.io import save_sequence

    paths = []
    for i, gait in enumerate(("walk", "jog")):
        path = str(folder / f"{gait}.npz")
        save_sequence(path, motion_sequence(generate_motion(gait, "S1", num_frames=40, fps=30.0, key=jax.random.key(i))))
        paths.append(path)
    return paths


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_fit_model_vlmm_stores_the_prototypes_and_automaton(tmp_path, monkeypatch):
    """``jaxtrack fit --model vlmm``: one file holds the BC-GPLVM and the VLMM-PF's prototypes and
    automaton; read back they are the dynamics that were fitted, plot-latent draws them, and
    ``track --method vlmmpf`` tracks with them without fitting prototypes again."""
    from jaxtrack.cli import main
    from jaxtrack.dynamics import vlmm_from_record, vlmm_to_record
    from jaxtrack.io import save_sequence
    from jaxtrack.manifold import load_model, make_manifold_prior, read_header

    paths = _walk_and_jog_files(tmp_path)
    out = str(tmp_path / "m.eqx")
    assert main(["fit", *paths, "--model", "vlmm", "--steps", "5", "--out", out]) == 0
    record = read_header(out)["extra"]["vlmm"]
    with jax.enable_x64(True):
        model, _ = load_model(out)
        prior = make_manifold_prior(model, 6 + model.data_dim)
        dynamics = vlmm_from_record(record, prior)
        assert prior.latent_dim == 3 and dynamics.prototypes.dim == 6
        again = vlmm_to_record(dynamics)
    assert again == record
    assert main(["plot-latent", out, "--out", str(tmp_path / "latent.png")]) == 0
    assert (tmp_path / "latent_prototypes.png").stat().st_size > 5000
    with pytest.raises(ValueError, match="version"):
        vlmm_from_record({**record, "version": 99}, prior)
    with pytest.raises(ValueError, match="output"):
        vlmm_from_record({**record, "output": record["output"][:-1]}, prior)

    from jaxtrack.camera import default_rig
    from jaxtrack.data import scene_from_sequence
    from jaxtrack.io import load_sequence

    def no_refit(*args, **kwargs):
        raise AssertionError("the prototypes were fitted again")

    monkeypatch.setattr("jaxtrack.tracking._vlmmpf.fit_vlmm_dynamics", no_refit)
    test = tmp_path / "test.npz"
    save_sequence(test, scene_from_sequence(jax.random.key(3), load_sequence(paths[0]), default_rig(num_views=2), frames=4))
    assert main(["track", str(test), "--method", "vlmmpf", "--model", out, "--validation", paths[1], "--budget", "16",
                 "--out", str(tmp_path / "est")]) == 0


def test_vlmmpf_reads_the_prototypes_its_model_file_stored():
    """``track --method vlmmpf`` on a model of ``jaxtrack fit --model vlmm``: the tracker's
    dynamics are the stored prototypes, automaton and step scale (not refitted), with the global
    walk's scales fitted on the validation motion; a record that does not fit the manifold is
    refused by name."""
    from jaxtrack.tracking import MotionData, fit_tracker, get_tracker

    from helpers import walk_and_gpdm_prior

    walk, prior = walk_and_gpdm_prior()
    m, d = 2, 2 * prior.latent_dim
    record = {"version": 1, "weights": [0.25, 0.75], "means": np.arange(m * d, dtype=float).reshape(m, d).tolist(),
              "covariances": [np.eye(d).tolist(), (2 * np.eye(d)).tolist()], "transition": [[1, 2], [1, 2], [1, 2]],
              "output": [[0.5, 0.5], [0.9, 0.1], [0.2, 0.8]], "initial": [1.0, 0.0, 0.0], "contexts": [[], [0], [1]],
              "s_global": [9.0] * prior.global_dims, "step_scale": 0.7}
    recipe = get_tracker("vlmmpf")
    with jax.enable_x64(True):
        dynamics = fit_tracker(recipe, jax.random.key(0), MotionData((), (walk,), prior, stored={"vlmm": record}))
    np.testing.assert_allclose(np.asarray(dynamics.prototypes.means), record["means"])
    np.testing.assert_allclose(np.asarray(dynamics.prototypes.weights), record["weights"])
    np.testing.assert_array_equal(np.asarray(dynamics.vlmm.transition), record["transition"])
    assert float(dynamics.step_scale) == pytest.approx(0.7)
    steps = np.diff(walk[:, : prior.global_dims], axis=0)
    np.testing.assert_allclose(np.asarray(dynamics.s_global), np.maximum(np.sqrt(np.mean(steps**2, axis=0)), 1e-3), rtol=1e-6)
    with pytest.raises(ValueError, match=r"the model file's VLMM record does not fit its manifold.*means"):
        fit_tracker(recipe, jax.random.key(0), MotionData((), (walk,), prior, stored={"vlmm": {**record, "means": [[0.0] * 3] * 2}}))


@pytest.mark.slow
def test_fit_model_vlmm_on_004s_sparse_bc_gplvm(tmp_path):
    """``jaxtrack fit --model vlmm --vlmm-manifold sparse-bc-gplvm``: 004's manifold (a sparse
    BC-GPLVM, here 20 inducing points) with the prototypes fitted through its back-constraint."""
    from jaxtrack.cli import main
    from jaxtrack.dynamics import vlmm_from_record
    from jaxtrack.manifold import SparseBCGPLVM, load_model, make_manifold_prior, read_header

    paths = _walk_and_jog_files(tmp_path)
    out = str(tmp_path / "sparse.eqx")
    assert main(["fit", *paths, "--model", "vlmm", "--vlmm-manifold", "sparse-bc-gplvm", "--inducing", "20", "--steps", "5",
                 "--out", out]) == 0
    header = read_header(out)
    assert header["class"] == "SparseBCGPLVM" and header["inducing"] == 20
    with jax.enable_x64(True):
        model, _ = load_model(out)
        dynamics = vlmm_from_record(header["extra"]["vlmm"], make_manifold_prior(model, 6 + model.data_dim))
    assert isinstance(model, SparseBCGPLVM) and dynamics.prototypes.dim == 6 and dynamics.prototypes.num_components >= 1


def test_a_restart_draws_from_the_automatons_initial_states():
    """004 sec. 6.1: a lost VLMM-PF restarts its particles from ``s``: the automaton's state from
    ``vlmm.initial``, the prototype from gamma of it, the latent point from the prototype; the
    global entries kept, and a wrapper's own entries too (``restart_states``)."""
    from jaxtrack.dynamics import AbstractDynamicsWrapper, is_restartable, restart_states

    dynamics = _two_prototype_dynamics(0.2)
    vlmm = dynamics.vlmm
    after_one = int(vlmm.transition[0, 1])  # the state of context (1,): gamma = (0.2, 0.8)
    object.__setattr__(dynamics, "vlmm", eqx.tree_at(lambda v: v.initial, vlmm, jnp.zeros(vlmm.num_states).at[after_one].set(1.0)))
    n = 20000
    states = jnp.concatenate([jax.random.normal(jax.random.key(1), (n, 6)), jnp.zeros((n, 6))], axis=1)
    new = eqx.filter_jit(VLMMDynamics.restart)(dynamics, jax.random.key(0), states)
    labels = np.asarray(new[:, -1]).astype(int)
    assert abs(labels.mean() - 0.8) < 4 * np.sqrt(0.2 * 0.8 / n)
    np.testing.assert_array_equal(np.asarray(new[:, :6]), np.asarray(states[:, :6]))
    np.testing.assert_allclose(np.asarray(new[labels == 1, 6:10]).mean(0), [5.0, 5.0, -0.1, 0.0], atol=0.01)
    np.testing.assert_array_equal(np.asarray(new[:, -2]).astype(int), np.asarray(vlmm.transition[after_one])[labels])

    class Tagged(AbstractDynamicsWrapper):
        inner: VLMMDynamics

        def own_size(self):
            return 2

        def init(self, key, pose, num_particles):
            raise NotImplementedError

        def to_pose(self, states):
            raise NotImplementedError

        def propose(self, key, previous):
            raise NotImplementedError

        def perturb(self, key, states, factor):
            raise NotImplementedError

    wrapped = Tagged(dynamics)
    tagged = jnp.concatenate([states, jnp.full((n, 2), 7.0)], axis=1)
    assert is_restartable(wrapped)
    out = eqx.filter_jit(restart_states)(wrapped, jax.random.key(0), tagged)  # the same key: the same draws as ``new``
    np.testing.assert_array_equal(np.asarray(out[:, -2:]), 7.0)
    np.testing.assert_array_equal(np.asarray(out[:, :-2]), np.asarray(new))
