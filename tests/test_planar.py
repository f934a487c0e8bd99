"""Paper 003's monocular 2-D path: the scaled prismatic model, the view-sphere training data,
the active-set GPLVM (IVM, eq. 2, eq. 5), the NCC templates and the three trackers."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtrack.planar as planar
from jaxtrack.cli import main
from jaxtrack.data import signalling_motion
from jaxtrack.manifold import ivm_select, optimise_points, point_objective, rbf_bias_kernel


@pytest.fixture(scope="module")
def small_model():
    """An SPM model of one short gesture take seen from 4 azimuths (80 poses, active set 30)."""
    motion = signalling_motion(jax.random.key(0), num_frames=60)
    rig = planar.view_sphere_rig((0, 90, 180, 270), (0,))
    model, starts = planar.fit_spm_model([motion.joints3d], rig=rig, every=3, active=30, iterations=1, max_steps=30)
    return model, starts


def test_spm_forward_is_the_hand_computed_chain():
    theta = np.zeros(planar.NUM_LINKS)
    d = np.ones(planar.NUM_LINKS)
    theta[1], d[1] = 0.1, 0.5  # neck: tilted, half seen
    theta[2], d[2] = np.pi / 2, 0.8  # left clavicle: a quarter turn from the spine (to the image's right)
    theta[3] = np.pi / 2  # left upper arm: a quarter turn further (pointing down)
    state = np.concatenate([[10.0, 20.0, np.log(100.0)], theta, d])
    markers = np.asarray(planar.spm_forward(jnp.asarray(state)))
    L = planar.SPM_REFERENCE_LENGTHS
    thorax = np.array([10.0, 20.0 - 100 * L[0]])
    head = thorax + 100 * L[1] * 0.5 * np.array([np.cos(-np.pi / 2 + 0.1), np.sin(-np.pi / 2 + 0.1)])
    shoulder = thorax + 100 * L[2] * 0.8 * np.array([1.0, 0.0])
    elbow = shoulder + 100 * L[3] * np.array([0.0, 1.0])
    index = planar.SPM_MARKERS.index
    np.testing.assert_allclose(markers[index("pelvis")], [10, 20], atol=1e-9)
    np.testing.assert_allclose(markers[index("thorax")], thorax, atol=1e-9)
    np.testing.assert_allclose(markers[index("head")], head, atol=1e-9)
    np.testing.assert_allclose(markers[index("lshoulder")], shoulder, atol=1e-9)
    np.testing.assert_allclose(markers[index("lelbow")], elbow, atol=1e-9)


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-27)
def test_spm_states_of_projected_joints_give_the_projected_markers_back():
    motion = signalling_motion(jax.random.key(3), num_frames=20)
    rig = planar.view_sphere_rig((20, 140, 250), (0, 35))
    markers, scale = planar.project_markers(rig, planar.centred_joints(motion.joints3d))
    states = planar.spm_from_markers(jnp.asarray(markers), jnp.asarray(scale))
    np.testing.assert_allclose(np.asarray(planar.spm_forward(states)), markers, atol=1e-8)
    # The features and the global part make the same state again.
    again = planar.spm_state(planar.spm_features(states), states[..., :2], states[..., 2])
    np.testing.assert_allclose(np.asarray(planar.spm_forward(again)), markers, atol=1e-8)
    # The scale is the focal length over the pelvis's depth, so a default-length link seen
    # side-on has d near 1 and none is much longer.
    d = np.asarray(states[..., 3 + planar.NUM_LINKS:])
    assert d.max() < 1.2 and np.median(d) > 0.5  # perspective: a limb nearer the camera looks longer
    # Training sets: one state sequence per (take, view).
    sets = planar.spm_training_set([motion.joints3d], rig, every=2)
    assert len(sets) == rig.num_views and sets[0].shape == (10, planar.SPM_STATE_DIM)
    np.testing.assert_allclose(sets[1], np.asarray(states[1, ::2]), atol=1e-9)


def test_ivm_picks_what_a_numpy_posterior_entropy_loop_picks():
    latent = np.random.default_rng(0).normal(size=(40, 2))
    kernel = rbf_bias_kernel(beta=1.3, gamma=2.0, beta0=0.05, noise=0.02)
    chosen = np.asarray(ivm_select(kernel, jnp.asarray(latent), 12))
    covariance = np.asarray(kernel(jnp.asarray(latent), jnp.asarray(latent)))
    noise = float(kernel.noise)
    expected = []
    for _ in range(12):
        # Entropy reduction 0.5 ln(1 + s_j / noise): the largest posterior variance.
        gains = 0.5 * np.log1p(np.diag(covariance) / noise)
        gains[expected] = -np.inf
        j = int(np.argmax(gains))
        expected.append(j)
        covariance = covariance - np.outer(covariance[:, j], covariance[j]) / (covariance[j, j] + noise)
    assert chosen.tolist() == expected
    with pytest.raises(ValueError, match="active set must hold"):
        ivm_select(kernel, jnp.asarray(latent), 41)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_eq2_objective_and_the_inverse_map_find_a_training_points_latent(small_model):
    model, _starts = small_model
    manifold = model.manifold
    predictor = manifold.predictor()
    inactive = np.setdiff1d(np.arange(manifold.latent.shape[0]), np.asarray(manifold.active))[:5]
    # eq. 2 against a NumPy evaluation of eqs. 2-4 on the active set.
    active = np.asarray(manifold.active)
    kernel = manifold.kernel
    XI, YI = np.asarray(manifold.latent)[active], np.asarray(manifold.data)[active]
    K = np.asarray(kernel(jnp.asarray(XI), jnp.asarray(XI))) + float(kernel.noise) * np.eye(len(active))
    x, y = np.asarray(manifold.latent)[inactive[0]], np.asarray(manifold.data)[inactive[0]]
    k = np.asarray(kernel(jnp.asarray(XI), jnp.asarray(x[None])))[:, 0]
    mu = YI.T @ np.linalg.solve(K, k)  # eq. 3
    var = float(kernel.diag(jnp.asarray(x[None]))[0]) - k @ np.linalg.solve(K, k) + float(kernel.noise)  # eq. 4 + noise
    expected = np.sum((y - mu) ** 2) / (2 * var) + 0.5 * y.size * np.log(var) + 0.5 * x @ x
    assert float(point_objective(predictor, jnp.asarray(x), jnp.asarray(y))) == pytest.approx(expected, rel=1e-9)
    # Each inactive point sits at a minimum of eq. 2: a nudge comes back.
    nudged = manifold.latent[inactive] + 0.03
    solved = np.asarray(optimise_points(predictor, nudged, manifold.data[inactive], 100))
    np.testing.assert_allclose(solved, np.asarray(manifold.latent)[inactive], atol=2e-3)
    # Solved a few points at a time (a remainder included), each point comes to the same place.
    chunked = np.asarray(optimise_points(predictor, nudged, manifold.data[inactive], 100, chunk=3))
    np.testing.assert_allclose(chunked, solved, atol=1e-8)
    # eq. 5 (encode by likelihood) of a training pose is that pose's latent point.
    poses = manifold.mean + manifold.scale * manifold.data[inactive]
    encoded = np.asarray(manifold.encode(poses, method="likelihood"))
    np.testing.assert_allclose(encoded, np.asarray(manifold.latent)[inactive], atol=2e-3)


def test_ncc_templates_match_numpy():
    rng = np.random.default_rng(1)
    image = rng.uniform(size=(40, 50))
    markers = np.array([[10.0, 12.0], [30.0, 20.0], [25.0, 8.0]])
    templates = planar.marker_templates(jnp.asarray(image), markers, radius=3, scale=5.0)
    other = rng.uniform(size=(40, 50))
    got = np.asarray(templates.correlations(jnp.asarray(other), jnp.asarray(markers)))

    def patch(img, m):
        u, v = int(m[0]), int(m[1])
        return img[v - 3 : v + 4, u - 3 : u + 4].ravel()

    for i, m in enumerate(markers):
        a, b = patch(other, m) - patch(other, m).mean(), patch(image, m) - patch(image, m).mean()
        assert got[i] == pytest.approx(a @ b / np.sqrt((a @ a) * (b @ b)), rel=1e-5)
    # On its own frame every template correlates perfectly: ln p = scale.
    assert float(templates.log_likelihood(jnp.asarray(image), jnp.asarray(markers))) == pytest.approx(5.0, rel=1e-5)
    with pytest.raises(ValueError, match="leave the 50x40 image"):
        planar.marker_templates(jnp.asarray(image), np.array([[1.0, 12.0]]), radius=3)


def test_arm_chain_and_gauss_newton():
    state = np.array([1.7, 0.4, 0.9, 1.2, -0.3, 1.0])
    first = np.asarray(planar.spm_forward(jnp.asarray(np.concatenate([[50.0, 90.0, np.log(100.0)],
                                                                      np.full(8, 0.2), np.ones(8)]))))
    anchor = planar.arm_anchor(jnp.asarray(first))
    markers = planar.arm_markers(jnp.asarray(state), anchor)
    np.testing.assert_allclose(np.asarray(planar.arm_state_from_markers(markers, anchor)), state, atol=1e-9)
    # Damped Gauss-Newton with the Armijo rule solves a linear least-squares problem.
    rng = np.random.default_rng(2)
    A, b = jnp.asarray(rng.normal(size=(9, 6))), jnp.asarray(rng.normal(size=9))
    x = planar.gauss_newton(lambda x: A @ x - b, jnp.zeros(6), iterations=10, backtracks=6, damping=1e-8)
    np.testing.assert_allclose(np.asarray(x), np.linalg.lstsq(np.asarray(A), np.asarray(b), rcond=None)[0], atol=1e-6)
    # The MHT keeps distinct modes: the best, then the best far enough from it.
    states = jnp.asarray([[0.0], [0.01], [1.0], [2.0]])
    chosen = planar.distinct_best(jnp.asarray([3.0, 2.9, 1.0, 0.5]), states, 3, 0.1)
    assert np.asarray(chosen).tolist() == [0, 2, 3]


def _static_video(size=(64, 80)):
    rng = np.random.default_rng(4)
    image = jax.image.resize(jnp.asarray(rng.uniform(size=(size[0] // 4, size[1] // 4))), size, "linear")
    return np.asarray(image, np.float32)


def _markers():
    state = np.concatenate([[40.0, 50.0, np.log(60.0)], [0.0, 0.0, 1.4, 1.4, 0.3, -1.4, -1.4, -0.3], np.full(8, 0.9)])
    return np.asarray(planar.spm_forward(jnp.asarray(state)))


def _capsule_mask(markers, shape, hand=0.0):
    """The SPM's capsules (``planar.HALF_WIDTHS``) drawn as a boolean mask by brute force."""
    v, u = np.mgrid[: shape[0], : shape[1]]
    pixels = np.stack([u.ravel(), v.ravel()], -1).astype(np.float64)
    spine = np.linalg.norm(markers[1] - markers[0])
    mask = np.zeros(len(pixels), bool)
    for name, _parent, a, b in planar.SPM_LINKS:
        p, q = markers[planar.SPM_MARKERS.index(a)], markers[planar.SPM_MARKERS.index(b)]
        if name.endswith("forearm"):
            q = q + hand * spine * (q - p) / np.linalg.norm(q - p)
        t = np.clip((pixels - p) @ (q - p) / ((q - p) @ (q - p)), 0, 1)
        mask |= np.linalg.norm(pixels - (p + t[:, None] * (q - p)), axis=-1) <= planar.HALF_WIDTHS[name] * spine
    return mask.reshape(shape)


