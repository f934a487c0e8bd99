import json

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body import forward_kinematics
from jaxtrack.data import generate_motion
from jaxtrack.manifold import (
    INVERSE_METHODS,
    fit_model,
    fit_pca,
    gaussian_log_marginal,
    make_bc_gpdm,
    make_bc_gplvm,
    make_gpdm,
    make_gplvm,
    predict,
)

from helpers import finite_difference_check


@pytest.fixture(scope="module")
def walk_jog():
    """Joint angles (no global position or orientation) of a synthetic walk and jog."""
    walk = generate_motion("walk", "S1", num_frames=120, fps=30.0, key=jax.random.key(0), dtype=jnp.float64)
    jog = generate_motion("jog", "S1", num_frames=80, fps=30.0, key=jax.random.key(1), dtype=jnp.float64)
    return walk, jog


def numpy_objective(Z, Y, beta, gamma, beta0, noise):
    d2 = ((Z[:, None] - Z[None]) ** 2).sum(-1)
    K = beta * np.exp(-0.5 * gamma * d2) + beta0 + noise * np.eye(len(Z))
    n, d = Y.shape
    _sign, logdet = np.linalg.slogdet(K)
    return -0.5 * d * n * np.log(2 * np.pi) - 0.5 * d * logdet - 0.5 * np.trace(np.linalg.solve(K, Y @ Y.T)) - 0.5 * np.sum(Z**2)


@pytest.fixture
def small_model(getkey):
    Y = np.asarray(jax.random.normal(getkey(), (12, 5)))
    model = make_gplvm(Y, 2)
    return eqx.tree_at(lambda m: m.latent, model, jax.random.normal(getkey(), (12, 2)))


def test_objective_equals_dense_numpy(small_model):
    m = small_model
    k = m.kernel
    expected = numpy_objective(np.asarray(m.latent), np.asarray(m.data), *(float(v) for v in (k.beta, k.gamma, k.beta0, k.noise)))
    assert float(m.objective()) == pytest.approx(expected, rel=1e-12)


def test_autodiff_matches_hand_derived_equations_17_18(small_model):
    m = small_model
    Z, Y = np.asarray(m.latent), np.asarray(m.data)
    k = m.kernel
    beta, gamma = float(k.beta), float(k.gamma)
    rbf = beta * np.exp(-0.5 * gamma * ((Z[:, None] - Z[None]) ** 2).sum(-1))
    K = rbf + float(k.beta0) + float(k.noise) * np.eye(len(Z))
    Kinv = np.linalg.inv(K)
    dL_dK = -0.5 * Y.shape[1] * Kinv + 0.5 * Kinv @ Y @ Y.T @ Kinv  # eq. 17
    diff = Z[:, None] - Z[None]  # (n, n, q)
    dK_dz = -gamma * diff * rbf[..., None]  # d k_nm / d z_n
    grad = 2 * np.einsum("nm,nmq->nq", dL_dK, dK_dz) - Z  # eq. 18 (K symmetric), minus the prior
    auto = jax.grad(lambda z: eqx.tree_at(lambda mm: mm.latent, m, z).objective())(m.latent)
    np.testing.assert_allclose(auto, grad, rtol=1e-8, atol=1e-10)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_gradients_match_finite_differences(walk_jog, getkey):
    walk, _jog = walk_jog
    Y = walk.pose[:30, 6:]
    for model in (make_gplvm(Y, 2), make_bc_gplvm(Y, 2), make_gpdm([Y[:15], Y[15:]], 2)):
        params, static = eqx.partition(model, model.trainable())
        flat, unravel = jax.flatten_util.ravel_pytree(params)
        f = lambda v, static=static, unravel=unravel: eqx.combine(unravel(v), static).objective()  # noqa: E731
        finite_difference_check(f, flat, jax.random.normal(getkey(), flat.shape), rtol=1e-5, atol=1e-6)


