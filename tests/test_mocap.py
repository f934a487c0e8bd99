import os
import time

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body import inverse_kinematics, retarget_positions
from jaxtrack.cli import main
from jaxtrack.data import generate_motion
from jaxtrack.errors import ConfigurationError
from jaxtrack.io import (
    MotionFileError,
    load_asf_amc,
    load_bvh,
    load_joints3d,
    load_sequence,
    read_asf,
    resample,
    save_sequence,
)

from helpers import ASF, write_amc, write_bvh


@pytest.fixture
def asf_amc(tmp_path):
    asf = tmp_path / "t.asf"
    asf.write_text(ASF)
    amc = tmp_path / "t.amc"
    write_amc(amc, [((0, 0, 0, 0, 0, 0), (0, 0, 0), (0,)), ((1, 2, 3, 0, 0, 90), (0, 0, 0), (90,))])
    return asf, amc


def test_asf_amc_forward_kinematics_by_hand(asf_amc):
    asf, amc = asf_amc
    motion = load_asf_amc(asf, amc, fps=60.0, length_unit_m=1.0)
    assert motion.joint_names == ("root", "up", "side") and motion.parents == (-1, 0, 1)
    # Frame 1: "up" ends 2 above the root (Y up in the file -> Z up here), "side" 1 along +x.
    np.testing.assert_allclose(motion.positions[0], [[0, 0, 0], [0, 0, 2], [1, 0, 2]], atol=1e-12)
    # Frame 2: root at (1, 2, 3) file units turned 90 deg about the file's z axis: its y axis
    # becomes -x. "side" rotates 90 deg about its local x (= file z after C): no change in
    # direction for a bone along its own local ... so check through the composed rotation.
    p = motion.positions[1]
    root_file = np.array([1.0, 2.0, 3.0])
    to_z_up = lambda v: np.array([v[0], -v[2], v[1]])  # noqa: E731
    np.testing.assert_allclose(p[0], to_z_up(root_file), atol=1e-12)
    np.testing.assert_allclose(p[1], to_z_up(root_file + [-2.0, 0, 0]), atol=1e-12)
    # side: direction (1,0,0) under R_root * C Rx(90) C^-1 with C = Rz(90): C Rx C^-1 = Ry(-90)...
    Rz = lambda a: np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])  # noqa: E731
    Rx = lambda a: np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])  # noqa: E731
    C = Rz(np.pi / 2)
    R_side = Rz(np.pi / 2) @ C @ Rx(np.pi / 2) @ C.T
    np.testing.assert_allclose(p[2], to_z_up(root_file + [-2.0, 0, 0] + R_side @ [1.0, 0, 0]), atol=1e-12)
    # Default units: inches scaled by the file's length factor (1.0 here).
    assert load_asf_amc(asf, amc, fps=60.0).positions[0, 1, 2] == pytest.approx(2 * 0.0254)


def test_amc_units_frame_numbers_and_asf_bones_are_checked(asf_amc, tmp_path):
    """AMC ``:RADIANS`` used to be ignored; a repeated frame number, an ASF ``direction 0 0 0``
    and ``length 0`` were accepted or failed later without a line."""
    asf, amc = asf_amc
    degrees = load_asf_amc(asf, amc, fps=60.0)
    text = amc.read_text()
    lines = text.splitlines()
    radians_lines = [":FULLY-SPECIFIED", ":RADIANS"]
    for line in lines[2:]:
        words = line.split()
        if words[0] == "root":  # TX TY TZ stay, RX RY RZ in radians
            words[4:] = [str(float(np.radians(float(v)))) for v in words[4:]]
        elif words[0] in ("up", "side"):
            words[1:] = [str(float(np.radians(float(v)))) for v in words[1:]]
        radians_lines.append(" ".join(words))
    radians = tmp_path / "radians.amc"
    radians.write_text("\n".join(radians_lines) + "\n")
    np.testing.assert_allclose(load_asf_amc(asf, radians, fps=60.0).positions, degrees.positions, atol=1e-12)
    repeated = tmp_path / "repeated.amc"
    repeated.write_text(text.replace("\n2\n", "\n1\n", 1))
    with pytest.raises(MotionFileError, match=r"repeated\.amc:\d+: frame number 1 where 2 was expected"):
        load_asf_amc(asf, repeated, fps=60.0)
    bad = tmp_path / "bad.asf"
    for old, new, message in (("direction 0 1 0", "direction 0 0 0", r"bad\.asf:\d+: direction 0 0 0"),
                              ("length 2.0", "length 0", r"bad\.asf:\d+: length 0: a bone's length must be positive")):
        bad.write_text(ASF.replace(old, new))
        with pytest.raises(MotionFileError, match=message):
            read_asf(bad)


