import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.likelihood import (
    bidirectional_silhouette_cost,
    check_silhouettes,
    make_silhouette_likelihood,
    silhouette_statistics_dense,
    silhouette_statistics_windowed,
    suggest_window,
)
from jaxtrack.render import project_capsules, soft_silhouettes

from helpers import finite_difference_check, small_scene


@pytest.fixture(scope="module")
def scene():
    motion, rig, seq = small_scene()
    observed = jnp.asarray(check_silhouettes(seq.silhouettes, rig), jnp.float64)
    return motion, rig, seq, observed


def test_cost_equals_paper_equation_12(scene, getkey):
    """Direct NumPy evaluation of 000 eq. 12 on soft silhouettes, per view, averaged."""
    motion, rig, _seq, observed = scene
    body = motion.body
    poses = jnp.asarray(motion.pose[:1]) + 0.05 * jax.random.normal(getkey(), (3, 32))
    lik = make_silhouette_likelihood(body, rig, window=None, edge_width=1.0, scale=2.0)
    loglik = np.asarray(eqx.filter_jit(lambda l, p, o: l.log_likelihood(p, o))(lik, poses, observed[:, 0]))
    soft = np.asarray(jax.jit(soft_silhouettes)(body, rig, poses, 1.0))
    obs = np.asarray(observed[:, 0])
    for n in range(3):
        terms = []
        for c in range(4):
            s, o = soft[n, c], obs[c]
            terms.append(np.sum(s * (1 - o)) / np.sum(s) + np.sum(o * (1 - s)) / np.sum(o))
        assert loglik[n] == pytest.approx(-2.0 * np.mean(terms), rel=1e-10)


def test_cost_bounds_and_zero_at_perfect_match():
    obs_area = jnp.array([10.0])
    assert float(bidirectional_silhouette_cost(jnp.array([10.0]), jnp.array([10.0]), obs_area)[0]) == 0.0
    assert float(bidirectional_silhouette_cost(jnp.array([10.0]), jnp.array([0.0]), obs_area)[0]) == 2.0
    # Body entirely outside the image: only the data term remains.
    assert float(bidirectional_silhouette_cost(jnp.array([0.0]), jnp.array([0.0]), obs_area)[0]) == 1.0
    grad = jax.grad(lambda a: bidirectional_silhouette_cost(a, jnp.zeros(1), obs_area).sum())(jnp.zeros(1))
    assert np.all(np.isfinite(grad))


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
@pytest.mark.parametrize("case", ["fits", "some_overflow", "all_dense"])
def test_windowed_matches_dense(scene, getkey, case):
    """The windowed evaluation equals the dense reference when every particle-view fits, when
    one dense pass patches the overflowing ones, and when the loop takes several passes."""
    motion, rig, _seq, observed = scene
    body, sk = motion.body, motion.body.skeleton
    poses = jnp.asarray(motion.pose[2]) + 0.02 * jax.random.normal(getkey(), (64, 32))
    # Two particles hold their arms out sideways: wider than a window sized on the data.
    poses = poses.at[:2, sk.dof_index("lshoulder_abd")].set(1.6).at[:2, sk.dof_index("rshoulder_abd")].set(1.6)
    caps = project_capsules(body, rig, poses)
    window = {"fits": (30, 40), "some_overflow": suggest_window(observed[:, 2], row_margin=0.2, col_margin=0.2)}.get(
        case, (10, 8)
    )
    area_d, overlap_d = silhouette_statistics_dense(caps, observed[:, 2], 1.0)
    area_w, overlap_w, count = jax.jit(silhouette_statistics_windowed, static_argnums=(3,))(caps, observed[:, 2], 1.0, window)
    count = int(count)
    if case == "fits":
        assert count == 0
    elif case == "some_overflow":
        assert 0 < count <= (64 * 4) // 32, count
    else:
        assert count > (64 * 4) // 32, count
    np.testing.assert_allclose(area_w, area_d, rtol=1e-5)
    np.testing.assert_allclose(overlap_w, overlap_d, rtol=1e-5, atol=1e-9)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_fast_likelihood_matches_dense_reference_float32(getkey):
    """The headline check in the working precision: relative error below 1e-5."""
    motion, rig, seq = small_scene(num_frames=4, width=80, height=60)
    observed = jnp.asarray(check_silhouettes(seq.silhouettes))
    body32 = jax.tree.map(lambda x: x.astype(jnp.float32) if eqx.is_inexact_array(x) else x, motion.body)
    rig32 = jax.tree.map(lambda x: x.astype(jnp.float32) if eqx.is_inexact_array(x) else x, rig)
    poses = jnp.asarray(motion.pose[1], jnp.float32) + 0.05 * jax.random.normal(getkey(), (200, 32), jnp.float32)
    fast = make_silhouette_likelihood(body32, rig32, silhouettes=observed)
    dense = make_silhouette_likelihood(body32, rig32, window=None)
    assert fast.window is not None and fast.window != (60, 80)
    a = eqx.filter_jit(lambda l, p, o: l.log_likelihood(p, o))(fast, poses, observed[:, 1])
    b = eqx.filter_jit(lambda l, p, o: l.log_likelihood(p, o))(dense, poses, observed[:, 1])
    assert a.dtype == jnp.float32
    np.testing.assert_allclose(a, b, rtol=1e-5)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_true_pose_scores_best_on_noisy_scene(getkey):
    """At the working resolution (80x60) the true pose beats 100 perturbations in every frame."""
    motion, rig, seq = small_scene(num_frames=4, width=80, height=60)
    observed = jnp.asarray(check_silhouettes(seq.silhouettes, rig), jnp.float64)
    lik = make_silhouette_likelihood(motion.body, rig, silhouettes=observed)
    score = eqx.filter_jit(lambda l, p, o: l.log_likelihood(p, o))
    wins = 0
    for t in range(seq.num_frames):
        truth = jnp.asarray(motion.pose[t])
        sigma = jnp.full(32, 0.15).at[:3].set(0.05)
        candidates = truth + sigma * jax.random.normal(getkey(), (100, 32))
        scores = score(lik, jnp.concatenate([truth[None], candidates]), observed[:, t])
        wins += int(jnp.argmax(scores) == 0)
    assert wins == seq.num_frames