def test_gaussian_log_marginal_survives_duplicate_frames():
    Z = jnp.zeros((6, 2))  # six identical latent points: K is rank one without noise
    K = jnp.ones((6, 6))
    value = gaussian_log_marginal(K, jnp.ones((6, 3)))
    assert np.isfinite(float(value))
    Y = np.repeat(np.random.default_rng(0).normal(size=(5, 4)), 3, axis=0)  # every frame three times
    model = make_gplvm(Y, 2)
    model = eqx.tree_at(lambda m: m.kernel.log_noise, model, jnp.asarray(-40.0))  # noise ~ 0
    assert np.isfinite(float(model.objective()))
    assert np.isfinite(float(make_gplvm(Y, 2).objective())) and Z.shape == (6, 2)


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-27)
def test_predictive_interpolates_and_reverts_to_the_prior(small_model):
    m = eqx.tree_at(lambda mm: mm.kernel.log_noise, small_model, jnp.asarray(np.log(1e-8)))
    mean, var = predict(m, m.latent)
    np.testing.assert_allclose(mean, m.mean + m.scale * m.data, atol=1e-5)
    assert float(var.max()) < 1e-5
    far_mean, far_var = predict(m, 1e3 * jnp.ones((1, 2)))
    assert float(far_var[0]) == pytest.approx(float(m.kernel.beta + m.kernel.beta0), rel=1e-2)
    assert np.all(np.abs(np.asarray(far_mean - m.mean)) < np.abs(np.asarray(m.data)).max())
    batched = jax.vmap(lambda z: predict(m, z[None])[0][0])(m.latent[:4])
    np.testing.assert_allclose(batched, mean[:4], rtol=1e-10)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_fitting_walk_and_jog(walk_jog):
    """The 2-D latent space separates walk from jog; the back-constrained model keeps
    consecutive frames close; its reconstruction of held-out frames beats PCA in mm."""
    walk, jog = walk_jog
    Y = np.concatenate([walk.pose[:100, 6:], jog.pose[:60, 6:]])
    labels = np.r_[np.zeros(100), np.ones(60)]
    bc0 = make_bc_gplvm(Y, 2)
    bc, info = fit_model(bc0, max_steps=300)
    assert info.objective > float(bc0.objective()) + 100
    Z = np.asarray(bc.latent)
    d = ((Z[:, None] - Z[None]) ** 2).sum(-1)
    np.fill_diagonal(d, np.inf)
    assert (labels[d.argmin(1)] == labels).mean() > 0.95
    steps = np.linalg.norm(np.diff(Z[:100], axis=0), axis=1)
    assert steps.max() / np.median(steps) < 5.0

    # held-out frames: encode with the back-constraint, decode with the GP mean; PCA alike
    held = np.concatenate([walk.pose[100:], jog.pose[60:]])
    skeleton = walk.body.skeleton

    def joints(angles):
        full = np.concatenate([np.zeros((len(angles), 6)), angles], axis=1)
        return np.asarray(forward_kinematics(skeleton, jnp.asarray(full)))

    truth = joints(held[:, 6:])
    gp_mean, _ = predict(bc, bc.encode(jnp.asarray(held[:, 6:])))
    linear = fit_pca(Y, 2)
    pca_rec = np.asarray(linear.decode(linear.encode(jnp.asarray(held[:, 6:]))))
    gp_mm = 1000 * np.linalg.norm(joints(np.asarray(gp_mean)) - truth, axis=-1).mean()
    pca_mm = 1000 * np.linalg.norm(joints(pca_rec) - truth, axis=-1).mean()
    print(f"held-out reconstruction: BC-GPLVM {gp_mm:.1f} mm, PCA {pca_mm:.1f} mm")
    assert gp_mm < pca_mm


@pytest.mark.slow
def test_gpdm_respects_sequence_boundaries(walk_jog):
    walk, jog = walk_jog
    model = make_gpdm([walk.pose[:20, 6:], jog.pose[:10, 6:]], 2)
    ins, _outs, firsts = model._transitions()
    assert 19 not in ins and list(firsts) == [0, 20] and len(ins) == 19 + 9
    _fitted, info = fit_model(model, max_steps=100)
    assert info.objective > float(model.objective())