@pytest.mark.parametrize("frame_time", ["inf", "nan", "1e-300", "0", "-0.01", "1e6"])
def test_bvh_frame_time_out_of_range_is_refused_with_its_line(tmp_path, frame_time):
    """``Frame Time: 1e-300`` used to write a 1e300 Hz file; ``inf`` was reported as "0.0 and 0.0"."""
    path = tmp_path / "t.bvh"
    write_bvh(path, [[10, 90, -5, 0, 0, 0, 0, 0, 0]], frame_time=frame_time)
    with pytest.raises(MotionFileError, match=rf"t\.bvh:\d+: Frame Time {frame_time}: must be a number of seconds between"):
        load_bvh(path)


def test_non_finite_values_in_motion_files_are_refused_with_their_line(asf_amc, tmp_path):
    asf, amc = asf_amc
    amc.write_text(amc.read_text().replace("side 90", "side nan"))
    with pytest.raises(MotionFileError, match=r"t\.amc:\d+: bone 'side': non-finite value in 'nan'"):
        load_asf_amc(asf, amc, fps=60.0)
    path = tmp_path / "t.bvh"
    write_bvh(path, [[10, 90, -5, 0, 0, 0, 0, 0, 0], [10, 90, -5, 0, float("inf"), 0, 0, 0, 0]])
    with pytest.raises(MotionFileError, match=r"t\.bvh:\d+: non-finite value 'inf' \(channel 5\)"):
        load_bvh(path)
    mapping = tmp_path / "map.json"
    mapping.write_text('{"head": "Head",\n "neck": }')
    assert main(["convert", str(path), str(tmp_path / "out.npz"), "--mapping", str(mapping)]) == 2


def test_bvh_written_and_read_back(tmp_path):
    path = tmp_path / "t.bvh"
    frames = [[10, 90, -5, 0, 0, 0, 0, 0, 0], [10, 90, -5, 90, 0, 0, 0, 90, 0]]
    write_bvh(path, frames)
    motion = load_bvh(path)  # centimetres guessed? rest height 90 cm -> 0.9 units > 3? no: give units
    motion = load_bvh(path, unit_m=0.01)
    assert motion.fps == pytest.approx(25.0) and motion.joint_names == ("hips", "spine")
    to_z_up = lambda v: np.array([v[0], -v[2], v[1]])  # noqa: E731
    np.testing.assert_allclose(motion.positions[0, 0], to_z_up([0.1, 0.9, -0.05]))
    np.testing.assert_allclose(motion.positions[0, 1], to_z_up([0.1, 1.4, -0.05]))
    # Frame 2: hips turned 90 deg about the file's z: the spine offset (0, 50, 0) points to -x.
    np.testing.assert_allclose(motion.positions[1, 1], to_z_up([0.1 - 0.5, 0.9, -0.05]), atol=1e-12)
    assert motion.values[1, 3] == pytest.approx(np.pi / 2)


