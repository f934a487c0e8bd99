"""The floor under a recorded motion (``io.fit_floor``, ``io.level_joints``) and the conversion
that levels it (``convert_motion(level_floor=True)``, ``jaxtrack convert --level-floor``)."""

import jax
import numpy as np
import pytest

from jaxtrack.body import HUMANEVA_JOINTS
from jaxtrack.data import generate_motion
from jaxtrack.io import fit_floor, level_joints, levelling_rotation

GRADIENT = np.array([0.012, -0.015])  # dz/dx, dz/dy: 19.2 mm a metre, 1.1 degrees (CMU 07's walks)
ANKLES = [HUMANEVA_JOINTS.index("lankle"), HUMANEVA_JOINTS.index("rankle")]


def _walk(num_frames=180, radius=1.5):
    """A synthetic walk on a level floor: an arc of a circle, so the path spans both directions."""
    motion = generate_motion("walk", "S1", num_frames=num_frames, path_radius=radius, key=jax.random.key(0), dtype=np.float64)
    return np.asarray(motion.joints3d, np.float64)


def _tilt(joints, gradient, pivot):
    """The joints on a floor of ``gradient`` through ``pivot``: ``level_joints``'s inverse."""
    return (joints - pivot) @ levelling_rotation(gradient) + pivot


def _bones(joints):
    parents = [-1, 0, 1, 2, 3, 1, 5, 6, 0, 8, 9, 0, 11, 12, 1]
    return np.stack([np.linalg.norm(joints[:, j] - joints[:, p], axis=-1) for j, p in enumerate(parents) if p >= 0], axis=-1)


def test_a_level_walk_has_a_level_floor_and_levelling_leaves_it_alone():
    joints = _walk()
    floor = fit_floor(joints)
    assert floor.seen and np.all(floor.spans >= 0.3)
    assert floor.slope < 1e-4 and floor.rise_m < 1e-3
    # the pivot is the stance ankles' floor point: the synthetic ankle's clearance, 8 cm
    np.testing.assert_allclose(floor.pivot[2], np.min(joints[:, ANKLES, 2]), atol=2e-3)
    np.testing.assert_allclose(level_joints(joints, floor), joints, atol=1e-4)


def test_the_floor_s_tilt_is_found_under_a_walk_that_climbs_it_and_levelled_away():
    joints = _walk()
    pivot = fit_floor(joints).pivot
    tilted = _tilt(joints, GRADIENT, pivot)
    floor = fit_floor(tilted)
    np.testing.assert_allclose(floor.gradient, GRADIENT, atol=5e-4)
    assert abs(floor.tilt_degrees - np.degrees(np.arctan(np.hypot(*GRADIENT)))) < 0.03
    assert 0.04 < floor.rise_m < 0.07 and "1.10 degrees" in floor.describe()
    levelled = level_joints(tilted, floor)
    assert fit_floor(levelled).slope < 2e-4
    np.testing.assert_allclose(levelled, joints, atol=1e-3)  # back where the level walk was
    np.testing.assert_allclose(_bones(levelled), _bones(tilted), rtol=1e-12)  # a rotation: every bone kept
    assert abs(fit_floor(levelled).pivot[2] - floor.pivot[2]) < 1e-3  # the floor's height at the path's centre kept


def test_feet_in_the_air_do_not_lift_the_floor():
    """A jog's flight phases and a heel rising put the lower ankle above the floor: the fit
    down-weights them instead of tilting the plane towards them."""
    joints = _tilt(_walk(), GRADIENT, np.array([0.0, 0.0, 0.08]))
    rng = np.random.default_rng(0)
    flying = rng.random(len(joints)) < 0.3
    lifted = joints.copy()
    lifted[flying, :, 2] += rng.uniform(0.05, 0.12, flying.sum())[:, None]  # the whole body in the air
    floor = fit_floor(lifted)
    np.testing.assert_allclose(floor.gradient, GRADIENT, atol=1e-3)
    # An unweighted plane through the same points would be pulled by 30 % of frames up to 12 cm high.
    assert fit_floor(lifted, lift=np.inf).slope != pytest.approx(floor.slope, abs=1e-4)


