"""2-D keypoints: the detector layouts' joint correspondence, the OpenPose and COCO readers (one
person followed among several), the keypoint file, and the reprojection likelihood against a
NumPy reference, at its maximum at the true pose, and its gradient against finite differences."""

import json

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body import HUMANEVA_JOINTS, forward_kinematics, humaneva_body
from jaxtrack.camera import default_rig, project_points
from jaxtrack.errors import ConfigurationError, MotionFileError, TrackingError
from jaxtrack.io import (
    HEAD_SPREAD_LIMIT,
    KEYPOINT_LAYOUTS,
    MIN_LAYOUT_FRAMES,
    detect_layout,
    follow_person,
    get_keypoint_layout,
    head_spread,
    keypoint_format_of,
    load_keypoints,
    read_coco_keypoints,
    read_keypoint_sources,
    read_openpose_folder,
    save_keypoints,
)
from jaxtrack.likelihood import ObservationPart, make_keypoint_likelihood

J = {name: i for i, name in enumerate(HUMANEVA_JOINTS)}


def test_each_layout_maps_its_points_onto_the_humaneva_joints():
    for name, layout in KEYPOINT_LAYOUTS.items():
        points = np.zeros((layout.num_points, 3))
        points[:, 0] = np.arange(layout.num_points)  # u = the point's index
        points[:, 2] = 1.0
        joints = layout.to_humaneva(points)
        index = {n: i for i, n in enumerate(layout.names)}
        for joint in ("lshoulder", "relbow", "lwrist", "rhip", "lknee", "rankle"):
            assert joints[J[joint], 0] == index[joint], (name, joint)
        assert joints[J["head"], 0] == (index["lear"] + index["rear"]) / 2
        pelvis = index["midhip"] if "midhip" in index else (index["lhip"] + index["rhip"]) / 2
        assert joints[J["pelvis"], 0] == pelvis
        thorax = index["neck"] if ("neck" in index and name != "body25b") else (index["lshoulder"] + index["rshoulder"]) / 2
        assert joints[J["thorax"], 0] == thorax
        assert layout.approximate[J["head"]] and not layout.approximate[J["lknee"]]
    # the layouts as their tools number them
    assert KEYPOINT_LAYOUTS["body25"].names[8] == "midhip" and KEYPOINT_LAYOUTS["body25"].names[24] == "rheel"
    assert KEYPOINT_LAYOUTS["coco18"].names[1] == "neck" and KEYPOINT_LAYOUTS["coco18"].names[2] == "rshoulder"
    assert KEYPOINT_LAYOUTS["halpe26"].names[17:20] == ("headtop", "neck", "midhip")
    assert KEYPOINT_LAYOUTS["body25b"].names[17:19] == ("upperneck", "headtop")
    # a joint made of a missing point is missing, position zero
    points = np.ones((17, 3))
    points[3, 2] = 0.0  # left ear
    joints = get_keypoint_layout("coco17").to_humaneva(points)
    assert joints[J["head"], 2] == 0 and np.all(joints[J["head"], :2] == 0) and joints[J["pelvis"], 2] == 1
    with pytest.raises(ValueError, match="unknown keypoint layout"):
        get_keypoint_layout("body135")


def test_the_person_followed_is_the_one_nearest_the_last():
    a = np.concatenate([np.full((3, 2), 10.0), np.ones((3, 1))], axis=1)
    b = np.concatenate([np.full((3, 2), 50.0), np.full((3, 1), 0.9)], axis=1)
    frames = [np.stack([b, a]), np.stack([a + 1, b + 1]), np.zeros((0, 3, 3)), np.stack([b - 1, a + 2])]
    chosen = follow_person(frames)  # a is the most confident at the start, then followed
    np.testing.assert_allclose(chosen[:, 0, 0], [10, 11, 0, 12])
    assert chosen[2, 0, 2] == 0


