"""2-D keypoints as a test scene's observation: the sequence file's ``keypoints2d`` (validated,
cropped, resized with the cameras), synthetic detections, the registered ``keypoints`` and
``silhouette+keypoints`` likelihoods built by ``prepare_test``, and the command line's
``scene --keypoints`` and ``keypoints`` verbs."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body import HUMANEVA_JOINTS
from jaxtrack.camera import project_points
from jaxtrack.cli import main
from jaxtrack.data import DetectorNoise, detect_keypoints
from jaxtrack.errors import SequenceFileError
from jaxtrack.io import get_keypoint_layout, load_sequence, save_sequence
from jaxtrack.likelihood import (
    LikelihoodRecipe,
    ObservationPart,
    SampledSilhouetteLikelihood,
    SumLikelihood,
    get_likelihood,
    make_keypoint_likelihood,
    make_silhouette_likelihood,
)
from jaxtrack.tracking import prepare_test

from helpers import small_scene

J = {name: i for i, name in enumerate(HUMANEVA_JOINTS)}
EXACT = DetectorNoise(noise_px=0.0, dropped=0.0, swapped=0.0, confidence=1.0)


@pytest.fixture(scope="module")
def scene():
    """The small noisy walk (4 views, 40x30) with exact detections of its true joints."""
    _, rig, seq = small_scene()
    return rig, seq.replace(keypoints2d=detect_keypoints(jax.random.key(5), seq.joints3d, rig, EXACT))


def test_exact_detections_are_the_projected_joints(scene):
    rig, seq = scene
    uv, _, _ = project_points(rig, jnp.asarray(seq.joints3d))  # (T, 15, C, 2)
    expected = np.moveaxis(np.asarray(uv), 2, 0)
    inside = seq.keypoints2d[..., 2] > 0
    np.testing.assert_allclose(seq.keypoints2d[..., :2][inside], expected[inside], atol=1e-3)
    size = np.asarray(rig.image_size, float)[:, None, None, :]
    outside = np.any((expected < -0.5) | (expected > size - 0.5), axis=-1)
    np.testing.assert_array_equal(~inside, outside)  # only what leaves the image is missing


def test_detector_noise_drops_swaps_and_repeats_with_its_key(scene):
    rig, seq = scene
    noisy = DetectorNoise(noise_px=3.0, dropped=0.3, swapped=0.0)
    a = detect_keypoints(jax.random.key(1), seq.joints3d, rig, noisy)
    np.testing.assert_array_equal(a, detect_keypoints(jax.random.key(1), seq.joints3d, rig, noisy))
    assert not np.array_equal(a, detect_keypoints(jax.random.key(2), seq.joints3d, rig, noisy))
    seen = a[..., 2] > 0
    assert 0.6 < seen.mean() < 0.8 and set(np.unique(a[..., 2])) == {0.0, 0.9}
    error = np.linalg.norm(a[..., :2] - seq.keypoints2d[..., :2], axis=-1)[seen & (seq.keypoints2d[..., 2] > 0)]
    assert 2.6 < np.sqrt(np.mean(error**2) / 2) < 3.4  # per-axis RMS 3 px, to sampling error
    swapped = detect_keypoints(jax.random.key(1), seq.joints3d, rig, DetectorNoise(0.0, 0.0, 1.0, 1.0))
    for left, right in (("lwrist", "rwrist"), ("lknee", "rknee")):
        both = (swapped[:, :, J[left], 2] > 0) & (seq.keypoints2d[:, :, J[right], 2] > 0)
        np.testing.assert_allclose(swapped[:, :, J[left], :2][both], seq.keypoints2d[:, :, J[right], :2][both], atol=1e-3)
    np.testing.assert_allclose(swapped[:, :, J["head"]], seq.keypoints2d[:, :, J["head"]], atol=1e-4)  # float32 storage
    with pytest.raises(ValueError, match="dropped is a probability"):
        DetectorNoise(dropped=1.5)
    with pytest.raises(ValueError, match="joints3d must be"):
        detect_keypoints(jax.random.key(0), seq.joints3d[:, :14], rig)


def test_keypoints_in_a_sequence_file_round_trip_crop_and_resize(scene, tmp_path):
    _rig, seq = scene
    back = load_sequence(save_sequence(tmp_path / "kp", seq))
    np.testing.assert_allclose(back.keypoints2d, seq.keypoints2d, atol=1e-4)
    assert back.cropped(3).keypoints2d.shape == (4, 3, 15, 3)
    small = back.resized(20, 15)  # the keypoints move with the pixels, as the intrinsics do
    uv, _, _ = project_points(small.rig(), jnp.asarray(seq.joints3d))
    seen = small.keypoints2d[..., 2] > 0
    np.testing.assert_allclose(small.keypoints2d[..., :2][seen], np.moveaxis(np.asarray(uv), 2, 0)[seen], atol=1e-3)
    assert np.all(small.keypoints2d[..., :2][~seen] == 0)
    bad = seq.keypoints2d.copy()
    bad[1, 2, 3, 2] = 1.5
    with pytest.raises(SequenceFileError, match=r"keypoints2d.*confidence 1.5 at \(camera, frame, joint\) \(1, 2, 3\)"):
        seq.replace(keypoints2d=bad)
    with pytest.raises(SequenceFileError, match=r"keypoints2d.*has 7 frames"):
        seq.replace(keypoints2d=seq.keypoints2d[:, :7])
    with pytest.raises(SequenceFileError, match=r"keypoints2d.*must have shape \(\*, \*, 15, 3\)"):
        seq.replace(keypoints2d=seq.keypoints2d[:, :, :14])
    nan = seq.keypoints2d.copy()
    nan[0, 0, 0, 0] = np.nan
    with pytest.raises(SequenceFileError, match=r"keypoints2d.*non-finite"):
        seq.replace(keypoints2d=nan)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_prepare_test_builds_the_registered_keypoint_likelihoods(scene):
    rig, seq = scene
    key = jax.random.key(0)
    alone = prepare_test(seq.replace(silhouettes=None), "kp", key=key, likelihood="keypoints",
                         likelihood_options={"sigma_px": 2.0})
    assert alone.observations.shape == (8, 4, 15, 3)
    reference = make_keypoint_likelihood(alone.body, rig, sigma_px=2.0, dtype=alone.body.radii.dtype)
    poses = alone.initial_pose[None] + np.zeros((2, 1), np.float32)
    poses = poses.at[1, 10].add(0.3)
    np.testing.assert_allclose(alone.likelihood.log_likelihood(poses, alone.observations[0]),
                               reference.log_likelihood(poses, np.asarray(seq.keypoints2d[:, 0])), rtol=1e-5, atol=1e-6)
    both = prepare_test(seq, "both", key=key, likelihood="silhouette+keypoints")
    assert set(both.observations) == {"silhouettes", "keypoints"} and isinstance(both.likelihood, SumLikelihood)
    frame = jax.tree.map(lambda x: x[0], both.observations)
    silhouettes = make_silhouette_likelihood(both.body, both.likelihood.terms[0].term.rig, scale=100.0,
                                             window=both.likelihood.terms[0].term.window)
    keypoints = make_keypoint_likelihood(both.body, rig, dtype=both.body.radii.dtype)
    expected = (silhouettes.log_likelihood(poses, frame["silhouettes"]) + keypoints.log_likelihood(poses, frame["keypoints"]))
    np.testing.assert_allclose(both.likelihood.log_likelihood(poses, frame), expected, rtol=1e-5, atol=1e-5)
    assert float(alone.likelihood.log_likelihood(poses, alone.observations[0])[0]) > float(
        alone.likelihood.log_likelihood(poses, alone.observations[0])[1])  # the truth beats a bent knee
    assert isinstance(both.likelihood.terms[1], ObservationPart) and both.likelihood.terms[1].key == "keypoints"
    sampled = prepare_test(seq, "sampled", key=key, likelihood="silhouette+keypoints", pixel_samples=64)  # the silhouettes' term only
    assert isinstance(sampled.likelihood.terms[0].term, SampledSilhouetteLikelihood)
    assert sampled.observations["silhouettes"].u.shape == (8, 4, 64)
    np.testing.assert_array_equal(np.asarray(sampled.observations["keypoints"]), np.asarray(both.observations["keypoints"]))


def test_a_scene_without_what_the_likelihood_reads_is_refused(scene):
    _, seq = scene
    with pytest.raises(ValueError, match=r"needs keypoints, which the file lacks \(key keypoints2d\)"):
        prepare_test(seq.replace(keypoints2d=None), "x", key=jax.random.key(0), likelihood="keypoints")
    with pytest.raises(ValueError, match=r"needs silhouettes, which the file lacks"):
        prepare_test(seq.replace(silhouettes=None), "x", key=jax.random.key(0), likelihood="silhouette+keypoints")
    with pytest.raises(Exception, match="--calibrate fits the capsule radii to silhouettes"):
        prepare_test(seq, "x", key=jax.random.key(0), likelihood="keypoints", calibrate=True)
    assert get_likelihood("keypoints").observes == ("keypoints",)
    with pytest.raises(ValueError, match="observes must name one or more of"):
        LikelihoodRecipe("toy", "a toy", lambda inputs: None, observes=("depth",))


def test_the_command_line_adds_detector_files_and_synthetic_detections(scene, tmp_path, capsys):
    rig, seq = scene
    path = save_sequence(tmp_path / "walk", seq.replace(keypoints2d=None))
    layout = get_keypoint_layout("coco18")
    folders = []
    for c in range(4):  # each camera's OpenPose output, the truth written in COCO-18 order
        folder = tmp_path / f"cam{c}"
        folder.mkdir()
        for t in range(seq.num_frames):
            points = np.zeros((layout.num_points, 3))
            for i, name in enumerate(layout.names):
                if name in J:
                    points[i] = seq.keypoints2d[c, t, J[name]]
            (folder / f"f_{t:04d}_keypoints.json").write_text(json.dumps({"people": [{"pose_keypoints_2d": points.ravel().tolist()}]}))
        folders.append(str(folder))
    out = tmp_path / "with_keypoints.npz"
    assert main(["keypoints", path, str(out), *folders, "--layout", "coco18"]) == 0
    read = load_sequence(out).keypoints2d
    for joint in ("lwrist", "rknee", "lankle"):
        np.testing.assert_allclose(read[:, :, J[joint]], seq.keypoints2d[:, :, J[joint]], atol=1e-4)
    assert "wrote" in capsys.readouterr().out
    assert main(["keypoints", path, str(tmp_path / "x.npz"), *folders[:3], "--layout", "coco18"]) == 2
    assert "4 cameras: give one openpose keypoint source per camera" in capsys.readouterr().err
    # a joints-only file and the cameras from a calibration file
    from jaxtrack.io import CAMERA_KEYS, save_calibration

    bare = save_sequence(tmp_path / "bare", seq.replace(keypoints2d=None, silhouettes=None, **dict.fromkeys(CAMERA_KEYS)))
    assert main(["keypoints", bare, str(tmp_path / "no_cameras.npz"), *folders, "--layout", "coco18"]) == 2
    assert "has no cameras; give the calibration (--calibration)" in capsys.readouterr().err
    calibration = save_calibration(tmp_path / "rig.json", rig)
    assert main(["keypoints", bare, str(tmp_path / "calibrated.npz"), *folders, "--layout", "coco18", "--calibration", calibration]) == 0
    calibrated = load_sequence(tmp_path / "calibrated.npz")
    np.testing.assert_allclose(calibrated.camera_K, np.asarray(rig.K), atol=1e-9)
    np.testing.assert_allclose(calibrated.keypoints2d, read, atol=1e-6)
