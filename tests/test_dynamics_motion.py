"""The motion the dynamics are fitted on when no validation file is given: the model file's own
training motion, else (SIR, APF without a model) the embedded walk."""

import json

import jax
import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.data import generate_motion, motion_sequence
from jaxtrack.dynamics import fit_pose_random_walk
from jaxtrack.io import load_sequence, save_sequence
from jaxtrack.manifold import load_model, read_header, save_model
from jaxtrack.tracking import DEFAULT_MOTION, MOTION_KEY, dynamics_motion, motion_record

from helpers import small_scene


def _walk(frames=20, seed=3):
    return motion_sequence(generate_motion("walk", "S2", num_frames=frames, fps=30.0, key=jax.random.key(seed)))


def test_a_stored_training_motion_reads_back_to_the_same_poses_skeleton_and_noise_scales():
    takes = [_walk(20, 3), _walk(12, 4).replace(skeleton_offsets=None)]  # the second keeps its joints instead
    record = json.loads(json.dumps(motion_record(takes, ["a.npz", "b.npz"])))  # as a model header holds it
    back, source = dynamics_motion(None, {"extra": {MOTION_KEY: record}}, fps=30.0, key=jax.random.key(0))
    assert source == "the model's own training motion (2 takes, 32 frames)"
    for original, read in zip(takes, back):
        np.testing.assert_allclose(read.pose, original.pose, atol=5e-7)
        assert read.fps == original.fps and list(read.pose_layout) == list(original.pose_layout)
    np.testing.assert_array_equal(back[0].skeleton_offsets, takes[0].skeleton_offsets)
    assert back[1].skeleton_offsets is None
    np.testing.assert_allclose(back[1].joints3d, takes[1].joints3d, atol=5e-5)
    # The noise scales the trackers fit are those of the original motion.
    np.testing.assert_allclose(fit_pose_random_walk([s.pose for s in back]).scales,
                               fit_pose_random_walk([s.pose for s in takes]).scales, rtol=1e-4)


def test_the_dynamics_motion_in_order_of_preference():
    key = jax.random.key(0)
    given = _walk()
    assert dynamics_motion(given, {"extra": {}}, fps=30.0, key=key) == ([given], "the validation motion")
    with pytest.raises(ValueError, match=r"does not store its training motion.*--validation"):
        dynamics_motion(None, {"extra": {}}, fps=30.0, key=key, model_name="old.eqx")
    (walk,), source = dynamics_motion(None, None, fps=50.0, key=key)
    gait, _, frames = DEFAULT_MOTION
    assert walk.fps == 50.0 and walk.num_frames == frames and f"embedded {gait}" in source
    (again,), _ = dynamics_motion(None, None, fps=50.0, key=key)
    np.testing.assert_array_equal(again.pose, walk.pose)  # the same key, the same motion
    with pytest.raises(ValueError, match="empty list"):
        dynamics_motion([], None, fps=30.0, key=key)


@pytest.mark.slow  # two fits and three short tracks: about 30 s on 2 cores
def test_track_without_validation_or_model(tmp_path, capsys):
    """``track`` with no ``--validation`` fits the dynamics on the model's own training motion;
    SIR and APF with no ``--model`` on the embedded walk, starting automatically; a manifold
    tracker with no model, and an old model file with no validation, are refused before any
    video or sequence is tracked."""
    test = tmp_path / "walk.npz"
    save_sequence(test, small_scene(num_frames=4)[2])
    model = tmp_path / "m.eqx"
    assert main(["fit", str(test), "--out", str(model), "--steps", "1"]) == 0
    assert MOTION_KEY in read_header(model)["extra"]
    capsys.readouterr()
    assert main(["track", str(test), "--model", str(model), "--method", "sir", "--budget", "16", "--out", str(tmp_path / "a")]) == 0
    assert "dynamics fitted on the model's own training motion (1 take, 4 frames)" in capsys.readouterr().out
    assert main(["track", str(test), "--method", "apf", "--budget", "20", "--start", "auto", "--out", str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out
    assert "dynamics fitted on the embedded walk" in out and "automatic start" in out
    estimate = load_sequence(tmp_path / "b.npz")
    assert estimate.pose.shape == (4, 32) and np.all(np.isfinite(estimate.joints3d))
    assert main(["track", str(test), "--method", "mrpf", "--out", str(tmp_path / "c")]) == 2
    assert "--method mrpf tracks on a manifold: give --model" in capsys.readouterr().err
    fitted, header = load_model(model)  # the same model, written as jaxtrack wrote it before it stored the motion
    old = tmp_path / "old.eqx"
    save_model(old, fitted, extra={k: v for k, v in header["extra"].items() if k != MOTION_KEY})
    assert main(["track", str(test), "--model", str(old), "--method", "sir", "--out", str(tmp_path / "d")]) == 2
    assert "old.eqx does not store its training motion" in capsys.readouterr().err
    assert not (tmp_path / "d.npz").exists()
