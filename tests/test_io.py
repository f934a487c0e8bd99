import numpy as np
import pytest

from jaxtrack.io import Sequence, SequenceFileError, load_sequence, save_sequence

from helpers import small_scene


@pytest.fixture(scope="module")
def scene():
    return small_scene()[2]


def test_round_trip_keeps_every_key(scene, tmp_path):
    path = tmp_path / "walk.npz"
    save_sequence(path, scene)
    back = load_sequence(path)
    for key, value in scene.to_dict().items():
        np.testing.assert_array_equal(getattr(back, key) if key != "fps" else back.fps, value)
    assert back.num_frames == 8 and back.has_cameras
    rig = back.rig()
    assert rig.num_views == 4 and rig.image_size[0] == (40, 30)
    np.testing.assert_allclose(back.body().radii, scene.capsule_radii)


def test_file_written_with_numpy_alone_loads(tmp_path):
    path = tmp_path / "other_tool.npz"
    joints = np.random.default_rng(0).normal(size=(5, 15, 3))
    np.savez(path, fps=np.float64(50), joints3d=joints, joint_names=np.array([f"j{i}" for i in range(15)]))
    seq = load_sequence(path)
    assert seq.fps == 50.0 and seq.joints3d.shape == (5, 15, 3) and seq.silhouettes is None


@pytest.mark.parametrize(
    "change,match",
    [
        ({"fps": None}, "missing required key 'fps'"),
        ({"fps": -1.0}, "key 'fps'"),
        ({"joints3d": np.zeros((8, 15))}, r"key 'joints3d': must have shape \(\*, \*, 3\)"),
        ({"joints3d": np.full((8, 15, 3), 1500.0)}, "store metres"),
        ({"joints3d": np.zeros((7, 15, 3))}, "key 'pose': has 8 frames but 'joints3d' has 7"),
        ({"pose": np.zeros((8, 31))}, "pose_layout names 32"),
        ({"camera_R": np.zeros((4, 3, 3))}, "key 'camera_R': camera 0 is not a rotation"),
        ({"camera_t": np.zeros((3, 3))}, "key 'camera_t': has 3 cameras"),
        ({"silhouettes": np.zeros((4, 8, 30, 40), np.float32)}, "key 'silhouettes': must be uint8"),
        ({"silhouettes": np.full((4, 8, 30, 40), 3, np.uint8)}, "0/1 or 0/255"),
        ({"silhouettes": np.zeros((4, 8, 30, 41), np.uint8)}, "image_size says 40x30"),
        ({"parents": np.array([0] * 15)}, "exactly one root"),
        ({"parents": np.array([-1, 2, 1] + list(range(3, 15)))}, r"joint 1's chain of parents never reaches the root \(a cycle\)"),
        ({"skeleton_offsets": np.zeros((15, 3))}, r"key 'skeleton_offsets': joint\(s\) \[1, 2, 3, 4, 5\] sit on their parent"),
        ({"joint_names": np.arange(15)}, "key 'joint_names': must be a 1-D array of strings"),
        ({"skeleton_offsets": np.full((15, 3), 1e200)}, "key 'skeleton_offsets': joint 0 sits 1e\\+200 m from its parent"),
        ({"capsule_radii": np.full(15, 5e4)}, "key 'capsule_radii': a radius of 5e\\+04 m"),
        ({"camera_t": np.full((4, 3), 1e300)}, "key 'camera_t': camera 0 sits 1e\\+300 m from the origin"),
        ({"camera_K": None}, "key 'camera_K': is required with the other camera keys"),
    ],
)
def test_bad_keys_are_named(scene, tmp_path, change, match):
    fields = scene.to_dict()
    fields.update(change)
    path = tmp_path / "bad.npz"
    np.savez(path, **{k: v for k, v in fields.items() if v is not None})
    with pytest.raises(SequenceFileError, match=match):
        load_sequence(path)


def test_nan_is_reported_with_its_index(scene, tmp_path):
    pose = scene.pose.copy()
    pose[3, 7] = np.nan
    with pytest.raises(SequenceFileError, match=r"key 'pose': contains a non-finite value at index \(3, 7\)"):
        scene.replace(pose=pose)