@pytest.mark.slow
def test_bc_gpdm_is_the_gpdm_at_its_back_constrained_points(walk_jog):
    """The back-constrained GPDM starts at the GPDM's PCA latent points, its objective is 001
    eq. 11 at ``X = g(Y)``, and its gradient in g's weights matches finite differences."""
    walk, jog = walk_jog
    takes = [walk.pose[:20, 6:], jog.pose[:12, 6:]]
    bc, plain = make_bc_gpdm(takes, 3), make_gpdm(takes, 3)
    np.testing.assert_allclose(bc.training_latent(), plain.latent, atol=1e-3 * float(jnp.max(jnp.abs(plain.latent))))
    moved = eqx.tree_at(lambda m: m.back.weights, bc, bc.back.weights * 1.3 + 0.01)
    at_points = eqx.tree_at(lambda m: m.latent, plain, moved.back(moved.data))
    assert float(moved.objective()) == pytest.approx(float(at_points.objective()), rel=1e-12)
    z = moved.training_latent()[:4] + 0.1
    np.testing.assert_allclose(predict(moved, z)[0], predict(at_points, z)[0], rtol=1e-10)
    np.testing.assert_allclose(moved.latent_dynamics()(z)[0], at_points.latent_dynamics()(z)[0], rtol=1e-10)

    def objective(weights):
        return eqx.tree_at(lambda m: m.back.weights, moved, weights).objective()

    direction = jax.random.normal(jax.random.key(3), bc.back.weights.shape, bc.back.weights.dtype)
    finite_difference_check(objective, moved.back.weights, direction, eps=1e-6, rtol=1e-5)
    with pytest.raises(ValueError, match="gamma_x must be positive"):
        make_bc_gpdm(takes, 3, gamma_x=0.0)


@pytest.mark.slow
def test_bc_gpdm_joins_two_takes_of_one_walk():
    """Two noisy takes of one walk that overlap in phase: the back-constrained GPDM puts the end
    of the first take among the second take's points, where the plain GPDM leaves it apart."""
    walk = generate_motion("walk", "S1", num_frames=70, fps=30.0, key=jax.random.key(5), dtype=jnp.float64).pose[:, 6:]
    noise = 0.01 * np.random.default_rng(0).standard_normal(walk.shape)
    takes = [walk[:40], walk[25:] + noise[25:]]

    def gap(model):
        """The first take's last latent point's distance to the second take, in median steps."""
        z = np.asarray(model.training_latent())
        steps = np.linalg.norm(np.diff(z[:40], axis=0), axis=1)
        return np.min(np.linalg.norm(z[40:] - z[39], axis=1)) / np.median(steps)

    bc = make_bc_gpdm(takes, 2).fit(max_steps=150)[0]
    plain = make_gpdm(takes, 2).fit(max_steps=150)[0]
    print(f"end of take 1 to take 2: back-constrained {gap(bc):.2f}, plain {gap(plain):.2f} median steps")
    assert gap(bc) < 1.5 and gap(bc) < gap(plain)