def test_silhouette_chamfer_against_numpy():
    markers = _markers()
    shape = (64, 80)
    mask = _capsule_mask(markers, shape, hand=planar.silhouette_chamfer().hand)
    evidence = planar.silhouette_evidence(jnp.asarray(mask), jax.random.key(0), samples=300, stride=1)
    # Every sample is a foreground pixel; the distance map is the exact distance to the foreground.
    points = np.asarray(evidence.points).astype(int)
    assert mask[points[:, 1], points[:, 0]].all() and np.asarray(evidence.valid).all()
    v, u = np.nonzero(mask)
    grid = np.stack(np.mgrid[: shape[0], : shape[1]][::-1], -1).reshape(-1, 2)
    brute = np.min(np.linalg.norm(grid[:, None] - np.stack([u, v], -1)[None], axis=-1), axis=1).reshape(shape)
    np.testing.assert_allclose(np.asarray(evidence.distance), brute, atol=1e-4)
    # Read from blocks of 2 x 2 pixels (the default), a distance is off by a pixel and a half at most.
    coarse = planar.silhouette_evidence(jnp.asarray(mask), jax.random.key(0), samples=300, stride=2)
    grid_points = jnp.asarray(grid[(grid[:, 0] < shape[1] - 2) & (grid[:, 1] < shape[0] - 2)], jnp.float32)
    exact = brute[np.asarray(grid_points[:, 1], int), np.asarray(grid_points[:, 0], int)]
    assert np.max(np.abs(np.asarray(coarse.outside(grid_points)) - exact)) <= 1.5
    chamfer = planar.silhouette_chamfer(weight=100.0)
    # The pose that drew the mask covers it (up to the pixels' rounding) and lies inside it.
    at_truth = float(chamfer.log_likelihood(evidence, jnp.asarray(markers)))
    assert -0.05 < at_truth <= 0.0
    # Against a NumPy reference at a moved left arm.
    moved = markers.copy()
    moved[[4, 5]] += np.array([12.0, -9.0])
    spine = np.linalg.norm(moved[1] - moved[0])
    links = [(planar.SPM_MARKERS.index(a), planar.SPM_MARKERS.index(b), name) for name, _, a, b in planar.SPM_LINKS]
    axis = np.concatenate([moved[a] + np.linspace(0, 1, 8)[:, None] * (moved[b] - moved[a]) for a, b, _ in links])
    def bilinear(image, x):  # the distance map read between pixels, as the likelihood reads it
        i, j = int(np.floor(x[1])), int(np.floor(x[0]))
        fy, fx = x[1] - i, x[0] - j
        return ((1 - fy) * ((1 - fx) * image[i, j] + fx * image[i, j + 1])
                + fy * ((1 - fx) * image[i + 1, j] + fx * image[i + 1, j + 1]))

    inside = [min(bilinear(brute, x) / spine, 0.5) for x in axis]
    samples = np.asarray(evidence.points, np.float64)
    gaps = []
    for x in samples[samples[:, 1] < moved[0, 1] + 0.1 * spine]:
        best = np.inf
        for a, b, name in links:
            p, q = moved[a], moved[b]
            if name.endswith("forearm"):
                q = q + chamfer.hand * spine * (q - p) / np.linalg.norm(q - p)
            t = np.clip((x - p) @ (q - p) / ((q - p) @ (q - p)), 0, 1)
            best = min(best, max(np.linalg.norm(x - p - t * (q - p)) / spine - planar.HALF_WIDTHS[name], 0.0))
        gaps.append(min(best, 0.5))
    expected = -100.0 * (np.mean(np.square(inside)) + np.mean(np.square(gaps)))
    got = float(chamfer.log_likelihood(evidence, jnp.asarray(moved)))
    np.testing.assert_allclose(got, expected, rtol=1e-4)
    assert got < at_truth - 0.5
    residuals = chamfer.residuals(evidence, jnp.asarray(moved))
    np.testing.assert_allclose(-float(jnp.sum(residuals**2)), got, rtol=1e-5)
    # An empty mask scores every pose 0, finitely.
    empty = planar.silhouette_evidence(jnp.zeros(shape, bool), jax.random.key(1))
    assert float(chamfer.log_likelihood(empty, jnp.asarray(moved))) == 0.0
    assert np.isfinite(np.asarray(jax.grad(lambda m: chamfer.log_likelihood(empty, m))(jnp.asarray(moved)))).all()
    with pytest.raises(ValueError, match="no SPM link"):
        planar.silhouette_chamfer(half_widths={"lhand": 0.1})


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_trackers_hold_a_still_scene_and_chunks_change_nothing(small_model):
    model, _ = small_model
    image = _static_video()
    markers = _markers()
    frames = jnp.asarray(np.repeat(image[None], 6, axis=0))
    key = jax.random.key(5)
    still = planar.get_tracker2d("latentpf2d").build(model, image, markers, particles=16, diffusion=0.0, translation_sd=0.0,
                                                     scale_sd=0.0)
    _, tracks = planar.track_frames(still, frames, key)
    decoded = np.asarray(still.markers(still.start[None])[0])
    np.testing.assert_allclose(np.asarray(tracks), np.broadcast_to(decoded, tracks.shape), atol=1e-3)  # float32 frames
    for name, options in (("latentpf2d", {"particles": 32}), ("condensation2d", {"particles": 64}), ("mht2d", {"modes": 3})):
        tracker = planar.get_tracker2d(name).build(model, image, markers, **options)
        _, whole = planar.track_frames(tracker, frames, key)
        carry, first = planar.track_frames(tracker, frames[:3], key)
        _, rest = planar.track_frames(tracker, frames[3:], key, carry=carry, first_index=4)
        np.testing.assert_allclose(np.concatenate([first, rest]), whole, atol=1e-9, err_msg=name)
        assert np.all(np.isfinite(np.asarray(whole)))
        # The same steps without jit give the same tracks.
        state, templates, loose = tracker.init(key), tracker.templates, []
        for i in range(frames.shape[0]):
            state, m = tracker.step(state, templates, planar.Frame2D(frames[i]), jax.random.fold_in(key, 1 + i))
            loose.append(m)
        # float32 pixels; the MHT's Gauss-Newton solves amplify the rounding of a fused program.
        np.testing.assert_allclose(np.stack(loose), whole, atol=0.2 if name == "mht2d" else 1e-3, err_msg=name)
    with pytest.raises(ValueError, match="takes no option 'speed'"):
        planar.get_tracker2d("mht2d").build(model, image, markers, speed=1.0)
    # With the body's silhouette: chunks change nothing, every tracker stays finite, and the fitted
    # start decodes nearer the given markers than 003's projection.
    masks = jnp.asarray(np.repeat(_capsule_mask(markers, image.shape)[None], 6, axis=0))
    for name in ("latentpf2d", "condensation2d", "mht2d"):
        tracker = planar.get_tracker2d(name).build(model, image, markers, **({"modes": 3} if name == "mht2d" else {"particles": 32}))
        _, whole = planar.track_frames(tracker, frames, key, masks=masks)
        carry, first = planar.track_frames(tracker, frames[:3], key, masks=masks[:3])
        _, rest = planar.track_frames(tracker, frames[3:], key, masks=masks[3:], carry=carry, first_index=4)
        np.testing.assert_allclose(np.concatenate([first, rest]), whole, atol=1e-9, err_msg=name)
        assert np.all(np.isfinite(np.asarray(whole)))
    with pytest.raises(ValueError, match="masks must be boolean"):
        planar.track_frames(tracker, frames, key, masks=masks[:3])
    errors = {}
    for method in planar.START_METHODS:
        start = planar.start_state(model, markers, method=method)
        errors[method] = float(np.mean(np.linalg.norm(np.asarray(still.markers(jnp.asarray(start, jnp.float32)[None])[0]) - markers,
                                                      axis=-1)))
    assert errors["fitted"] <= errors["projection"] + 1e-3, errors
    with pytest.raises(ValueError, match="start must be one of"):
        planar.start_state(model, markers, method="nearest")


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (the fitted model)
def test_model_file_round_trip_and_refusals(small_model, tmp_path):
    model, starts = small_model
    path = tmp_path / "spm.eqx"
    planar.save_spm_model(path, model, starts)
    loaded = planar.load_spm_model(path)
    np.testing.assert_array_equal(np.asarray(loaded.manifold.latent), np.asarray(model.manifold.latent))
    np.testing.assert_array_equal(np.asarray(loaded.manifold.active), np.asarray(model.manifold.active))
    np.testing.assert_array_equal(np.asarray(loaded.step_sd), np.asarray(model.step_sd))
    np.testing.assert_array_equal(np.asarray(loaded.arm_ar.a1), np.asarray(model.arm_ar.a1))
    from jaxtrack.manifold import make_gplvm, save_model

    other = tmp_path / "gplvm.eqx"
    save_model(other, make_gplvm(np.random.default_rng(0).normal(size=(10, 4)), 2))
    with pytest.raises(ValueError, match="not an SPM model"):
        planar.load_spm_model(other)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_track2d_command_writes_tracks_and_refuses_bad_input(small_model, tmp_path, capsys):
    import imageio.v3 as iio

    model, starts = small_model
    planar.save_spm_model(tmp_path / "spm.eqx", model, starts)
    folder = tmp_path / "frames"
    folder.mkdir()
    image = (_static_video() * 255).astype(np.uint8)
    for i in range(5):
        iio.imwrite(folder / f"{i:03d}.png", np.repeat(image[..., None], 3, axis=-1))
    markers = _markers()
    record = {"markers": {name: markers[i].tolist() for i, name in enumerate(planar.SPM_MARKERS)}}
    (tmp_path / "first.json").write_text(json.dumps(record))
    out = tmp_path / "tracks.npz"
    args = ["track2d", "--video", str(folder), "--markers", str(tmp_path / "first.json"), "--model", str(tmp_path / "spm.eqx"),
            "--out", str(out), "--chunk-frames", "2", "--method", "condensation2d"]
    assert main(args) == 0
    tracks = np.load(out)
    assert tracks["markers2d"].shape == (5, 9, 2) and tracks["marker_names"].tolist() == list(planar.SPM_MARKERS)
    np.testing.assert_allclose(tracks["markers2d"][0], markers)
    assert (tmp_path / "tracks_overlay.mp4").stat().st_size > 0
    # With the empty scene: the silhouettes are scored too; an empty scene of another size is refused.
    empty = tmp_path / "empty"
    empty.mkdir()
    for i in range(3):
        iio.imwrite(empty / f"{i:03d}.png", np.full((*image.shape, 3), 128, np.uint8))
    assert main([*args, "--background", str(empty), "--option", "silhouette_weight=500", "--no-overlay"]) == 0
    assert np.isfinite(np.load(out)["markers2d"]).all()
    iio.imwrite(empty / "003.png", np.full((10, 10, 3), 128, np.uint8))
    (empty / "003.png").rename(tmp_path / "small.png")
    small = tmp_path / "small"
    small.mkdir()
    (tmp_path / "small.png").rename(small / "000.png")
    assert main([*args, "--background", str(small), "--no-overlay"]) == 2
    assert "the empty scene is 10x10" in capsys.readouterr().err
    assert main([*args, "--option", "speed=2", "--no-overlay"]) == 2
    assert "takes no option 'speed'" in capsys.readouterr().err
    # A video with fewer frames than asked, a marker file that does not match the model.
    assert main([*args, "--frames", "9", "--no-overlay"]) == 2
    assert "has 5 frames, fewer than the 9 asked for" in capsys.readouterr().err
    del record["markers"]["lwrist"]
    record["markers"]["lhand"] = [1, 2]
    (tmp_path / "first.json").write_text(json.dumps(record))
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "missing lwrist" in err and "unknown lhand" in err
    # Templates that leave the image.
    record["markers"] = {name: markers[i].tolist() for i, name in enumerate(planar.SPM_MARKERS)}
    record["markers"]["head"] = [78.5, 3.0]
    (tmp_path / "first.json").write_text(json.dumps(record))
    assert main(args) == 2
    assert "the templates of head" in capsys.readouterr().err