@pytest.mark.slow
def test_likelihood_gradient_matches_finite_differences(scene, getkey):
    motion, rig, _seq, observed = scene
    lik = make_silhouette_likelihood(motion.body, rig, window=(24, 16), edge_width=1.5)
    pose = jnp.asarray(motion.pose[3]) + 0.03 * jax.random.normal(getkey(), (32,))
    f = lambda p: lik.log_likelihood(p[None], observed[:, 3])[0]  # noqa: E731
    finite_difference_check(f, pose, jax.random.normal(getkey(), (32,)) * 0.1, rtol=1e-4, atol=1e-8)  # checks finiteness too


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_jit_vmap_and_no_jit_agree(scene, getkey):
    motion, rig, _seq, observed = scene
    lik = make_silhouette_likelihood(motion.body, rig, silhouettes=observed)
    poses = jnp.asarray(motion.pose[0]) + 0.05 * jax.random.normal(getkey(), (3, 32))
    score = eqx.filter_jit(lambda l, p, o: l(p, o))
    jitted = score(lik, poses, observed[:, 0])
    with jax.disable_jit():
        plain = lik(poses, observed[:, 0])
    looped = jnp.stack([score(lik, p[None], observed[:, 0])[0] for p in poses])
    np.testing.assert_allclose(jitted, plain, rtol=1e-10)
    np.testing.assert_allclose(jitted, looped, rtol=1e-10)


@pytest.mark.slow
def test_camera_behind_body_gives_minus_infinity(scene):
    motion, rig, _seq, observed = scene
    lik = make_silhouette_likelihood(motion.body, rig, silhouettes=observed)
    centre = np.asarray(rig.centers[0])
    pose = jnp.asarray(motion.pose[0]).at[:3].set(jnp.asarray(centre + np.asarray(rig.R[0])[2] * -0.5))
    score = eqx.filter_jit(lambda l, p, o: l.log_likelihood(p, o))
    out = score(lik, jnp.stack([jnp.asarray(motion.pose[0]), pose]), observed[:, 0])
    assert np.isfinite(float(out[0])) and float(out[1]) == -np.inf

    def finite_part(p):
        s = lik.log_likelihood(p[None], observed[:, 0])[0]
        return jnp.where(jnp.isfinite(s), s, 0.0)

    grad = jax.jit(jax.grad(finite_part))(pose)
    assert np.all(np.isfinite(grad))