def test_bad_training_data():
    Y = np.random.default_rng(0).normal(size=(20, 4))
    with pytest.raises(ValueError, match="non-finite value at frame 3, dimension 1"):
        make_gplvm(np.where(np.arange(80).reshape(20, 4) == 13, np.nan, Y), 2)
    with pytest.raises(ValueError, match="constant"):
        make_gplvm(np.ones((20, 4)), 2)
    with pytest.raises(ValueError, match="too few"):
        make_gplvm(Y[:3], 2)
    with pytest.raises(ValueError, match="larger than the data dimension"):
        make_bc_gplvm(Y, 5)
    with pytest.raises(ValueError, match=r"one or more \(T, D\) sequences"):
        make_gpdm([Y[None]], 2)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_save_load_round_trip_and_errors(walk_jog, tmp_path):
    from jaxtrack.manifold import ModelFileError, load_model, save_model

    walk, jog = walk_jog
    angles = walk.pose[:30, 6:]
    takes = [walk.pose[:20, 6:], jog.pose[:10, 6:]]
    models = (make_gplvm(angles, 2), make_bc_gplvm(angles, 2), make_gpdm(takes, 3), make_bc_gpdm(takes, 3))
    for model in models:
        path = tmp_path / f"{type(model).__name__}.eqx"
        save_model(path, model, extra={"note": "test"})
        back, header = load_model(path)
        assert type(back) is type(model) and header["extra"] == {"note": "test"}
        assert float(back.objective()) == pytest.approx(float(model.objective()), rel=1e-12)
        z = jnp.zeros((1, model.training_latent().shape[1]))
        np.testing.assert_allclose(predict(back, z)[0], predict(model, z)[0])
    with pytest.raises(ModelFileError, match="holds a GPDM, but a BCGPLVM is needed"):
        load_model(tmp_path / "GPDM.eqx", expected_class="BCGPLVM")
    text = (tmp_path / "GPLVM.eqx").read_bytes().replace(b'"version": 3', b'"version": 9', 1)
    (tmp_path / "v9.eqx").write_bytes(text)
    with pytest.raises(ModelFileError, match="format version 9"):
        load_model(tmp_path / "v9.eqx")
    (tmp_path / "junk.eqx").write_bytes(b"\x00\x01garbage")
    with pytest.raises(ModelFileError, match="not a jaxtrack model file"):
        load_model(tmp_path / "junk.eqx")
    # Truncated, extended, or edited in place: reported as such, with the file's name.
    good = (tmp_path / "BCGPLVM.eqx").read_bytes()
    header_end = good.index(b"\n") + 1
    cases = {
        "cut.eqx": (good[:-100], r"cut\.eqx: truncated: the arrays take \d+ bytes, the header says \d+"),
        "long.eqx": (good + b"\x00", r"long\.eqx: edited: the arrays take"),
        "flip.eqx": (good[:-9] + bytes([good[-9] ^ 0xFF]) + good[-8:], r"flip\.eqx: edited or corrupted: the arrays' SHA-256"),
        "header.eqx": (good[:header_end].replace(b'"latent_dim": 2', b'"latent_dim": 3') + good[header_end:],
                       r"header\.eqx: edited or corrupted: the header's SHA-256"),
    }
    for name, (data, message) in cases.items():
        (tmp_path / name).write_bytes(data)
        with pytest.raises(ModelFileError, match=message):
            load_model(tmp_path / name)
    # Version-1 files (no payload length or checksum) and version-2 files (no header checksum) still
    # load; in a version-2 file an edit of the shapes is caught when the arrays do not fit them, and
    # a header asking for more arrays than the file holds is refused before anything is allocated.
    fields = json.loads(good[:header_end])
    del fields["header_sha256"]
    (tmp_path / "v2.eqx").write_bytes((json.dumps({**fields, "version": 2}) + "\n").encode() + good[header_end:])
    assert type(load_model(tmp_path / "v2.eqx")[0]).__name__ == "BCGPLVM"
    for edit, message in (({"latent_dim": 3}, "the header does not describe the arrays"),
                          ({"frames": 10**9}, r"the header describes \d+ bytes of arrays, the file holds \d+")):
        (tmp_path / "v2edit.eqx").write_bytes((json.dumps({**fields, "version": 2, **edit}) + "\n").encode() + good[header_end:])
        with pytest.raises(ModelFileError, match=message):
            load_model(tmp_path / "v2edit.eqx")
    v1 = {k: v for k, v in fields.items() if k not in ("payload_bytes", "payload_sha256")}
    (tmp_path / "v1.eqx").write_bytes((json.dumps({**v1, "version": 1}) + "\n").encode() + good[header_end:])
    assert type(load_model(tmp_path / "v1.eqx")[0]).__name__ == "BCGPLVM"
    # What a version-1 header cannot guard by a checksum is checked on reading: sequence_starts, a
    # header that is not a JSON object.
    (tmp_path / "v1s.eqx").write_bytes((json.dumps({**v1, "version": 1, "sequence_starts": [0, 5, 3]}) + "\n").encode()
                                       + good[header_end:])
    with pytest.raises(ModelFileError, match="sequence_starts must rise from 0"):
        load_model(tmp_path / "v1s.eqx")
    (tmp_path / "list.eqx").write_bytes(b"[1, 2]\n" + good[header_end:])
    with pytest.raises(ModelFileError, match="its header is a JSON list, not an object"):
        load_model(tmp_path / "list.eqx")