def test_not_an_npz_and_unknown_keys(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_text("hello")  # was reported as "contains pickled (object) data"
    with pytest.raises(SequenceFileError, match=r"bad\.npz: not a \.npz sequence file \(an \.npz is a zip archive; this file starts"):
        load_sequence(bad)
    np.save(tmp_path / "array.npy", np.zeros(3))
    (tmp_path / "array.npy").rename(bad)  # a .npy renamed .npz used to end in a TypeError
    with pytest.raises(SequenceFileError, match=r"is a single NumPy array \(\.npy\)"):
        load_sequence(bad)
    bad.write_bytes(b"PK\x03\x04 and then nothing")
    with pytest.raises(SequenceFileError, match=r"not a readable \.npz"):
        load_sequence(bad)
    np.savez(bad, fps=30.0, joints3d=np.zeros((0, 15, 3)))  # zero frames used to end in an IndexError later
    with pytest.raises(SequenceFileError, match=r"key 'joints3d': has no frames"):
        load_sequence(bad)
    with pytest.raises(SequenceFileError, match="is a folder"):
        load_sequence(tmp_path)
    with pytest.raises(FileNotFoundError):
        load_sequence(tmp_path / "missing.npz")
    extra = tmp_path / "extra.npz"
    np.savez(extra, fps=30.0, colour=np.zeros(3))
    with pytest.raises(SequenceFileError, match=r"unknown key\(s\) \['colour'\]"):
        load_sequence(extra)


def test_save_validates_first_and_loses_nothing(scene, tmp_path):
    path = tmp_path / "keep.npz"
    save_sequence(path, scene)
    before = path.read_bytes()
    with pytest.raises(SequenceFileError):
        save_sequence(path, {"fps": 30.0, "joints3d": np.zeros((2, 3))})
    assert path.read_bytes() == before
    seq = Sequence.create(fps=30.0, joints3d=np.zeros((2, 15, 3)))
    assert seq.num_frames == 2


def test_pose_columns_are_matched_by_name(scene, tmp_path):
    """A file whose pose columns are in another (named) order used to be read by position."""
    standard = tmp_path / "standard.npz"
    save_sequence(standard, scene)
    fields = dict(np.load(standard))
    perm = np.random.default_rng(0).permutation(fields["pose"].shape[1])
    fields["pose"], fields["pose_layout"] = fields["pose"][:, perm], fields["pose_layout"][perm]
    shuffled = tmp_path / "shuffled.npz"
    np.savez(shuffled, **fields)
    back = load_sequence(shuffled)
    np.testing.assert_array_equal(back.pose, load_sequence(standard).pose)
    np.testing.assert_array_equal(back.pose_layout, load_sequence(standard).pose_layout)
    fields["pose_layout"] = fields["pose_layout"].copy()
    fields["pose_layout"][0] = "tail_wag"
    np.savez(shuffled, **fields)
    with pytest.raises(SequenceFileError, match=r"key 'pose_layout': is not the HumanEva pose layout: unknown entries \['tail_wag'\]"):
        load_sequence(shuffled)
    fields["pose_layout"][0] = fields["pose_layout"][1]
    np.savez(shuffled, **fields)
    with pytest.raises(SequenceFileError, match=r"names \[.*\] more than once"):
        load_sequence(shuffled)


@pytest.mark.slow  # moved to the slow suite for the default suite's 10 minutes
def test_a_reordered_pose_layout_goes_through_every_command_as_the_standard_one(scene, tmp_path, capsys):
    """Every command reads sequences through the same loader, which puts the pose columns in the
    standard order by name: ``scene`` renders, ``fit`` learns and ``render`` draws the same
    from a file whose columns are shuffled as from the standard file, and what they write is
    labelled in the order it is stored."""
    from jaxtrack.cli import main
    from jaxtrack.manifold import load_model, read_header

    standard = tmp_path / "standard.npz"
    save_sequence(standard, scene.replace(silhouettes=None, camera_K=None, camera_R=None, camera_t=None, camera_dist=None,
                                          image_size=None, camera_names=None))
    fields = dict(np.load(standard))
    perm = np.random.default_rng(1).permutation(fields["pose"].shape[1])
    fields["pose"], fields["pose_layout"] = fields["pose"][:, perm], fields["pose_layout"][perm]
    shuffled = tmp_path / "shuffled.npz"
    np.savez(shuffled, **fields)
    for name in ("standard", "shuffled"):
        assert main(["scene", str(tmp_path / f"{name}.npz"), str(tmp_path / f"{name}_scene"), "--width", "16", "--height", "12",
                     "--clean"]) == 0
        assert main(["fit", str(tmp_path / f"{name}.npz"), "--steps", "2", "--out", str(tmp_path / f"{name}.eqx")]) == 0
    a, b = load_sequence(tmp_path / "standard_scene.npz"), load_sequence(tmp_path / "shuffled_scene.npz")
    np.testing.assert_array_equal(a.silhouettes, b.silhouettes)
    np.testing.assert_array_equal(a.pose, b.pose)
    np.testing.assert_array_equal(b.pose_layout, load_sequence(standard).pose_layout)
    assert read_header(tmp_path / "standard.eqx")["extra"]["pose_layout"] == read_header(tmp_path / "shuffled.eqx")["extra"]["pose_layout"]
    np.testing.assert_allclose(load_model(tmp_path / "standard.eqx")[0].data, load_model(tmp_path / "shuffled.eqx")[0].data, atol=1e-12)
    capsys.readouterr()