def test_silhouette_validation(scene):
    motion, rig, seq, _observed = scene
    sil = np.array(seq.silhouettes)
    assert check_silhouettes(sil * 255, rig).max() == 1.0
    empty = sil.copy()
    empty[2, 5] = 0
    with pytest.raises(ValueError, match="empty silhouette in view 2, frame 5"):
        check_silhouettes(empty, rig)
    full = sil.copy()
    full[1, 3] = 1
    with pytest.raises(ValueError, match="silhouette in view 1, frame 3 is all foreground"):
        check_silhouettes(full, rig)
    with pytest.raises(ValueError, match="0/1 or 0/255"):
        check_silhouettes(sil * 7, rig)
    with pytest.raises(ValueError, match="3 views, the camera rig has 4"):
        check_silhouettes(sil[:3], rig)
    with pytest.raises(ValueError, match="the cameras expect 30x40"):
        check_silhouettes(sil[..., :20], rig)
    with pytest.raises(ValueError, match="NaN"):
        check_silhouettes(np.full((4, 30, 40), np.nan), rig)
    with pytest.raises(ValueError, match="edge_width"):
        make_silhouette_likelihood(motion.body, rig, edge_width=0.0)
    with pytest.raises(ValueError, match="must fit"):
        make_silhouette_likelihood(motion.body, rig, window=(31, 10))
    with pytest.raises(ValueError, match=r"silhouettes= must be \(views, height, width\)"):
        make_silhouette_likelihood(motion.body, rig, silhouettes=np.ones((5, 30)))


def test_masks_of_any_convention_score_alike_and_a_transposed_frame_is_refused(scene):
    motion, rig, _seq, observed = scene
    likelihood = make_silhouette_likelihood(motion.body, rig, window=None)
    poses = jnp.asarray(motion.pose[:3], jnp.float64)
    frame = observed[:, 0]  # (views, H, W) in {0, 1}
    jitted = eqx.filter_jit(lambda lik, p, o: lik.log_likelihood(p, o))
    reference = np.asarray(jitted(likelihood, poses, frame))
    scored = jitted(likelihood, poses, jnp.asarray(np.asarray(frame, np.uint8) * 255))  # 0/255 uint8 masks
    np.testing.assert_allclose(np.asarray(scored), reference, rtol=1e-12)
    with pytest.raises(ValueError, match=r"values in \[0, 1\], found up to 255"):
        likelihood.log_likelihood(poses, frame * 255.0)  # refused before anything is computed
    with pytest.raises(ValueError, match=r"\(views, height, width\) = \(4, 30, 40\), got \(4, 40, 30\) \(transposed"):
        jitted(likelihood, poses, jnp.swapaxes(frame, 1, 2))
    with pytest.raises(ValueError, match=r"got \(3, 30, 40\)"):
        jitted(likelihood, poses, frame[:3])
    # One NaN pixel in a 4x30x40 float32 frame: XLA's vectorised min and max on a CPU pass it over
    # (they return 0 and 1), so the check tests every element (docs/robustness.md).
    with pytest.raises(ValueError, match="NaN or infinite"):
        likelihood.log_likelihood(poses, jnp.asarray(frame, jnp.float32).at[0, 0, 0].set(jnp.nan))


def test_suggest_window_ignores_clutter():
    sil = np.zeros((1, 60, 80), np.uint8)
    sil[0, 10:40, 30:40] = 1  # the person
    sil[0, 55:58, 0:3] = 1  # a clutter blob far away
    rows, cols = suggest_window(sil, edge_width=1.0, row_margin=0.0, col_margin=0.0)
    assert rows == 30 + 4 and cols == 16