@pytest.mark.slow  # moved to the slow suite for the default suite's 10 minutes
def test_inverse_mapping(walk_jog):
    walk, _ = walk_jog
    Y = walk.pose[:60, 6:]
    gplvm, _ = fit_model(make_gplvm(Y, 2), max_steps=150)
    # Training poses map back (near) to their own latent points, by projection onto the mean
    # surface (the default) and by the optimisation of 003 eq. 5.
    for method in INVERSE_METHODS:
        Z = gplvm.encode(jnp.asarray(Y[::10]), method=method)
        recon, _ = predict(gplvm, Z)
        assert float(jnp.abs(recon - Y[::10]).max()) < 0.05, method
    # A pose the manifold was not trained on (every angle 0.15 rad off, like another subject):
    # the projection decodes nearer to it than the nearest training pose's latent point, and
    # much nearer than 003 eq. 5, whose optimum leaves the training points for large variance.
    off = jnp.asarray(Y[5:60:6] + 0.15)
    distance = lambda Z: np.linalg.norm(np.asarray(predict(gplvm, Z)[0]) - np.asarray(off), axis=1)  # noqa: E731
    nearest = gplvm.latent[np.argmin(((np.asarray(off)[:, None] - Y[None]) ** 2).sum(-1), axis=1)]
    projected, likelihood = distance(gplvm.encode(off)), distance(gplvm.encode(off, method="likelihood"))
    assert np.all(projected <= distance(nearest) + 1e-6) and np.mean(projected) < np.mean(distance(nearest))
    assert np.mean(projected) < np.mean(likelihood)
    with pytest.raises(ValueError, match="encode method must be one of"):
        gplvm.encode(off, method="nearest")
    bc = make_bc_gplvm(Y, 2)
    np.testing.assert_allclose(bc.encode(jnp.asarray(Y)), bc.latent, atol=1e-10)
    with pytest.raises(ValueError, match=r"poses must be \(m, 26\)"):
        bc.encode(jnp.zeros((2, 5)))


@pytest.mark.slow
def test_fit_and_plot_latent_cli(walk_jog, tmp_path):
    import imageio.v3 as iio

    from jaxtrack.cli import main
    from jaxtrack.io import Sequence, save_sequence
    from jaxtrack.manifold import load_model

    walk, jog = walk_jog
    layout = np.array(walk.body.skeleton.pose_layout)
    for name, m in (("walk", walk), ("jog", jog)):
        save_sequence(tmp_path / f"{name}.npz", Sequence.create(fps=30.0, pose=m.pose[:40], pose_layout=layout))
    out = tmp_path / "model.eqx"
    arguments = ["fit", str(tmp_path / "walk.npz"), str(tmp_path / "jog.npz"), "--model", "gpdm", "--latent-dim", "2", "--steps", "50"]
    assert main([*arguments, "--out", str(out)]) == 0
    assert main(["plot-latent", str(out)]) == 0
    constrained = tmp_path / "bc.eqx"
    assert main([*arguments[:3], "--model", "bc-gpdm", "--steps", "20", "--out", str(constrained)]) == 0
    assert type(load_model(constrained)[0]).__name__ == "BCGPDM"
    image = iio.imread(tmp_path / "model_latent.png")
    assert image.shape[0] > 200
    no_pose = tmp_path / "joints.npz"
    np.savez(no_pose, fps=30.0, joints3d=np.zeros((3, 15, 3)))
    assert main(["fit", str(no_pose), "--out", str(out)]) == 2


