"""The tracker registry as an extension point, the pipeline's precision boundary and key
streams, and the run of a tracker defined here through the experiment API and the CLI."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.dynamics import AbstractDynamics, fit_pose_random_walk, gaussian_step
from jaxtrack.experiment import ExperimentConfig, results_table, run_experiment
from jaxtrack.filters import SIR, BestParticle, run_filter
from jaxtrack.tracking import (
    Budget,
    MotionData,
    TrackerRecipe,
    available_trackers,
    build_tracker,
    get_tracker,
    register_tracker,
    tracker_index,
    unregister_tracker,
)

from helpers import small_experiment_sequences, small_tracking_inputs


class DampedWalk(AbstractDynamics):
    """A dynamics written outside the package: a random walk whose joint angles relax towards a
    rest pose, ``x_t = rest + rho (x_{t-1} - rest) + N(0, s^2)``."""

    rest: jax.Array
    rho: jax.Array
    scales: jax.Array

    def init(self, key, pose, num_particles):
        return jnp.broadcast_to(pose.astype(self.scales.dtype), (num_particles, pose.shape[0]))

    def to_pose(self, states):
        return states

    def propose(self, key, previous):
        mean = self.rest + self.rho * (previous - self.rest)
        return gaussian_step(key, mean, self.scales), jnp.zeros(previous.shape[0], previous.dtype)

    def perturb(self, key, states, factor):
        return gaussian_step(key, states, self.scales * factor)


def fit_damped(key, motion: MotionData):
    del key
    walk = fit_pose_random_walk(list(motion.validation))
    rest = np.concatenate(motion.training).mean(axis=0)
    return DampedWalk(rest=jnp.asarray(rest), rho=jnp.asarray(0.95), scales=walk.scales)


def build_damped(dynamics, likelihood, budget):
    return SIR(dynamics, likelihood, budget.evaluations, estimator=BestParticle())


DAMPED = TrackerRecipe("test-damped", "Damped", "SIR with a damped random walk, best-particle estimate (test)", fit_damped,
                       build_damped)


@pytest.fixture
def damped_registered():
    register_tracker(DAMPED, replace=True)
    yield DAMPED
    unregister_tracker(DAMPED.name)


@pytest.fixture(scope="module")
def sequences():
    return small_experiment_sequences()


def test_builtin_trackers_are_registered():
    assert available_trackers()[:6] == ("sir", "apf", "mrpf", "gpapf", "latentpf", "mrpf-alg1")
    assert [tracker_index(n) for n in ("sir", "apf", "mrpf", "gpapf", "latentpf")] == [0, 1, 2, 3, 4]
    assert get_tracker("gpapf").annealed and get_tracker("gpapf").min_layers == 2
    with pytest.raises(ValueError, match="already registered"):
        register_tracker(get_tracker("sir"))
    with pytest.raises(ValueError, match="unknown tracker 'nope'; registered trackers: sir, apf"):
        get_tracker("nope")
    with pytest.raises(TypeError, match="TrackerRecipe"):
        register_tracker("sir")
    with pytest.raises(ValueError, match="non-empty word"):
        TrackerRecipe("two words", "x", "x", fit_damped, build_damped)
    with pytest.raises(ValueError, match="latent_dim must be a positive integer or None"):
        TrackerRecipe("flat", "x", "x", fit_damped, build_damped, needs_manifold=True, latent_dim=0)
    with pytest.raises(ValueError, match="positive integer"):
        Budget(0)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_a_tracker_defined_here_runs_through_the_experiment_api(damped_registered, sequences, tmp_path):
    train, validation, test = sequences
    assert "test-damped" in available_trackers()
    config = ExperimentConfig(methods=("sir", "test-damped"), budget=60, runs=2, frames=5)
    assert not config.needs_manifold  # no manifold is fitted for these two
    results = run_experiment(train, validation, test, config, out_dir=str(tmp_path), names={"test": ["walk.npz"]},
                             progress=False, animations=False)
    damped = results["sequences"]["walk.npz"]["test-damped"]
    assert np.isfinite(damped["error_mm_mean"]) and damped["error_mm_mean"] < 300
    assert len(damped["error_mm_per_run"]) == 2 and damped["error_mm_per_run"][0] != damped["error_mm_per_run"][1]
    assert len(damped["per_frame_error_mm"]) == 5 and damped["degenerate_fraction"] == 0.0
    assert results["dynamics"]["test-damped"]["class"] == "DampedWalk"
    assert results["dynamics"]["test-damped"]["rho"] == pytest.approx(0.95)
    assert results_table(results).startswith("| Sequence | SIR | Damped |")
    # the same tracker alone gives the same numbers: its keys come from its registry position
    alone = run_experiment(train, validation, test, ExperimentConfig(methods=("test-damped",), budget=60, runs=2, frames=5),
                           progress=False)
    assert alone["sequences"]["test0"]["test-damped"]["error_mm_per_run"] == damped["error_mm_per_run"]
    saved = json.loads((tmp_path / "results.json").read_text())
    assert saved["config"]["methods"] == ["sir", "test-damped"]


PLUGIN = '''
import jax.numpy as jnp
from jaxtrack.dynamics import fit_pose_random_walk, PoseRandomWalk
from jaxtrack.filters import SIR
from jaxtrack.tracking import TrackerRecipe, register_tracker


def fit(key, motion):
    return PoseRandomWalk(0.5 * jnp.asarray(fit_pose_random_walk(list(motion.validation)).scales))


register_tracker(TrackerRecipe("plugin-sir", "PluginSIR", "SIR with half the fitted steps", fit,
                               lambda dynamics, likelihood, budget: SIR(dynamics, likelihood, budget.evaluations)), replace=True)
'''


@pytest.mark.slow  # moved to the slow suite for the default suite's 10 minutes
def test_a_plugin_tracker_runs_through_the_command_line(sequences, tmp_path, capsys):
    from jaxtrack.cli import main
    from jaxtrack.io import save_sequence

    train, validation, test = sequences
    paths = {}
    for name, seq in (("train", train[0]), ("validation", validation[0]), ("test", test[0])):
        paths[name] = str(tmp_path / f"{name}.npz")
        save_sequence(paths[name], seq)
    plugin = tmp_path / "my_trackers.py"
    plugin.write_text(PLUGIN)
    try:
        code = main(["experiment", "--plugin", str(plugin), "--train", paths["train"], "--validation", paths["validation"],
                     "--test", paths["test"], "--methods", "plugin-sir", "--budget", "40", "--runs", "1", "--frames", "3",
                     "--no-animation", "--out", str(tmp_path / "out")])
        assert code == 0, capsys.readouterr().err
        assert "| test.npz |" in (tmp_path / "out" / "table.md").read_text()
        assert "PluginSIR" in capsys.readouterr().out
    finally:
        unregister_tracker("plugin-sir")
    assert main(["experiment", "--plugin", str(tmp_path / "missing.py"), "--train", "x"]) == 2
    assert "cannot load plugin" in capsys.readouterr().err


def test_build_casts_once_to_float32_and_clips(sequences):
    """Dynamics fitted in float64 reach the filter in float32; a scale beyond float32's range
    is clipped to its largest value instead of overflowing to inf."""
    from jaxtrack.dynamics import PoseRandomWalk
    from jaxtrack.likelihood import as_likelihood

    fitted = PoseRandomWalk(jnp.asarray(np.array([1e-3, 2e47]), jnp.float64))
    flat = as_likelihood(lambda poses, obs: jnp.zeros(poses.shape[0], poses.dtype))
    tracker = build_tracker(get_tracker("sir"), fitted, flat, Budget(10))
    assert tracker.dynamics.scales.dtype == jnp.float32
    assert np.isfinite(np.asarray(tracker.dynamics.scales)).all()
    assert float(tracker.dynamics.scales[1]) == float(np.finfo(np.float32).max)
    with pytest.raises(ValueError, match="cannot be split into 3 equal annealing layers for APF"):
        build_tracker(get_tracker("apf"), fitted, flat, Budget(100, 3))


def test_build_gives_any_tracker_a_velocity():
    """``build_tracker(..., velocity_from=)`` wraps the filter's dynamics in a velocity fitted on
    the validation poses (in float64, cast to float32 with the rest); the annealed trackers'
    final layer keeps its pose random walk."""
    from jaxtrack.dynamics import PoseRandomWalk, StateVelocity, VelocityFit
    from jaxtrack.likelihood import as_likelihood
    from jaxtrack.tracking import fit_velocity

    poses = np.cumsum(np.full((20, 8), 0.01), axis=0)
    fitted = PoseRandomWalk(jnp.full(8, 0.1, jnp.float64))
    velocity = fit_velocity(fitted, [poses])
    assert isinstance(velocity, VelocityFit) and velocity.acceleration.dtype == jnp.float64
    flat = as_likelihood(lambda p, obs: jnp.zeros(p.shape[0], p.dtype))
    for name, budget in (("sir", Budget(10)), ("apf", Budget(30, 3))):
        tracker = build_tracker(get_tracker(name), fitted, flat, budget, velocity_from=[poses])
        assert isinstance(tracker.dynamics, StateVelocity) and tracker.dynamics.acceleration.dtype == jnp.float32
        np.testing.assert_allclose(tracker.dynamics.initial_speed, velocity.initial_speed, rtol=1e-6)
        assert tracker.init(jax.random.key(0), jnp.zeros(8)).particles.shape == (10, 8 + 4 * 6 + 1)


def test_refined_budget_pays_for_gradients_with_particles():
    """A budget with refined moves buys fewer particles (a gradient counts as ``gradient_cost``
    evaluations), and ``build_tracker`` gives any SIR- or APF-built tracker the moves."""
    from jaxtrack.dynamics import PoseRandomWalk
    from jaxtrack.filters import LangevinRefinement
    from jaxtrack.likelihood import as_likelihood

    budget = Budget(500, 5, refine_steps=2, gradient_cost=10.0)
    assert (budget.particles, budget.per_layer) == (500 // 21, 500 // 25)
    assert Budget(500, 5).per_layer == 100 and Budget(500).particles == 500
    fitted = PoseRandomWalk(jnp.full(3, 0.1, jnp.float64))
    flat = as_likelihood(lambda poses, obs: jnp.zeros(poses.shape[0], poses.dtype))
    sir = build_tracker(get_tracker("sir"), fitted, flat, Budget(100, 1, 2, 10.0))
    assert sir.num_particles == 100 // 21 and sir.refine == LangevinRefinement(2)
    apf = build_tracker(get_tracker("apf"), fitted, flat, Budget(100, 3, 1, 10.0))  # no divisibility needed
    assert apf.num_particles == 100 // 13 and apf.refine.num_steps == 1
    assert build_tracker(get_tracker("sir"), fitted, flat, Budget(100)).refine is None
    with pytest.raises(ValueError, match="cannot pay for one particle and 3 refined moves"):
        Budget(30, 5, refine_steps=3, gradient_cost=10.0)
    # Five layers are the annealed trackers' business: SIR runs on a budget of 1, APF names itself.
    get_tracker("sir").check_budget(Budget(1, 5))
    with pytest.raises(ValueError, match="one particle through 5 annealing layers of APF; give at least 5"):
        get_tracker("apf").check_budget(Budget(4, 5))
    with pytest.raises(ValueError, match="the budget pays for 2"):
        build_tracker(get_tracker("sir"), fitted, flat, Budget(100, 1, 2, 10.0), LangevinRefinement(3))


@pytest.mark.slow  # moved to the slow suite for the default suite's 10 minutes
def test_tracking_at_a_lower_resolution():
    """A 160x120 scene tracked at 80x60: the silhouettes are block-averaged, the cameras rescaled,
    and both agree with the scene rendered at 80x60 directly."""
    from jaxtrack.camera import default_rig, project_points
    from jaxtrack.data import NO_NOISE, build_scene, generate_motion
    from jaxtrack.image import downsample_silhouettes
    from jaxtrack.tracking import prepare_test

    motion = generate_motion("walk", "S1", num_frames=3, fps=30.0, key=jax.random.key(0), dtype=jnp.float64)
    fine = build_scene(jax.random.key(1), motion, default_rig(160, 120, dtype=jnp.float64), NO_NOISE)
    coarse = build_scene(jax.random.key(1), motion, default_rig(80, 60, dtype=jnp.float64), NO_NOISE)
    scene = prepare_test(fine, "fine", key=jax.random.key(2), resolution=(80, 60))
    assert scene.observations.shape == (3, 4, 60, 80)
    assert scene.likelihood.rig.image_size == ((80, 60),) * 4
    agreement = np.mean(np.asarray(scene.observations) == np.moveaxis(coarse.silhouettes > 0, 1, 0))
    assert agreement > 0.98, agreement
    points = jnp.asarray(motion.joints3d[0], jnp.float32)
    np.testing.assert_allclose(project_points(scene.likelihood.rig, points)[0], project_points(coarse.rig(dtype=jnp.float32), points)[0],
                               atol=1e-3)
    np.testing.assert_array_equal(downsample_silhouettes(np.array([[0, 255, 255, 255], [0, 0, 255, 0]]), 2, 1), [[0.0, 1.0]])
    with pytest.raises(ValueError, match="cannot resample 160x120 images to 100x60"):
        prepare_test(fine, "fine", key=jax.random.key(2), resolution=(100, 60))


@pytest.mark.slow
def test_batched_sequences_equal_separate_tracks():
    """``track_sequences``: equal-length sequences of one subject in one rig, tracked in one
    vmapped call, give each sequence's own ``track`` (float32: equal to rounding)."""
    from jaxtrack.camera import default_rig
    from jaxtrack.data import SilhouetteNoise, build_scene, generate_motion
    from jaxtrack.tracking import prepare_test, track, track_sequences

    rig = default_rig(40, 30, dtype=jnp.float64)

    def scene(subject, tag, frames=4):
        motion = generate_motion("walk", subject, num_frames=frames, fps=30.0, key=jax.random.key(tag), dtype=jnp.float64)
        built = build_scene(jax.random.key(100 + tag), motion, rig, SilhouetteNoise())
        return motion, prepare_test(built, f"walk {tag}", key=jax.random.key(tag))

    (motion, first), (_, second) = scene("S1", 0), scene("S1", 1)
    tracker = SIR(fit_pose_random_walk([np.asarray(motion.pose)], dtype=jnp.float32), first.likelihood, 60)
    keys = jax.random.split(jax.random.key(7), 2)
    poses, joints, info = track_sequences(tracker, keys, [first, second])
    assert poses.shape == (2, 4, motion.pose.shape[1]) and joints.shape[:2] == (2, 4) and info.ess.shape == (2, 4)
    for s, scene_s in enumerate((first, second)):
        alone, alone_joints, _ = track(tracker, keys[s], scene_s)
        np.testing.assert_allclose(poses[s], alone, atol=1e-3)
        np.testing.assert_allclose(joints[s], alone_joints, atol=1e-3)
    assert np.abs(poses[0] - poses[1]).max() > 1e-2  # two sequences, not one twice
    with pytest.raises(ValueError, match="2 keys for 1 scenes"):
        track_sequences(tracker, keys, [first])
    with pytest.raises(ValueError, match="another body than scene 0"):
        track_sequences(tracker, keys, [first, scene("S2", 2)[1]])
    with pytest.raises(ValueError, match="observations"):
        track_sequences(tracker, keys, [first, scene("S1", 3, frames=5)[1]])