@pytest.mark.parametrize(
    "mutate,match",
    [
        (lambda t: t.replace("Frames: 2", "Frames: 3"), r"t\.bvh:\d+: header says 3 frames, found 2"),
        (lambda t: t.rstrip("\n").rsplit("\n", 1)[0] + "\n10 90 -5 0 0\n", r"t\.bvh:20: frame has 5 values, the hierarchy declares 9"),
        (lambda t: t.replace("10 90 -5 90", "10 90 -5 abc"), r"t\.bvh:20: non-numeric value 'abc'"),
        (lambda t: t.replace("CHANNELS 3 Zrotation", "CHANNELS 4 Zrotation"), r"t\.bvh:9: CHANNELS says 4 but lists 3"),
        (lambda t: t.split("MOTION")[0], r"t\.bvh:\d+: no MOTION section"),
        (lambda t: t.replace("Yrotation\n\t\tEnd", "Wrotation\n\t\tEnd"), r"t\.bvh:9: unknown channel 'Wrotation'"),
    ],
)
def test_bad_bvh_names_file_and_line(tmp_path, mutate, match):
    path = tmp_path / "t.bvh"
    write_bvh(path, [[10, 90, -5, 0, 0, 0, 0, 0, 0], [10, 90, -5, 90, 0, 0, 0, 90, 0]])
    path.write_text(mutate(path.read_text()))
    with pytest.raises(MotionFileError, match=match):
        load_bvh(path)


def test_bad_amc_and_asf_name_file_and_line(asf_amc, tmp_path):
    asf, amc = asf_amc
    text = amc.read_text()
    amc.write_text(text.replace("side 90", "elbow 90"))
    with pytest.raises(MotionFileError, match=r"t\.amc:10: unknown bone 'elbow'"):
        load_asf_amc(asf, amc, fps=120.0)
    amc.write_text(text.replace("up 0 0 0\nside 90", "up 0 x 0\nside 90"))
    with pytest.raises(MotionFileError, match=r"t\.amc:9: bone 'up': non-numeric value"):
        load_asf_amc(asf, amc, fps=120.0)
    amc.write_text(text.replace("up 0 0 0\nside 90", "up 0 0\nside 90"))
    with pytest.raises(MotionFileError, match=r"t\.amc:9: bone 'up': expected 3 numbers, got 2"):
        load_asf_amc(asf, amc, fps=120.0)
    amc.write_text(text.rsplit("side", 1)[0])  # truncated: the last frame lacks a bone
    with pytest.raises(MotionFileError, match=r"t\.amc:7: frame 2 lacks bone\(s\) \['side'\]"):
        load_asf_amc(asf, amc, fps=120.0)
    bad_asf = tmp_path / "bad.asf"
    bad_asf.write_text(ASF.replace("    up side\n", "    up hand\n"))
    with pytest.raises(MotionFileError, match=r"bad\.asf:36: hierarchy names unknown bone\(s\) \['hand'\]"):
        read_asf(bad_asf)
    bad_asf.write_text(ASF.split("  end\n  begin\n     id 2")[0])
    with pytest.raises(MotionFileError, match=r"bad\.asf:\d+: bone block not closed"):
        read_asf(bad_asf)


def test_asf_hierarchy_cycles_and_depth_end_quickly(tmp_path):
    """A hierarchy that is not a tree (a bone with two parents, a cycle detached from the root,
    the root given a parent) is refused with its line; the parse used to loop for ever. A
    chain of 3000 bones parses in well under a second."""
    bad = tmp_path / "cycle.asf"
    cases = [
        ("    up side\n", "    up side\n    side up\n", r"cycle\.asf:37: hierarchy gives bone 'up' a second parent \(first on line 35\)"),
        ("    up side\n", "    up side\n    side root\n", r"cycle\.asf:37: hierarchy names unknown bone\(s\) \['root'\]"),
        ("    root up\n    up side\n", "    root up\n    side side\n", r"cycle\.asf:36: hierarchy gives 'side' a parent it cannot have"),
    ]
    for old, new, message in cases:
        bad.write_text(ASF.replace(old, new))
        with pytest.raises(MotionFileError, match=message):
            read_asf(bad)
    # A two-bone cycle with no path from the root: each bone has one parent, none is reached.
    three = ASF.replace(":hierarchy", "  begin\n     id 3\n     name loose\n     direction 1 0 0\n     length 1.0\n"
                                      "     axis 0 0 0 XYZ\n  end\n:hierarchy")
    bad.write_text(three.replace("    up side\n", "    side loose\n    loose side\n").replace("    root up\n", "    root up\n"))
    with pytest.raises(MotionFileError, match=r"(second parent|not connected to the root)"):
        read_asf(bad)
    bad.write_text(three.replace("    up side\n", "    up side\n    loose loose\n"))
    with pytest.raises(MotionFileError, match="parent it cannot have"):
        read_asf(bad)
    # Deep: root -> b0 -> b1 -> ... -> b2999.
    bones = "".join(f"  begin\n     id {i + 1}\n     name b{i}\n     direction 0 1 0\n     length 0.01\n     axis 0 0 0 XYZ\n  end\n"
                    for i in range(3000))
    links = "    root b0\n" + "".join(f"    b{i} b{i + 1}\n" for i in range(2999))
    deep = ASF.split(":bonedata")[0] + ":bonedata\n" + bones + ":hierarchy\n  begin\n" + links + "  end\n"
    path = tmp_path / "deep.asf"
    path.write_text(deep)
    start = time.perf_counter()
    skeleton = read_asf(path)
    assert len(skeleton.order()) == 3001 and skeleton.order()[-1] == ("b2999", "b2998")
    assert time.perf_counter() - start < 2.0