def test_a_straight_walk_sees_the_slope_along_it_only_and_a_still_person_none():
    walk = _walk(num_frames=90, radius=40.0)  # nearly straight: about 1.8 m along, centimetres across
    floor = fit_floor(_tilt(walk, GRADIENT, fit_floor(walk).pivot))
    along = fit_floor(walk).spans, floor.spans
    assert along[0][0] > 0.3 > along[0][1]
    assert floor.seen and floor.slope < np.hypot(*GRADIENT)  # the slope across the path is not seen
    still = np.repeat(walk[:1], 40, axis=0)
    resting = fit_floor(still)
    assert not resting.seen and resting.slope == 0.0 and "not seen" in resting.describe()
    np.testing.assert_allclose(level_joints(still, resting), still, atol=1e-12)


def test_the_floor_fit_refuses_joints_it_cannot_read_and_skips_missing_frames():
    joints = _tilt(_walk(), GRADIENT, np.array([0.0, 0.0, 0.08]))
    with pytest.raises(ValueError, match=r"joints must be \(T, 15, 3\)"):
        fit_floor(joints[:, :, :2])
    with pytest.raises(ValueError, match="no lankle, rankle"):
        fit_floor(joints[:, :13], HUMANEVA_JOINTS[:10] + ("a", "b", "c"))
    holes = joints.copy()
    holes[::4, ANKLES] = np.nan  # occluded markers: those frames say nothing
    np.testing.assert_allclose(fit_floor(holes).gradient, fit_floor(joints[np.arange(len(joints)) % 4 != 0]).gradient, atol=1e-12)
    assert np.isnan(fit_floor(holes).heights[::4]).all()
    empty = fit_floor(np.full((5, 15, 3), np.nan))
    assert not empty.seen and empty.rise_m == 0.0


def test_convert_levels_a_tilted_capture_on_request(tmp_path, capsys):
    """``convert_motion`` reports the floor it found; ``level_floor=True`` (``--level-floor``)
    rotates the joints before the inverse kinematics, and the CLI says when a floor is tilted."""
    from jaxtrack.cli import main
    from jaxtrack.io import convert_motion, load_sequence

    joints = _tilt(_walk(num_frames=120, radius=1.5)[::2], GRADIENT, np.array([0.0, 0.0, 0.08]))  # 60 frames at 30 Hz
    source = tmp_path / "climb.npz"
    np.savez(source, fps=30.0, joints3d=joints, joint_names=np.array(HUMANEVA_JOINTS))
    kept = convert_motion(str(source), None)
    assert not kept.levelled and kept.floor.tilt_degrees == pytest.approx(1.10, abs=0.05)
    np.testing.assert_allclose(kept.sequence.joints3d, joints, atol=1e-9)
    levelled = convert_motion(str(source), None, level_floor=True)
    assert levelled.levelled and levelled.floor.tilt_degrees == pytest.approx(1.10, abs=0.05)  # the source's floor
    assert fit_floor(levelled.sequence.joints3d).slope < 5e-4 and levelled.mean_residual_mm < 5.0
    assert main(["convert", str(source), str(tmp_path / "kept.npz")]) == 0
    said = capsys.readouterr().out
    assert "the floor tilts 1.1" in said and "pass --level-floor" in said
    assert main(["convert", str(source), str(tmp_path / "level.npz"), "--level-floor"]) == 0
    said = capsys.readouterr().out
    assert "levelled" in said and "pass --level-floor" not in said
    assert fit_floor(load_sequence(str(tmp_path / "level.npz")).joints3d).slope < 5e-4


@pytest.mark.shared_data
def test_cmu_07_s_walks_climb_its_capture_s_floor_and_cmu_35_s_do_not(shared_data, tmp_path):
    """The measurement behind the protocols' levelled takes (docs/floor.md, "A tilted capture")."""
    from jaxtrack.experiment import convert_takes, get_protocol

    walk = get_protocol("walk-loso")
    takes = [walk.subject("cmu07").test, walk.subject("cmu35").validation]
    raw = convert_takes(takes, shared_data, str(tmp_path / "raw"), say=lambda *a: None)
    level = convert_takes(takes, shared_data, str(tmp_path / "level"), level_floor=True, say=lambda *a: None)
    cmu07, cmu35 = (fit_floor(raw[t.name].joints3d) for t in takes)
    assert 1.0 < cmu07.tilt_degrees < 1.25 and cmu07.rise_m > 0.06
    assert cmu35.tilt_degrees < 0.25
    for take in takes:
        assert fit_floor(level[take.name].joints3d).tilt_degrees < 0.05