@pytest.mark.slow
def test_tracking_on_sampled_pixels(tmp_path, capsys):
    """``prepare_test(pixel_samples=n)``: the sampled likelihood with one ``PixelSample`` per
    frame as the observations; runs batched in one call equal separate runs, and the estimates
    stay on the person (160x120, SIR, 4 frames)."""
    from jaxtrack.camera import default_rig
    from jaxtrack.data import SilhouetteNoise, build_scene, generate_motion
    from jaxtrack.errors import ConfigurationError
    from jaxtrack.likelihood import PixelSample, SampledSilhouetteLikelihood
    from jaxtrack.tracking import prepare_test, track, track_runs

    motion = generate_motion("walk", "S1", num_frames=4, fps=30.0, key=jax.random.key(0), dtype=jnp.float64)
    built = build_scene(jax.random.key(1), motion, default_rig(160, 120, num_views=3, dtype=jnp.float64), SilhouetteNoise())
    scene = prepare_test(built, "walk", key=jax.random.key(2), pixel_samples=512)
    assert isinstance(scene.likelihood, SampledSilhouetteLikelihood) and isinstance(scene.observations, PixelSample)
    assert scene.observations.u.shape == (4, 3, 512) and scene.num_frames == 4
    again = prepare_test(built, "walk", key=jax.random.key(2), pixel_samples=512)
    np.testing.assert_array_equal(np.asarray(again.observations.u), np.asarray(scene.observations.u))  # keyed
    tracker = SIR(fit_pose_random_walk([np.asarray(motion.pose)], dtype=jnp.float32), scene.likelihood, 100)
    keys = jax.random.split(jax.random.key(7), 2)
    poses, joints, _ = track_runs(tracker, keys, scene)
    for r in range(2):
        alone, _, _ = track(tracker, keys[r], scene)
        np.testing.assert_allclose(poses[r], alone, atol=1e-3)
    error = np.linalg.norm(joints - np.asarray(motion.joints3d)[None], axis=-1).mean() * 1000
    assert error < 60, error
    with pytest.raises(ConfigurationError, match="pixel_samples"):
        ExperimentConfig(pixel_samples=2)
    from jaxtrack.cli import main

    inputs = ["--train", "walk.npz", "--validation", "walk.npz", "--test", "walk.npz", "--out", str(tmp_path / "out")]
    assert main(["experiment", *inputs, "--pixel-samples", "2"]) == 2
    assert "pixel_samples must be a whole number >= 4" in capsys.readouterr().err