def test_resample():
    values = np.arange(13, dtype=float)[:, None] * np.array([[1.0, 2.0]])  # 120 Hz ramp
    out = resample(values, 120.0, 30.0)
    np.testing.assert_allclose(out[:, 0], [0, 4, 8, 12])
    out = resample(values, 120.0, 50.0)
    np.testing.assert_allclose(out[:, 1], 2 * np.arange(6) * 2.4)  # 0.1 s at 50 Hz: 6 frames


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_ik_round_trip_recovers_the_pose():
    motion = generate_motion("walk", "S2", num_frames=40, fps=30.0, key=jax.random.key(0), dtype=jnp.float64)
    result = inverse_kinematics(motion.joints3d, key=jax.random.key(1))
    np.testing.assert_allclose(
        np.asarray(result.skeleton.offsets), np.asarray(motion.body.skeleton.offsets), atol=1e-9
    )
    assert float(result.residual_mm.max()) < 1.0
    # Every joint is reproduced, and so is every angle the 15 joints determine (to 0.6 degrees:
    # the pelvis yaw rests on the hips alone, 0.1 m from the root). Twists about a bone's own
    # axis and the clavicles trade against each other (null space), so they are not compared.
    pose = np.asarray(result.pose)
    identifiable = [n for n in result.skeleton.pose_layout if "twist" not in n and "clavicle" not in n]
    assert len(identifiable) == 22
    for name in identifiable:
        k = result.skeleton.dof_index(name)
        np.testing.assert_allclose(pose[:, k], motion.pose[:, k], atol=1e-2, err_msg=name)
    assert float(result.skeleton.limit_violation(result.pose).max()) == 0.0


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_ik_fits_in_float64_whether_or_not_x64_is_on():
    # The Gauss-Newton tolerances need float64: the fit runs in it and returns the dtype asked for.
    motion = generate_motion("jog", "S1", num_frames=12, fps=60.0, key=jax.random.key(0), dtype=jnp.float64)
    wide = inverse_kinematics(motion.joints3d, key=jax.random.key(1))
    with jax.enable_x64(False):
        narrow = inverse_kinematics(np.asarray(motion.joints3d), key=jax.random.key(1))
        assert narrow.pose.dtype == jnp.float32 and narrow.skeleton.offsets.dtype == jnp.float32
    assert wide.pose.dtype == jnp.float64
    np.testing.assert_allclose(np.asarray(narrow.pose), np.asarray(wide.pose), atol=1e-6)
    np.testing.assert_allclose(np.asarray(narrow.residual_mm), np.asarray(wide.residual_mm), atol=1e-3)


def test_ik_and_mapping_errors():
    with pytest.raises(ValueError, match=r"\(T, 15, 3\)"):
        inverse_kinematics(np.zeros((4, 14, 3)), restarts=0)
    bad = np.zeros((4, 15, 3))
    bad[2, 3, 0] = np.nan
    with pytest.raises(ValueError, match="frame 2, joint lelbow"):
        inverse_kinematics(bad, restarts=0)
    with pytest.raises(ValueError, match="needs a PRNG key"):
        inverse_kinematics(np.random.default_rng(0).normal(size=(4, 15, 3)))
    with pytest.raises(ValueError, match="no built-in joint mapping fits"):
        retarget_positions(np.zeros((2, 3, 3)), ["a", "b", "c"])
    with pytest.raises(ValueError, match="lacks"):
        retarget_positions(np.zeros((2, 3, 3)), ["a", "b", "c"], dict.fromkeys(__import__("jaxtrack").body.HUMANEVA_JOINTS, "zz"))