def test_openpose_and_coco_files_read_back(tmp_path):
    layout = get_keypoint_layout("body25")
    rng = np.random.default_rng(0)
    truth = np.concatenate([rng.uniform(0, 80, (3, 25, 2)), np.ones((3, 25, 1))], axis=2)
    folder = tmp_path / "cam1"
    folder.mkdir()
    for t in range(3):
        stranger = truth[t].copy()
        stranger[:, :2] += 200.0
        stranger[:, 2] = 0.5
        people = [{"pose_keypoints_2d": stranger.ravel().tolist()}, {"pose_keypoints_2d": truth[t].ravel().tolist()}]
        (folder / f"video_{t:012d}_keypoints.json").write_text(json.dumps({"version": 1.3, "people": people}))
    read = read_openpose_folder(folder, "body25")
    np.testing.assert_allclose(read, layout.to_humaneva(truth))
    (folder / "video_000000000003_keypoints.json").write_text('{"people": [{"pose_keypoints_2d": [1, 2]}]}')
    with pytest.raises(MotionFileError, match="expected 75 numbers"):
        read_openpose_folder(folder, "body25")
    (folder / "video_000000000003_keypoints.json").write_text('{"people":\n [1, 2,,]}')
    with pytest.raises(MotionFileError, match=r"_keypoints.json:2: not JSON"):
        read_openpose_folder(folder, "body25")

    coco = get_keypoint_layout("coco17")
    points = np.concatenate([rng.uniform(0, 80, (2, 17, 2)), np.full((2, 17, 1), 2.0)], axis=2)
    annotations = [{"image_id": 7 + t, "keypoints": points[t].ravel().tolist()} for t in range(2)]
    path = tmp_path / "coco.json"
    path.write_text(json.dumps({"annotations": annotations, "images": [{"id": 7}, {"id": 8}]}))
    expected = points.copy()
    expected[..., 2] = 1.0  # visibility 2 -> confidence 1
    np.testing.assert_allclose(read_coco_keypoints(path), coco.to_humaneva(expected))

    keypoints = np.stack([read, read])
    save_keypoints(tmp_path / "k.npz", keypoints, ["C1", "C2"])
    loaded, names = load_keypoints(tmp_path / "k.npz")
    np.testing.assert_array_equal(loaded, keypoints)
    assert names == ("C1", "C2")
    with pytest.raises(MotionFileError, match="confidences must lie in"):
        save_keypoints(tmp_path / "bad.npz", keypoints * 2, ["C1", "C2"])


@pytest.fixture(scope="module")
def scene():
    body = humaneva_body(dtype=jnp.float64)
    rig = default_rig(160, 120, dtype=jnp.float64)
    pose = jnp.asarray(body.skeleton.zero_pose()).at[2].set(0.95).at[8].set(0.3).at[21].set(0.4)
    uv, _, _ = project_points(rig, forward_kinematics(body.skeleton, pose))  # (15, C, 2)
    keypoints = jnp.concatenate([jnp.swapaxes(uv, 0, 1), jnp.ones((4, 15, 1))], axis=-1)  # (C, 15, 3)
    return body, rig, pose, keypoints


def _numpy_reference(body, rig, poses, keypoints, sigmas, robust):
    out = []
    for pose in np.asarray(poses):
        uv, _, _ = project_points(rig, forward_kinematics(body.skeleton, jnp.asarray(pose)))
        uv = np.swapaxes(np.asarray(uv), 0, 1)
        total = 0.0
        for c in range(uv.shape[0]):
            for j in range(15):
                s = np.sum((uv[c, j] - keypoints[c, j, :2]) ** 2) / sigmas[j] ** 2
                total -= keypoints[c, j, 2] * (np.log1p(s / 2) if robust == "cauchy" else s / 2)
        out.append(total)
    return np.asarray(out)