def test_a_sum_of_likelihoods_is_a_likelihood():
    from jaxtrack.likelihood import AbstractLikelihood, FunctionLikelihood, SumLikelihood, as_likelihood

    a = as_likelihood(lambda poses, obs: -jnp.sum((poses - obs) ** 2, axis=1))
    b = FunctionLikelihood(lambda poses, obs: -jnp.abs(poses[:, 0]))
    total = a + b
    assert isinstance(total, SumLikelihood) and isinstance(total, AbstractLikelihood)
    poses, obs = jnp.array([[0.0, 1.0], [2.0, -1.0]]), jnp.array([1.0, 1.0])
    np.testing.assert_allclose(total(poses, obs), a(poses, obs) + b(poses, obs))
    np.testing.assert_allclose(jax.jit(total.log_likelihood)(poses, obs), [-1.0, -7.0])
    assert as_likelihood(total) is total
    with pytest.raises(TypeError, match="AbstractLikelihood or a callable"):
        as_likelihood(3.0)
    with pytest.raises(TypeError, match="one or more AbstractLikelihood"):
        SumLikelihood(())


@pytest.mark.slow
def test_shape_calibration_recovers_known_radii():
    """Silhouettes rendered (clean, 160x120) from a body whose torso is 20 % thicker, legs 15 %
    thinner and arms 10 % thicker than the default: calibrating from the default capsules with
    the poses known (and a weak prior, sd 0.5 in log radius) recovers the radii of every capsule
    that shows outside the others (the clavicles and the neck hide inside the torso and head,
    and are left to the prior)."""
    import dataclasses

    from jaxtrack.camera import default_rig
    from jaxtrack.data import NO_NOISE, build_scene, generate_motion
    from jaxtrack.likelihood import calibrate_shape

    motion = generate_motion("walk", "S1", num_frames=12, fps=30.0, key=jax.random.key(0))
    factors = {"torso": 1.2, "legs": 0.85, "arms": 1.1, "head": 1.0}
    default = motion.body
    true_radii = np.asarray(default.radii) * np.array([factors[g] for g in default.capsule_groups])
    subject = dataclasses.replace(motion, body=eqx.tree_at(lambda b: b.radii, default, jnp.asarray(true_radii, default.radii.dtype)))
    rig = default_rig(160, 120)
    scene = build_scene(jax.random.key(1), subject, rig, NO_NOISE)
    observed = np.moveaxis(check_silhouettes(scene.silhouettes, rig), 1, 0)
    likelihood = make_silhouette_likelihood(default, rig, scale=100.0, window=None)
    frames = [0, 4, 8]
    calibrated, report = calibrate_shape(likelihood, scene.pose[frames], observed[frames], prior_sd=0.5)
    visible = [i for i, n in enumerate(default.capsule_names) if n not in ("lclavicle", "rclavicle", "neck")]
    np.testing.assert_allclose(report.radii_after[visible], true_radii[visible], rtol=0.06)
    assert np.abs(report.radii_before[visible] / true_radii[visible] - 1).max() > 0.15  # it had something to correct
    assert report.cost_after < 0.85 * report.cost_before
    np.testing.assert_allclose(np.asarray(calibrated.body.radii), report.radii_after, rtol=1e-6)
    with pytest.raises((ValueError, TypeError)):  # (jaxtyping's frame-count check comes first in the tests)
        calibrate_shape(likelihood, scene.pose[frames], observed[:2])
    empty = observed[frames].copy()
    empty[1, 2] = 0
    with pytest.raises(ValueError, match="frame 1, view 2 is empty"):
        calibrate_shape(likelihood, scene.pose[frames], empty)