def test_a_marker_file_must_name_the_models_markers(tmp_path):
    markers = _markers()
    record = {"markers": {name: markers[i].tolist() for i, name in enumerate(planar.SPM_MARKERS)}}
    path = tmp_path / "first.json"
    path.write_text(json.dumps(record))
    np.testing.assert_allclose(planar.read_first_markers(path), markers)
    record["markers"]["lhand"] = record["markers"].pop("lwrist")
    path.write_text(json.dumps(record))
    with pytest.raises(ValueError, match="missing lwrist; unknown lhand"):
        planar.read_first_markers(path)
    record["markers"]["lwrist"] = [1.0, "x"]
    del record["markers"]["lhand"]
    path.write_text(json.dumps(record))
    with pytest.raises(ValueError, match="marker 'lwrist' must be"):
        planar.read_first_markers(path)
    path.write_text("{not json")
    with pytest.raises(ValueError, match="not JSON"):
        planar.read_first_markers(path)


def test_gesture_video_films_the_person_the_empty_scene_and_a_sidestep():
    key = jax.random.key(3)
    still = planar.gesture_video(key, frames=2, fps=1.0, width=64, height=48, background="wall", background_frames=2)
    moved = planar.gesture_video(key, frames=2, fps=1.0, width=64, height=48, background="wall", background_frames=2,
                                 sidestep=0.3)
    assert still.images.shape == (2, 48, 64, 3) and still.images.dtype == np.uint8
    assert still.background.shape == (2, 48, 64, 3) and still.masks.shape == (2, 48, 64) and still.masks.dtype == bool
    assert still.masks.all(axis=(1, 2)).sum() == 0 and still.masks.any(axis=(1, 2)).all()
    # The empty scene is the video where the person is not.
    outside = ~still.masks[0]
    assert np.abs(still.images[0].astype(int) - still.background[0].astype(int))[outside].mean() < 10
    assert np.abs(still.images[0].astype(int) - still.background[0].astype(int))[still.masks[0]].mean() > 10
    # A sidestep (at t = 1 s, a quarter of its 4 s period: 0.3 m) moves every marker across the image,
    # along the camera's horizontal axis: u changes, v does not; frame 0 is where the person stood.
    np.testing.assert_allclose(moved.markers[0], still.markers[0], atol=1e-6)
    shift = moved.markers[1] - still.markers[1]
    assert np.all(np.abs(shift[:, 0]) > 3.0) and np.max(np.abs(shift[:, 1])) < 1e-3
    with pytest.raises(ValueError, match="is a training view"):
        planar.gesture_video(key, view=(30.0, 0.0), frames=2)