def test_the_keypoint_likelihood_matches_numpy_on_two_poses(scene):
    with jax.enable_x64(True):
        body, rig, pose, keypoints = scene
        noisy = np.asarray(keypoints).copy()
        noisy[..., :2] += np.random.default_rng(2).normal(0, 3, noisy[..., :2].shape)
        noisy[0, 3, 2] = 0.0
        poses = jnp.stack([pose, pose.at[10].add(0.2)])
        likelihood = make_keypoint_likelihood(body, rig, sigma_px=4.0, dtype=jnp.float64)
        np.testing.assert_allclose(likelihood(poses, jnp.asarray(noisy)),
                                   _numpy_reference(body, rig, poses, noisy, np.asarray(likelihood.sigmas), "cauchy"), rtol=1e-9)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_the_keypoint_likelihood_matches_numpy_peaks_at_the_truth_and_has_the_right_gradient(scene):
    with jax.enable_x64(True):
        body, rig, pose, keypoints = scene
        rng = np.random.default_rng(1)
        noisy = np.asarray(keypoints).copy()
        noisy[..., :2] += rng.normal(0, 3, noisy[..., :2].shape)
        noisy[..., 2] = rng.uniform(0, 1, noisy[..., 2].shape)
        noisy[1, 4, 2] = 0.0  # a missing joint
        poses = pose + 0.05 * jnp.asarray(rng.normal(size=(5, pose.shape[0])))
        for robust in ("cauchy", "gaussian"):
            likelihood = make_keypoint_likelihood(body, rig, sigma_px=4.0, robust=robust, dtype=jnp.float64)
            np.testing.assert_allclose(likelihood(poses, jnp.asarray(noisy)),
                                       _numpy_reference(body, rig, poses, noisy, np.asarray(likelihood.sigmas), robust), rtol=1e-9)
        likelihood = make_keypoint_likelihood(body, rig, dtype=jnp.float64)
        values = likelihood(jnp.concatenate([pose[None], poses]), keypoints)
        assert values[0] == 0.0 and np.all(values[1:] < 0)
        # a missing joint does not count: moving only the left wrist's detection changes nothing
        moved = keypoints.at[:, J["lwrist"], :2].add(30.0).at[:, J["lwrist"], 2].set(0.0)
        np.testing.assert_allclose(likelihood(poses, moved), likelihood(poses, keypoints.at[:, J["lwrist"], 2].set(0.0)))
        # read from a dict, to be summed with another cue
        keyed = ObservationPart(likelihood, "keypoints")
        assert keyed.reads_observation
        np.testing.assert_allclose(keyed(poses, {"keypoints": keypoints, "silhouettes": jnp.zeros(3)}), likelihood(poses, keypoints))
        with pytest.raises(TrackingError, match="needs a dict observation"):
            keyed(poses, keypoints)
        # gradient against central finite differences
        f = jax.jit(lambda p: likelihood(p, jnp.asarray(noisy)))  # (n, D) -> (n,)
        x = poses[0]
        grad = jax.grad(lambda p: f(p[None])[0])(x)
        eps = 1e-6
        steps = eps * jnp.eye(x.shape[0])
        numeric = np.asarray((f(x + steps) - f(x - steps)) / (2 * eps))
        np.testing.assert_allclose(grad, numeric, rtol=1e-5, atol=1e-6)
        # jit against no jit
        jitted = eqx.filter_jit(lambda lik, p, k: lik(p, k))
        np.testing.assert_allclose(jitted(likelihood, poses, keypoints), likelihood(poses, keypoints), rtol=1e-12)


def test_bad_keypoint_likelihood_settings_are_refused(scene):
    body, rig, _, _ = scene
    with pytest.raises(ConfigurationError, match="sigma_px"):
        make_keypoint_likelihood(body, rig, sigma_px=0.0)
    with pytest.raises(ConfigurationError, match="robust"):
        make_keypoint_likelihood(body, rig, robust="huber")


# A standing person's detector points in pixels (v down, about 175 px tall), by point name.
_FIGURE = {
    "headtop": (0, 0), "nose": (3, 15), "leye": (4, 10), "reye": (-4, 10), "lear": (8, 12), "rear": (-8, 12),
    "upperneck": (0, 24), "neck": (0, 30), "lshoulder": (20, 35), "rshoulder": (-20, 35), "lelbow": (25, 65),
    "relbow": (-25, 65), "lwrist": (27, 95), "rwrist": (-27, 95), "midhip": (0, 95), "lhip": (10, 95), "rhip": (-10, 95),
    "lknee": (11, 135), "rknee": (-11, 135), "lankle": (12, 170), "rankle": (-12, 170), "lheel": (11, 173),
    "rheel": (-11, 173), "lbigtoe": (18, 176), "rbigtoe": (-18, 176), "lsmalltoe": (21, 175), "rsmalltoe": (-21, 175),
}


def _detections(layout: str, frames: int, seed: int = 0) -> np.ndarray:
    """(frames, K, 3) one person's points in ``layout``'s order, moved and jittered per frame."""
    rng = np.random.default_rng(seed)
    names = get_keypoint_layout(layout).names
    base = np.asarray([_FIGURE[n] for n in names], np.float64)
    out = np.empty((frames, len(names), 3))
    for t in range(frames):
        out[t, :, :2] = base + [300 + 5 * t, 200] + rng.normal(0, 1.5, base.shape)
        out[t, :, 2] = rng.uniform(0.5, 1.0, len(names))
    return out


def _write_openpose(folder, detections, extra_empty: bool = False):
    folder.mkdir()
    for t, person in enumerate(detections):
        people = [{"pose_keypoints_2d": person.ravel().tolist()}]
        if extra_empty:
            people.insert(0, {"pose_keypoints_2d": []})  # OpenPose writes entries like this
        (folder / f"c_{t:012d}_keypoints.json").write_text(json.dumps({"version": 1.3, "people": people}))