@pytest.mark.slow
def test_cmu_walk_and_jog_manifold(shared_data):
    """Real motion (CMU subject 35, GPmat's 30 Hz channels): fit a BC-GPLVM to walk 35_01 and
    jog 35_17; score held-out walk 35_29 against PCA (about 17 mm vs 38 mm)."""
    import os

    from scipy.io import loadmat

    from jaxtrack.body import inverse_kinematics, retarget_positions
    from jaxtrack.io import motion_from_amc_values, read_asf

    cmu = os.path.join(shared_data, "cmu35")
    data = loadmat(os.path.join(cmu, "cmu35WalkJog.mat"))
    asf = read_asf(os.path.join(cmu, "35.asf"))

    def angles(rows, seed):
        motion = motion_from_amc_values(asf, rows, fps=30.0)
        result = inverse_kinematics(retarget_positions(motion.positions, motion.joint_names), key=jax.random.key(seed))
        return np.asarray(result.pose), result.skeleton

    walk, skeleton = angles(data["Y"][data["lbls"][:, 0] == 1], 0)
    jog, _ = angles(data["Y"][data["lbls"][:, 16] == 1], 1)
    held, _ = angles(data["Ytest"][data["lblstest"][:, 1] == 1][:40], 2)
    Y = np.concatenate([walk[:, 6:], jog[:, 6:]])
    labels = np.r_[np.zeros(len(walk)), np.ones(len(jog))]
    model, _ = fit_model(make_bc_gplvm(Y, 2), max_steps=300)
    Z = np.asarray(model.latent)
    d = ((Z[:, None] - Z[None]) ** 2).sum(-1)
    np.fill_diagonal(d, np.inf)
    assert (labels[d.argmin(1)] == labels).mean() > 0.95
    steps = np.linalg.norm(np.diff(Z[: len(walk)], axis=0), axis=1)
    assert steps.max() / np.median(steps) < 5.0

    def joints(a):
        return np.asarray(forward_kinematics(skeleton, jnp.asarray(np.concatenate([np.zeros((len(a), 6)), a], 1))))

    truth = joints(held[:, 6:])
    gp_mean, _ = predict(model, model.encode(jnp.asarray(held[:, 6:])))
    linear = fit_pca(Y, 2)
    gp_mm = 1000 * np.linalg.norm(joints(np.asarray(gp_mean)) - truth, axis=-1).mean()
    pca_mm = 1000 * np.linalg.norm(joints(np.asarray(linear.decode(linear.encode(jnp.asarray(held[:, 6:]))))) - truth, axis=-1).mean()
    print(f"CMU held-out walk 35_29: BC-GPLVM {gp_mm:.1f} mm, PCA {pca_mm:.1f} mm")
    assert gp_mm < pca_mm


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_every_model_is_an_abstract_manifold_in_the_registry(walk_jog):
    from jaxtrack.manifold import MANIFOLD_CLASSES, AbstractManifold, ManifoldPrior, make_manifold_prior, register_manifold

    assert set(MANIFOLD_CLASSES) == {"GPLVM", "BCGPLVM", "GPDM", "BCGPDM", "SparseGPLVM", "SparseBCGPLVM", "SpectralEmbedding",
                                    "ActiveSetGPLVM"}
    walk, _ = walk_jog
    Y = walk.pose[:30, 6:]
    from jaxtrack.manifold import make_active_set_gplvm

    for model in (make_gplvm(Y, 2), make_bc_gplvm(Y, 2), make_active_set_gplvm(Y, 2, active=12)):
        assert isinstance(model, AbstractManifold) and model.latent_dim == 2 and model.data_dim == 26
        prior = make_manifold_prior(model, 32)
        assert isinstance(prior, ManifoldPrior) and prior.global_dims == 6 and prior.pose_dim == 32
        np.testing.assert_allclose(prior.training_poses(), Y, atol=1e-10)
        z = model.training_latent()[:3]
        np.testing.assert_allclose(prior.decode_mean(z), model.decode(z)[0], rtol=1e-10)
        np.testing.assert_allclose(prior.encode(jnp.asarray(Y[:3])), model.encode(jnp.asarray(Y[:3])), rtol=1e-8, atol=1e-8)
    fitted, info = make_gplvm(Y, 2).fit(max_steps=6, chunk=3)
    reference, _ = fit_model(make_gplvm(Y, 2), max_steps=6, chunk=3)
    assert info.steps == 6 and float(fitted.objective()) == pytest.approx(float(reference.objective()), rel=1e-12)
    assert make_manifold_prior(make_bc_gplvm(Y, 2), 32).has_back_constraint
    assert not make_manifold_prior(make_gplvm(Y, 2), 32).has_back_constraint
    with pytest.raises(TypeError, match="AbstractSaveableManifold subclass"):
        register_manifold(dict)
    with pytest.raises(TypeError, match="needs a fitted AbstractManifold"):
        make_manifold_prior(fit_pca(Y, 2), 32)
    with pytest.raises(ValueError, match="models 26 pose entries but the pose vector has only 20"):
        make_manifold_prior(make_gplvm(Y, 2), 20)