@pytest.mark.slow
def test_a_coarse_level_scores_like_every_pixel_of_a_large_image():
    """320x240 silhouettes block-averaged to 80x60 (the cameras rescaled; what ``--resolution``
    tracks at) give 000 eq. 12's cost of every 320x240 pixel to within a small bias, and rank
    poses the same way: measured around a noisy walk's first frame (``benchmarks/
    bench_resolution.py`` measures it on 200 poses and the tracking error it gives)."""
    from jaxtrack.camera import default_rig
    from jaxtrack.data import SilhouetteNoise, build_scene, generate_motion
    from jaxtrack.tracking import prepare_test

    motion = generate_motion("walk", "S1", num_frames=2, fps=60.0, key=jax.random.key(0))
    scene = build_scene(jax.random.key(1), motion, default_rig(320, 240, num_views=3), SilhouetteNoise())
    fine = prepare_test(scene, "walk", key=jax.random.key(2), frames=1, window=None)
    coarse = prepare_test(scene, "walk", key=jax.random.key(2), frames=1, window=None, resolution=(80, 60))
    truth = fine.initial_pose
    spread = jnp.full(truth.shape, 0.1, truth.dtype).at[:3].set(0.03)
    poses = truth + spread * jax.random.normal(jax.random.key(3), (48, truth.shape[0]), truth.dtype)
    cost_fine = -np.asarray(fine.likelihood(poses, fine.observations[0])) / float(fine.likelihood.scale)
    cost_coarse = -np.asarray(coarse.likelihood(poses, coarse.observations[0])) / float(coarse.likelihood.scale)
    bias = cost_coarse - cost_fine
    assert abs(float(bias.mean())) < 0.05 and float(bias.std()) < 0.03, (bias.mean(), bias.std())
    assert np.corrcoef(cost_coarse, cost_fine)[0, 1] > 0.97


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_coarse_likelihood_scores_the_block_averaged_silhouettes_on_resized_cameras(scene, getkey):
    """``coarsen_likelihood``: factor 1 is the likelihood itself (to rounding); factor 2 equals the
    silhouette likelihood of the half-size rig on the silhouettes ``jaxtrack.image`` downsamples
    (the same block average and threshold), its window shrunk with the image; the silhouettes
    plus the ground prior (the experiment's default) coarsen the silhouettes and keep the prior;
    bad factors and a likelihood that is not the silhouette one are refused."""
    from jaxtrack.image import downsample_silhouettes
    from jaxtrack.likelihood import FunctionLikelihood, coarsen_likelihood, make_ground_prior

    motion, rig, _seq, observed = scene
    fine_rig = rig.resized(80, 60)
    observed = jnp.asarray(downsample_silhouettes(np.kron(np.asarray(observed[:, 0]), np.ones((2, 2))), 80, 60), jnp.float64)
    poses = jnp.asarray(motion.pose[:1]) + 0.05 * jax.random.normal(getkey(), (16, 32))
    score = eqx.filter_jit(lambda lik, p, o: lik(p, o))
    fine = make_silhouette_likelihood(motion.body, fine_rig, window=None)
    np.testing.assert_allclose(score(coarsen_likelihood(fine, 1), poses, observed), score(fine, poses, observed), rtol=1e-12)
    half = jnp.asarray(downsample_silhouettes(np.asarray(observed), 40, 30), jnp.float64)
    reference = make_silhouette_likelihood(motion.body, fine_rig.resized(40, 30), window=None)
    coarse = coarsen_likelihood(make_silhouette_likelihood(motion.body, fine_rig, window=(40, 24)), 2)
    assert coarse.coarse.rig.image_size[0] == (40, 30) and coarse.coarse.window == (21, 13)
    np.testing.assert_allclose(score(coarse, poses, observed), score(reference, poses, half), rtol=1e-10)
    prior = make_ground_prior(motion.body.skeleton, 0.2)  # above the ankles: every pose pays
    assert float(jnp.min(-score(prior, poses, observed))) > 1.0
    grounded = coarsen_likelihood(make_silhouette_likelihood(motion.body, fine_rig, window=(40, 24)) + prior, 2)
    assert grounded.terms[1] is prior
    np.testing.assert_allclose(score(grounded, poses, observed), score(reference, poses, half) + score(prior, poses, half), rtol=1e-10)
    with pytest.raises(TypeError, match="every term of this SumLikelihood ignores the frame"):
        coarsen_likelihood(prior + prior, 2)
    with pytest.raises(ValueError, match="a factor of 3x3 does not divide the 80x60 images"):
        coarsen_likelihood(fine, 3)
    with pytest.raises(ValueError, match="factor must be a positive integer"):
        coarsen_likelihood(fine, 0)
    with pytest.raises(TypeError, match="coarse-to-fine needs a SilhouetteLikelihood"):
        coarsen_likelihood(FunctionLikelihood(lambda p, o: jnp.zeros(p.shape[0])), 2)
    with pytest.raises(ValueError, match="observed silhouettes are 40x30; this coarse likelihood expects 80x60"):
        coarse(poses, half)