@pytest.mark.parametrize("layout", sorted(KEYPOINT_LAYOUTS))
def test_the_layout_is_told_from_the_points_and_body25_from_body25b_by_the_data(tmp_path, layout):
    detections = _detections(layout, 8)
    _write_openpose(tmp_path / "cam", detections)
    said = []
    read = read_openpose_folder(tmp_path / "cam", say=said.append)
    np.testing.assert_allclose(read, get_keypoint_layout(layout).to_humaneva(detections))
    assert f"keypoint layout {layout}" in said[0]
    frames = list(detections[:, None])
    assert detect_layout(frames, "x")[0] == layout
    coco = [{"image_id": t, "keypoints": p.ravel().tolist(), "score": 1.0} for t, p in enumerate(detections)]
    (tmp_path / "coco.json").write_text(json.dumps(coco))
    np.testing.assert_allclose(read_coco_keypoints(tmp_path / "coco.json"), read)


def test_the_head_spread_separates_body25_from_body25b():
    body25 = head_spread(_detections("body25", 20))
    body25b = head_spread(_detections("body25b", 20))
    # an arm's span against a head's, over the height
    assert np.median(body25) > 0.45 and np.median(body25b) < 0.12
    assert HEAD_SPREAD_LIMIT > body25b.max() and HEAD_SPREAD_LIMIT < body25.min()
    unsure = _detections("body25b", 3)
    unsure[:, 1, 2] = 0.1  # an eye not confident: the detection does not count
    assert np.all(np.isnan(head_spread(unsure)))


def test_twenty_five_points_too_few_to_tell_apart_ask_for_the_layout(tmp_path):
    detections = _detections("body25b", MIN_LAYOUT_FRAMES - 1)
    _write_openpose(tmp_path / "cam", detections)
    with pytest.raises(MotionFileError, match=r"body25 or body25b.*--keypoint-layout body25 or body25b"):
        read_openpose_folder(tmp_path / "cam")
    np.testing.assert_allclose(read_openpose_folder(tmp_path / "cam", "body25b"),
                               get_keypoint_layout("body25b").to_humaneva(detections))
    with pytest.raises(MotionFileError, match="13 points per person is no known layout"):
        detect_layout([np.ones((1, 13, 3))], "x")


def test_an_empty_openpose_person_entry_is_nobody_detected(tmp_path):
    detections = _detections("coco18", 4)
    _write_openpose(tmp_path / "cam", detections, extra_empty=True)
    (tmp_path / "cam" / "c_000000000004_keypoints.json").write_text(json.dumps({"people": [{"pose_keypoints_2d": []}]}))
    read = read_openpose_folder(tmp_path / "cam")
    np.testing.assert_allclose(read[:4], get_keypoint_layout("coco18").to_humaneva(detections))
    assert read.shape == (5, 15, 3) and np.all(read[4] == 0)  # the last frame: every joint missing


def test_the_keypoint_format_is_told_from_what_is_given(tmp_path):
    (tmp_path / "cam1").mkdir()
    (tmp_path / "c.json").write_text("[]")
    save_keypoints(tmp_path / "k.npz", np.zeros((1, 2, 15, 3)), ["C1"])
    assert keypoint_format_of([tmp_path / "cam1"]) == "openpose"
    assert keypoint_format_of([tmp_path / "c.json"]) == "coco"
    assert keypoint_format_of([tmp_path / "k.npz"]) == "npz"
    with pytest.raises(ValueError, match="different formats"):
        keypoint_format_of([tmp_path / "cam1", tmp_path / "c.json"])
    with pytest.raises(ValueError, match="no such keypoint file or folder"):
        keypoint_format_of([tmp_path / "missing"])
    (tmp_path / "notes.txt").write_text("")
    with pytest.raises(ValueError, match="not a keypoint source"):
        keypoint_format_of([tmp_path / "notes.txt"])
    folders = []
    for c in range(2):
        _write_openpose(tmp_path / f"view{c}", _detections("body25", 6, seed=c))
        folders.append(tmp_path / f"view{c}")
    said = []
    keypoints = read_keypoint_sources(folders, camera_names=["a", "b"], say=said.append)
    assert keypoints.shape == (2, 6, 15, 3) and said[0].startswith("keypoints: folders of per-frame JSON: OpenPose")
    assert sum("keypoint layout body25 (" in s for s in said) == 2