def test_a_model_built_directly_is_checked(walk_jog):
    """``__check_init__`` refuses inconsistent shapes (checked with jaxtyping's own run-time
    checks switched off, since they would refuse them first in the test suite)."""
    import jaxtyping

    from jaxtrack.manifold import GPLVM, rbf_bias_kernel

    jaxtyping.config.update("jaxtyping_disable", True)
    try:
        _check_direct_construction(GPLVM, rbf_bias_kernel)
    finally:
        jaxtyping.config.update("jaxtyping_disable", False)


def _check_direct_construction(GPLVM, rbf_bias_kernel):
    with pytest.raises(ValueError, match=r"GPLVM: mean must have shape \(4,\)"):
        GPLVM(latent=jnp.zeros((5, 2)), kernel=rbf_bias_kernel(), data=jnp.zeros((5, 4)), mean=jnp.zeros(3), scale=jnp.ones(4))
    with pytest.raises(ValueError, match="data must be"):
        GPLVM(latent=jnp.zeros((5, 2)), kernel=rbf_bias_kernel(), data=jnp.zeros(5), mean=jnp.zeros(3), scale=jnp.ones(4))


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_gpdm_objective_is_bounded_along_its_scale_and_constant_entries(walk_jog):
    """001 eq. 11: scaling the pose kernel, its noise and W^2 together by s changes the objective
    only by the bias's own prior, -ln s (the scale's and the precision beta_3 = 1/noise's terms
    cancel; with a variance's sign they added -2 ln s, and the fit collapsed), and a pose entry
    that never moves has no term, so its W cannot run off to infinity."""
    walk, _ = walk_jog
    frames = np.asarray(walk.pose[:40, 6:14], np.float64).copy()
    frames[:, -1] = 0.3  # an entry that never moves
    model = make_gpdm([frames], 2)
    base = float(model.objective())
    s = 1e3
    scaled = eqx.tree_at(
        lambda m: (m.kernel.log_beta, m.kernel.log_beta0, m.kernel.log_noise, m.log_w),
        model,
        (model.kernel.log_beta + np.log(s), model.kernel.log_beta0 + np.log(s), model.kernel.log_noise + np.log(s),
         model.log_w + 0.5 * np.log(s)),
    )
    np.testing.assert_allclose(float(scaled.objective()), base - np.log(s), rtol=1e-9)
    still = eqx.tree_at(lambda m: m.log_w, model, model.log_w.at[-1].set(20.0))
    np.testing.assert_allclose(float(still.objective()), base, rtol=1e-12)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_fit_takes_exactly_the_steps_asked_and_never_returns_nans():
    """``--steps 30`` used to run 50 (a whole chunk); an objective that turns NaN part-way
    leaves the parameters of the last finite step."""
    Y = generate_motion("walk", "S1", num_frames=40, fps=30.0, key=jax.random.key(2), dtype=jnp.float64).pose[:, 6:]
    _, info = fit_model(make_gplvm(np.asarray(Y), 2), max_steps=30, chunk=50, tolerance=0.0)
    assert info.steps == 30 and info.trace.shape == (30,)

    class Cliff(eqx.Module):
        x: jax.Array
        beyond: float = eqx.field(static=True, default=float("nan"))

        def trainable(self):
            return jax.tree_util.tree_map(lambda _: True, self)

        def objective(self):  # climbs until x = 3, then NaN (or +inf)
            return jnp.where(self.x[0] < 3.0, self.x[0] - 0.1 * self.x[0] ** 2 / 9, self.beyond)

    # NaN beyond the cliff: the line search refuses those points, and the fit stays below it
    fitted, info = fit_model(Cliff(jnp.zeros(1)), max_steps=200, chunk=5, tolerance=0.0)
    assert np.isfinite(float(fitted.x[0])) and np.isfinite(info.objective) and np.all(np.isfinite(info.trace))
    assert float(fitted.x[0]) < 3.0 and info.objective == pytest.approx(float(fitted.objective()))
    # +inf beyond it: a loss of -inf passes the line search as a decrease; that step is dropped
    fitted, info = fit_model(Cliff(jnp.zeros(1), float("inf")), max_steps=200, chunk=5, tolerance=0.0)
    assert np.isfinite(float(fitted.x[0])) and float(fitted.x[0]) < 3.0 and np.all(np.isfinite(info.trace))
    assert info.steps < 200 and info.objective == pytest.approx(float(fitted.objective()))
    with pytest.raises(ValueError, match="max_steps must be a positive integer"):
        fit_model(Cliff(jnp.zeros(1)), max_steps=0)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_gpdm_gle_start_keeps_the_mirror_half_cycles_apart():
    """A cycle whose strongest directions, once standardised, are a half-cycle feature (cos 2 phi,
    three entries) and the stride (sin phi, two): PCA's 2-D start puts phase phi on phase
    pi - phi, the GLE start (002) lays the cycle out as a loop, and the GPDM fitted from it
    keeps the two half-cycles apart."""
    phase = 2 * np.pi * np.arange(120) / 40  # three cycles of 40 frames
    noise = 0.01 * np.random.default_rng(0).standard_normal((120, 6))
    shifts = np.array([0.0, 0.05, 0.0, 0.05, 0.1, 0.0])
    frequency = np.array([1, 1, 2, 2, 2, 1])
    cycle = np.where(np.arange(6) < 2, np.sin(frequency * phase[:, None] + shifts), np.cos(frequency * phase[:, None] + shifts)) + noise
    takes = [cycle[:60], cycle[60:]]
    first, mirror = np.arange(38, 43), 60 - np.arange(38, 43)  # phi near 0 and pi - phi, in the first take

    def separation(model):
        """Mirror-phase distance over the median step."""
        z = np.asarray(model.training_latent())
        return np.median(np.linalg.norm(z[first] - z[mirror], axis=1)) / np.median(np.linalg.norm(np.diff(z[:60], axis=0), axis=1))

    pca_start, gle_start = make_gpdm(takes, 2), make_gpdm(takes, 2, init="gle")
    assert np.std(np.asarray(gle_start.latent)[:, 0]) == pytest.approx(1.0)
    fitted = gle_start.fit(max_steps=30)[0]
    print(f"mirror phases apart: PCA start {separation(pca_start):.2f}, GLE start {separation(gle_start):.2f}, "
          f"fitted from it {separation(fitted):.2f} median steps")
    assert separation(pca_start) < 1.0 < 8.0 < separation(gle_start)
    assert separation(fitted) > 8.0
    with pytest.raises(ValueError, match="init must be one of"):
        make_gpdm(takes, 2, init="isomap")