@pytest.mark.slow  # 75 s on 2 cores: six trackers compiled, two with and without a residual
def test_every_paper_tracker_tracking_blind_leaks_no_nans():
    """Every particle of every paper tracker scores -inf, with each tracker's defaults (the
    velocity and its rest draws, GPAPF's final layer, LatentPF's latent estimate, the graph
    walk) and with an off-manifold residual: every frame is reported degenerate, and the
    estimates, weights and particles stay finite."""
    from jaxtrack.likelihood import as_likelihood
    from jaxtrack.tracking import PAPER_TRACKERS, fit_manifold, fit_tracker, motion_data

    key = jax.random.key(0)
    scene, train_poses, validation_poses = small_tracking_inputs(4)
    blind = as_likelihood(lambda poses, observation: jnp.full(poses.shape[0], -jnp.inf, poses.dtype))
    motions = {}
    for name in PAPER_TRACKERS:
        recipe = get_tracker(name)
        spec = (recipe.manifold, recipe.latent_dim) if recipe.needs_manifold else None
        if spec not in motions:
            model, starts = None, None
            if spec is not None:
                model, _, starts = fit_manifold(train_poses, spec[1], 5, kind=spec[0])
            motions[spec] = motion_data(train_poses, validation_poses, model, starts)
        fitted = fit_tracker(recipe, key, motions[spec])
        residuals = ((0.0, 1.0), (1.0, 0.9)) if name in ("latentpf", "glegbpf") else ((0.0, 1.0),)
        for residual, decay in residuals:
            tracker = build_tracker(recipe, fitted, blind, Budget(40, 2), velocity_from=validation_poses if recipe.velocity else None,
                                    residual_from=validation_poses, residual_scale=residual, residual_decay=decay)
            state, info = run_filter(tracker, jax.random.key(1), scene.initial_pose, scene.observations)
            label = f"{name}, residual {residual}"
            assert bool(np.all(np.asarray(info.degenerate))), label
            for leaf in (info.estimate, info.ess, *jax.tree.leaves(state)):
                if jnp.issubdtype(jnp.asarray(leaf).dtype, jnp.floating):
                    assert not np.any(np.isnan(np.asarray(leaf))), label
            assert np.all(np.isfinite(np.asarray(info.estimate))), label