@pytest.mark.slow
def test_convert_cli_on_joint_arrays(tmp_path, capsys):
    motion = generate_motion("walk", "S1", num_frames=30, fps=60.0, dtype=jnp.float64)
    source = tmp_path / "joints.npz"
    np.savez(source, fps=60.0, joints3d=motion.joints3d, joint_names=np.array(motion.body.skeleton.joint_names))
    assert load_joints3d(source).num_frames == 30
    out = tmp_path / "out.npz"
    assert main(["convert", str(source), str(out), "--fps", "30"]) == 0
    seq = load_sequence(out)
    assert seq.fps == 30.0 and seq.pose.shape == (15, 32) and seq.joints3d.shape == (15, 15, 3)
    np.testing.assert_allclose(seq.joints3d, motion.joints3d[::2], atol=1e-9)
    assert "residual mean" in capsys.readouterr().out
    assert main(["convert", str(tmp_path / "x.amc"), str(out)]) == 2
    assert "pass --asf" in capsys.readouterr().err
    # A motion file whose lengths are centimetres read as metres (a BVH's offsets, an ASF's units):
    # refused before the inverse kinematics, naming the source and the units it looks like.
    from jaxtrack.io import MotionCapture, convert_motion

    names = tuple(motion.body.skeleton.joint_names)
    in_cm = MotionCapture(names, tuple(motion.body.skeleton.parents), 100.0 * np.asarray(motion.joints3d), 60.0, (),
                          np.zeros((30, 0)), "walk_cm.bvh")
    started = time.perf_counter()
    with pytest.raises(ConfigurationError, match=r"walk_cm.bvh: the legs \(hip to ankle\) are .* looks like centimetres"):
        convert_motion(in_cm, None)
    assert time.perf_counter() - started < 5.0


# --- real motion capture from ../shared/data (skipped when absent) -------------------------


def _speed(joints, fps):
    return np.linalg.norm(np.diff(joints[:, 0, :2], axis=0), axis=1).mean() * fps


