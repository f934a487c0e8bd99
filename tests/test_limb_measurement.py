"""Limb lengths measured from every frame's 2-D keypoints with the noise's bias removed
(``tracking.measure_limb_lengths``), and the measurement folded into the body calibration's
prior (``likelihood.combine_length_prior``, ``calibrate_body(measured_lengths=...)``)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body import HUMANEVA_JOINTS, LIMB_SEGMENTS, humaneva_body
from jaxtrack.camera import default_rig
from jaxtrack.data import DetectorNoise, SubjectStyle, detect_keypoints, generate_motion
from jaxtrack.likelihood import calibrate_body, combine_length_prior, make_keypoint_likelihood
from jaxtrack.tracking import limb_lengths_of, measure_limb_lengths, triangulate

LIMB_FACTORS = (("spine", 1.12), ("neck", 0.9), ("shoulder", 1.1), ("upper_arm", 0.87), ("forearm", 1.13), ("hip", 0.88),
                ("thigh", 1.12), ("shin", 0.86))
LONG_LIMBS = ("spine", "upper_arm", "forearm", "thigh", "shin")


@pytest.fixture(scope="module")
def walk():
    """120 frames of a walk by a subject whose limbs are 10-14 % off the default, its true limb
    lengths, and 4 views of 160x120 (about 20 mm a pixel at the person)."""
    subject = SubjectStyle("X", limb_lengths=LIMB_FACTORS)
    motion = generate_motion("walk", subject, num_frames=120, fps=60.0, key=jax.random.key(3), dtype=jnp.float64)
    return np.asarray(motion.joints3d, np.float64), limb_lengths_of(motion.body), default_rig(160, 120, dtype=jnp.float64)


def _raw_lengths(rig, keypoints):
    """Each limb's mean triangulated length, no correction: what a per-frame fit tends to."""
    points, seen = triangulate(rig, keypoints[..., :2], (keypoints[..., 2] > 0).astype(float))
    index = {n: i for i, n in enumerate(HUMANEVA_JOINTS)}
    out = {}
    for limb, bones in LIMB_SEGMENTS.items():
        out[limb] = np.mean(np.concatenate([np.linalg.norm(points[seen[:, index[a]] & seen[:, index[b]], index[a]]
                                                           - points[seen[:, index[a]] & seen[:, index[b]], index[b]], axis=-1)
                                            for a, b in bones]))
    return out


def test_the_measured_limb_lengths_lose_the_noise_bias_and_find_the_noise(walk):
    """With 3-pixel detections (10 % dropped) the raw triangulated lengths are too long by several
    standard errors (31 mm on the long limbs); the corrected ones fall within three of the truth (8 mm), and the noise estimate
    within 10 % of the detector's."""
    joints, truth, rig = walk
    keypoints = detect_keypoints(jax.random.key(1), joints, rig, DetectorNoise(noise_px=3.0, dropped=0.1))
    measured = measure_limb_lengths(rig, keypoints)
    assert measured is not None and set(measured.lengths) == set(LIMB_SEGMENTS)
    assert abs(measured.pixel_noise - 3.0) < 0.3, measured.pixel_noise
    raw = _raw_lengths(rig, keypoints)
    for limb in LONG_LIMBS:
        error, se = measured.lengths[limb] - truth[limb], measured.standard_errors[limb]
        assert abs(error) < 3 * se + 0.003, (limb, error, se)
    raw_bias = np.mean([raw[k] - truth[k] for k in LONG_LIMBS])
    corrected = np.mean([abs(measured.lengths[k] - truth[k]) for k in LONG_LIMBS])
    assert raw_bias > 0.02 and corrected < 0.35 * raw_bias, (raw_bias, corrected)
    assert measured.as_observation()["thigh"] == (measured.lengths["thigh"], measured.standard_errors["thigh"])


def test_swapped_detections_are_left_out_and_one_view_measures_nothing(walk):
    joints, truth, rig = walk
    keypoints = detect_keypoints(jax.random.key(2), joints, rig, DetectorNoise(noise_px=1.0, swapped=0.1))
    measured = measure_limb_lengths(rig, keypoints)
    assert measured.points_left_out > 0
    assert abs(measured.pixel_noise - 1.0) < 0.3, measured.pixel_noise
    for limb in ("thigh", "shin", "upper_arm"):
        assert abs(measured.lengths[limb] - truth[limb]) < 0.015, limb
    assert measure_limb_lengths(rig.view(0), keypoints[:1]) is None
    with pytest.raises(ValueError, match="keypoints must be"):
        measure_limb_lengths(rig, keypoints[..., :2])


def test_a_measurement_folds_into_the_length_prior_as_a_gaussian_observation():
    """Exact measurement: the limb takes its value and every other limb moves by the common scale's
    share of it, ``s^2 / (s^2 + p^2)`` (the Gaussian regression of one limb on another); a vague
    measurement changes nothing."""
    names = tuple(LIMB_SEGMENTS)
    reference = np.linspace(0.1, 0.5, len(names))
    s, p = 0.1, 0.06
    sds = np.full(len(names), p)
    centre, scale_sd, proportion_sds = combine_length_prior(names, reference, s, sds, {"thigh": (1.1 * reference[6], 1e-7)})
    np.testing.assert_allclose(centre[6], 1.1 * reference[6], rtol=1e-6)
    shift = np.log(centre / reference)
    expected = s ** 2 / (s ** 2 + p ** 2) * np.log(1.1)
    np.testing.assert_allclose(np.delete(shift, 6), expected, rtol=1e-6)
    assert proportion_sds[6] < 1e-5 and np.all(np.delete(proportion_sds, 6) < np.hypot(s, p)) and scale_sd < 0.01
    vague, _, vague_sds = combine_length_prior(names, reference, s, sds, {"thigh": (2.0, 1e6)})
    np.testing.assert_allclose(vague, reference, rtol=1e-9)
    np.testing.assert_allclose(vague_sds, np.hypot(s, p), rtol=1e-6)
    with pytest.raises(ValueError, match="not limbs"):
        combine_length_prior(names, reference, s, sds, {"tail": (0.3, 0.01)})
    with pytest.raises(ValueError, match="must be positive"):
        combine_length_prior(names, reference, s, sds, {"thigh": (0.3, 0.0)})


def test_the_calibration_takes_a_precise_measurement(walk):
    """``calibrate_body`` on two frames' noisy keypoints ends near a precise measurement of the
    limbs, not where those two frames' noise puts them."""
    joints, truth, rig = walk
    body = humaneva_body(dtype=jnp.float64)
    keypoints = detect_keypoints(jax.random.key(3), joints[:2], rig, DetectorNoise(noise_px=3.0))
    likelihood = make_keypoint_likelihood(body, rig, sigma_px=3.0, dtype=jnp.float64)
    start = np.zeros((2, body.skeleton.num_dofs))
    start[:, :3] = joints[:2, 0]
    observations = jnp.asarray(np.moveaxis(keypoints, 0, 1))
    measured = {limb: (truth[limb], 0.002) for limb in truth}
    report = calibrate_body(likelihood, start, observations, steps=150, measured_lengths=measured)[2]
    fitted = dict(zip(report.limb_names, report.lengths_after))
    assert max(abs(fitted[k] - truth[k]) for k in truth) < 0.01, {k: fitted[k] - truth[k] for k in truth}