def test_prepare_test_refuses_a_frame_count_that_is_not_one_or_more():
    from jaxtrack.tracking import prepare_test

    from helpers import small_scene

    scene = small_scene()[2]
    for frames in (-3, 0, True):  # a float is refused by the type hint itself (beartype, in the tests)
        with pytest.raises(ValueError, match="frames must be a whole number of frames, 1 or more"):
            prepare_test(scene, "walk.npz", key=jax.random.key(0), frames=frames)


@pytest.mark.slow  # a GPDM fitted and GPAPF compiled twice: 20 s or more on 2 cores with an empty compilation cache
def test_a_latent_tracker_given_a_pose_off_its_manifold_starts_from_that_pose():
    """GPAPF carries no pose residual: it starts at the given pose's projection onto its manifold.
    Given a pose with the arms raised (which no training walk or jog does), the projection is
    centimetres away, so it is built with the fading start instead and starts at the pose itself;
    given the walk's own frame 0, nothing changes. Under a flat likelihood frame 0's estimate is
    the first step from where the dynamics start: at least twice as near the given pose."""
    from jaxtrack.body import forward_kinematics
    from jaxtrack.dynamics import PoseResidual
    from jaxtrack.likelihood import as_likelihood
    from jaxtrack.tracking import OFF_MANIFOLD_START_MM, build_for_start, fit_manifold, fit_tracker, motion_data, start_off_manifold_mm

    scene, train_poses, validation_poses = small_tracking_inputs(4)
    recipe = get_tracker("gpapf")
    model, _, starts = fit_manifold(train_poses, 3, 5, kind="gpdm")
    fitted = fit_tracker(recipe, jax.random.key(0), motion_data(train_poses, validation_poses, model, starts))
    flat = as_likelihood(lambda poses, observation: jnp.zeros(poses.shape[0], poses.dtype))
    skeleton = scene.body.skeleton
    layout = list(skeleton.pose_layout)
    raised = np.asarray(scene.initial_pose).copy()
    for name in ("lshoulder_flex", "rshoulder_flex"):
        raised[layout.index(name)] = 2.5
    said = []
    built = {}
    for label, start in (("walk", np.asarray(scene.initial_pose)), ("raised", raised)):
        built[label] = build_for_start(recipe, fitted, flat, Budget(40, 2), start_pose=start, skeleton=skeleton,
                                       key=jax.random.key(1), say=said.append, name=label, residual_from=validation_poses)
    (walk, walk_distance), (tracker, distance) = built["walk"], built["raised"]
    assert walk_distance < OFF_MANIFOLD_START_MM and not isinstance(walk.dynamics, PoseResidual)
    assert distance > 100.0 and isinstance(tracker.dynamics, PoseResidual)
    assert len(said) == 1 and said[0].startswith("raised: GPAPF would start") and "fading pose residual" in said[0]
    assert start_off_manifold_mm(tracker.dynamics, raised, skeleton, jax.random.key(1)) < 1.0
    raised_joints = forward_kinematics(skeleton, jnp.asarray(raised))

    def frame0_off(filter_):  # mm from the raised pose, after frame 0's step under the flat likelihood
        _, info = run_filter(filter_, jax.random.key(2), raised, scene.observations)
        first = forward_kinematics(skeleton, info.estimate[0])
        return 1000.0 * float(jnp.mean(jnp.linalg.norm(first - raised_joints.astype(first.dtype), axis=-1)))

    plain = build_tracker(recipe, fitted, flat, Budget(40, 2))
    assert frame0_off(tracker) < 0.5 * frame0_off(plain)