def _check_ik(joints, key):
    result = inverse_kinematics(joints, key=key)
    residual = float(result.residual_mm.mean())
    pose = np.asarray(result.pose)
    jumps = np.abs(np.diff(pose[:, 3:], axis=0)).max()
    assert residual < 15.0, residual
    assert float(result.skeleton.limit_violation(result.pose).max()) == 0.0
    assert jumps < 1.0, jumps  # no wrapping or flips between frames (largest real step ~0.6 rad)
    return residual


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_cmu_walk_and_jog(shared_data):
    cmu = os.path.join(shared_data, "cmu35")
    motion = load_asf_amc(os.path.join(cmu, "35.asf"), os.path.join(cmu, "35_01.amc"), fps=120.0)
    lengths = motion.bone_lengths()
    np.testing.assert_allclose(lengths.std(axis=0), 0, atol=1e-9)
    assert 1.2 < _speed(motion.positions, 120.0) < 1.4
    assert 1.55 < motion.joint("head")[:, 2].mean() < 1.75
    walk = resample(retarget_positions(motion.positions, motion.joint_names), 120.0, 30.0)[:60]
    walk_residual = _check_ik(walk, jax.random.key(0))

    from scipy.io import loadmat

    from jaxtrack.io import motion_from_amc_values, read_asf

    data = loadmat(os.path.join(cmu, "cmu35WalkJog.mat"))
    jog_rows = data["lbls"][:, 16] == 1  # trial 35_17, a jog
    skeleton = read_asf(os.path.join(cmu, "35.asf"))
    jog = motion_from_amc_values(skeleton, data["Y"][jog_rows], fps=30.0)
    # The .mat's first sequence equals every 4th frame of 35_01.amc.
    first = motion_from_amc_values(skeleton, data["Y"][data["lbls"][:, 0] == 1][:3], fps=30.0)
    np.testing.assert_allclose(first.positions, motion.positions[:12:4], atol=1e-6)
    assert 2.5 < _speed(jog.positions, 30.0) < 4.0
    jog_residual = _check_ik(retarget_positions(jog.positions, jog.joint_names), jax.random.key(1))
    print(f"CMU IK residual: walk {walk_residual:.1f} mm, jog {jog_residual:.1f} mm")


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_bandai_walk_and_run(shared_data):
    folder = os.path.join(shared_data, "bandai_walk_run")
    walk = load_bvh(os.path.join(folder, "dataset-2_walk_normal_001.bvh"))
    run = load_bvh(os.path.join(folder, "dataset-2_run_normal_001.bvh"))
    assert walk.fps == pytest.approx(30.0, rel=1e-4)  # "Frame Time: 0.0333333"
    assert 1.0 < _speed(walk.joint("Hips")[:, None], 30.0) < 1.25
    assert 2.8 < _speed(run.joint("Hips")[:, None], 30.0) < 4.2
    lengths = walk.bone_lengths()[:, 2:]  # joint_Root -> Hips carries the world translation
    np.testing.assert_allclose(lengths.std(axis=0), 0, atol=1e-9)
    residuals = [
        _check_ik(retarget_positions(m.positions, m.joint_names)[:60], jax.random.key(i)) for i, m in enumerate((walk, run))
    ]
    print(f"Bandai IK residual: walk {residuals[0]:.1f} mm, run {residuals[1]:.1f} mm")


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_bandai_run_first_frame_is_upright_without_x64(shared_data):
    # In float32 this take's first frame landed at a pelvis pitch of 0.81 rad (the spine bent back
    # to match, 8.6 mm from the joints) and the next frame jumped 0.7 rad out of it.
    run = load_bvh(os.path.join(shared_data, "bandai_walk_run", "dataset-2_run_normal_006.bvh"))
    joints = retarget_positions(run.positions, run.joint_names)[:8]
    with jax.enable_x64(False):
        result = inverse_kinematics(joints, key=jax.random.key(0))
    pose = np.asarray(result.pose)
    pitch, roll = (result.skeleton.dof_index(n) for n in ("root_pitch", "root_roll"))
    assert abs(pose[0, pitch]) < 0.1 and abs(pose[0, roll]) < 0.3, pose[0, 3:6]
    assert np.abs(np.diff(pose[:, 3:6], axis=0)).max() < 0.2  # the root turns smoothly from frame 0 on
    assert float(result.residual_mm.mean()) < 5.0


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_convert_cli_on_real_amc(shared_data, tmp_path):
    cmu = os.path.join(shared_data, "cmu35")
    out = tmp_path / "35_01.npz"
    assert main(["convert", os.path.join(cmu, "35_01.amc"), str(out), "--source-fps", "120", "--fps", "30"]) == 0
    seq = load_sequence(out)
    assert seq.num_frames == 90 and seq.pose.shape == (90, 32)
    save_sequence(tmp_path / "again.npz", seq)


def test_cmu_mat_trials_written_as_amc(shared_data, tmp_path):
    """benchmarks/cmu_trials_to_amc.py writes GPmat's 30 Hz trials as AMC files that read back
    to the same channel values; trial 35_01 equals every 4th frame of the raw 120 Hz file."""
    import importlib.util

    from jaxtrack.io import read_amc, read_asf

    script = os.path.join(os.path.dirname(__file__), "..", "benchmarks", "cmu_trials_to_amc.py")
    spec = importlib.util.spec_from_file_location("cmu_trials_to_amc", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main([str(tmp_path), "--data", os.path.join(shared_data, "cmu35")]) == 0
    skeleton = read_asf(tmp_path / "35.asf")
    _, written = read_amc(tmp_path / "35_01.amc", skeleton)
    _, raw = read_amc(os.path.join(shared_data, "cmu35", "35_01.amc"), skeleton)
    assert written.shape == (90, 62)
    np.testing.assert_allclose(written, raw[::4][:90], rtol=1e-5, atol=1e-4)
    assert read_amc(tmp_path / "35_18.amc", skeleton)[1].shape[0] == 44
    assert read_amc(tmp_path / "35_29.amc", skeleton)[1].shape[0] == 125
