"""Calibration files: the documented JSON, aniposelib / Pose2Sim TOML (Rodrigues, millimetres, a
Y-up world) and OpenCV FileStorage YAML and XML, each hand-written from one reference rig and
read back to project world points where the reference does; units and the up axis told apart;
malformed files refused naming the file and the entry."""

import json
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from jaxtrack.camera import default_rig, make_rig, project_points
from jaxtrack.io import CalibrationFileError, read_calibration, rodrigues, save_calibration

POINTS = np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 1.0], [-0.4, 0.5, 1.7], [0.1, 0.1, 0.5]])  # metres, Z up: a person's extent


@pytest.fixture(scope="module")
def reference():
    """A 3-camera rig at 640x480 with distortion, float64."""
    base = default_rig(640, 480, num_views=3, dtype=jnp.float64)
    dist = np.array([[-0.2, 0.05, 0.001, -0.002, 0.0], [0.1, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, 0.0]])
    return make_rig(np.asarray(base.K), np.asarray(base.R), np.asarray(base.t), np.asarray(base.image_size), dist=dist,
                    names=["left", "front", "right"], dtype=jnp.float64)


def _projected(rig, points):
    uv, _, _ = project_points(rig, jnp.asarray(points, rig.K.dtype))
    return np.asarray(uv)


def _matrix_yaml(name, m):
    m = np.atleast_2d(m)
    values = ", ".join(f"{v:.17g}" for v in m.ravel())
    return f"{name}: !!opencv-matrix\n   rows: {m.shape[0]}\n   cols: {m.shape[1]}\n   dt: d\n   data: [ {values} ]\n"


def test_rodrigues_is_scipys_rotation_vector():
    for v in ([0.0, 0.0, 0.0], [0.3, -1.2, 0.5], [np.pi, 0, 0]):
        np.testing.assert_allclose(rodrigues(v), Rotation.from_rotvec(v).as_matrix(), atol=1e-12)


def test_the_documented_json_round_trips(reference, tmp_path):
    path = save_calibration(tmp_path / "rig.json", reference)
    rig = read_calibration(path, dtype=jnp.float64)
    assert rig.names == ("left", "front", "right") and rig.image_size == reference.image_size
    np.testing.assert_allclose(_projected(rig, POINTS), _projected(reference, POINTS), atol=1e-9)
    data = json.loads(Path(path).read_text())
    assert data["units"] == "m" and data["up"] == "z" and len(data["cameras"][0]["distortion"]) == 5


def test_anipose_toml_in_millimetres_and_a_y_up_world(reference, tmp_path):
    to_file = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # Z-up world -> a Y-up one (y = z, z = -y)
    lines = []
    for c, name in enumerate(reference.names):
        R = np.asarray(reference.R[c]) @ to_file.T  # x_cam = R_file X_file + t
        rvec = Rotation.from_matrix(R).as_rotvec()
        K = np.asarray(reference.K[c])
        lines += [f"[cam_{c}]", f'name = "{name}"', "size = [ 640.0, 480.0,]",
                  "matrix = [ " + ", ".join("[ " + ", ".join(f"{v:.17g}" for v in row) + ",]" for row in K) + ",]",
                  "distortions = [ " + ", ".join(f"{v:.17g}" for v in np.asarray(reference.dist[c])) + ",]",
                  "rotation = [ " + ", ".join(f"{v:.17g}" for v in rvec) + ",]",
                  "translation = [ " + ", ".join(f"{1000 * v:.17g}" for v in np.asarray(reference.t[c])) + ",]",
                  "fisheye = false", ""]
    lines += ["[metadata]", "adjusted = false", "error = 0.31"]
    path = tmp_path / "calibration.toml"
    path.write_text("\n".join(lines))
    rig = read_calibration(path, dtype=jnp.float64)  # millimetres and Y up, both told from the cameras
    world = np.asarray(rig.R[0]).T @ np.asarray(reference.R[0])  # the read world's frame against the reference's
    np.testing.assert_allclose(world[:, 2], [0, 0, 1], atol=1e-9)  # up is up: heights are kept
    np.testing.assert_allclose(_projected(rig, POINTS @ world.T), _projected(reference, POINTS), atol=1e-6)
    stated = read_calibration(path, units="mm", up="y", dtype=jnp.float64)
    np.testing.assert_allclose(np.asarray(stated.R), np.asarray(rig.R), atol=1e-12)
    path.write_text("\n".join(lines).replace("fisheye = false", "fisheye = true", 1))
    with pytest.raises(CalibrationFileError, match=r"calibration.toml: \[cam_0\]: a fisheye camera"):
        read_calibration(path)
    # the size as width and height keys, as some tools write it
    path.write_text("\n".join(lines).replace("size = [ 640.0, 480.0,]", "width = 640\nheight = 480"))
    np.testing.assert_array_equal(np.asarray(read_calibration(path).image_size), np.asarray(rig.image_size))
    path.write_text("\n".join(lines).replace("size = [ 640.0, 480.0,]", "width = 640", 1))
    with pytest.raises(CalibrationFileError, match=r"\[cam_0\] size: missing \(looked for 'size', 'width' and 'height'"):
        read_calibration(path)
    # no size at all: taken from the videos where they are given, and said
    sizeless = "\n".join(lines).replace("size = [ 640.0, 480.0,]", "")
    path.write_text(sizeless)
    said = []
    filled = read_calibration(path, image_sizes=[(640, 480)] * rig.num_views, say=said.append)
    np.testing.assert_array_equal(np.asarray(filled.image_size), np.asarray(rig.image_size))
    assert said[0] == "calibration: camera 'left' gives no image size: 640x480, its video's" and len(said) == rig.num_views
    with pytest.raises(CalibrationFileError, match=r"size: missing .*track --video takes it from the videos"):
        read_calibration(path)


def test_opencv_yaml_and_xml_one_file_per_camera(reference, tmp_path):
    yaml_paths, xml_paths = [], []
    for c, name in enumerate(reference.names):
        K, R, t, d = (np.asarray(a[c]) for a in (reference.K, reference.R, reference.t, reference.dist))
        text = "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n" + _matrix_yaml("camera_matrix", K)
        text += _matrix_yaml("distortion_coefficients", d[None]) + _matrix_yaml("rvec", Rotation.from_matrix(R).as_rotvec()[:, None])
        text += _matrix_yaml("tvec", 1000 * t[:, None])
        (tmp_path / f"{name}.yml").write_text(text)
        yaml_paths.append(tmp_path / f"{name}.yml")

        def matrix(tag, m):
            m = np.atleast_2d(m)
            return (f'<{tag} type_id="opencv-matrix"><rows>{m.shape[0]}</rows><cols>{m.shape[1]}</cols><dt>d</dt>'
                    f'<data>{" ".join(f"{v:.17g}" for v in m.ravel())}</data></{tag}>')

        xml = ('<?xml version="1.0"?>\n<opencv_storage>\n<image_width>640</image_width><image_height>480</image_height>\n'
               + matrix("camera_matrix", K) + matrix("distortion_coefficients", d) + matrix("R", R) + matrix("T", t)
               + "\n</opencv_storage>\n")
        (tmp_path / f"{name}.xml").write_text(xml)
        xml_paths.append(tmp_path / f"{name}.xml")
    from_yaml = read_calibration(yaml_paths, dtype=jnp.float64)  # millimetres told from the distances
    from_xml = read_calibration(xml_paths, units="m", up="z", dtype=jnp.float64)
    assert from_yaml.names == ("left", "front", "right")
    for rig in (from_yaml, from_xml):
        np.testing.assert_allclose(_projected(rig, POINTS), _projected(reference, POINTS), atol=1e-6)


def test_malformed_calibrations_name_the_file_and_the_entry(reference, tmp_path):
    path = save_calibration(tmp_path / "rig.json", reference)
    data = json.loads(Path(path).read_text())
    del data["cameras"][1]["translation"]
    (tmp_path / "missing.json").write_text(json.dumps(data))
    with pytest.raises(CalibrationFileError, match=r"missing.json: cameras\[1\] translation: missing"):
        read_calibration(tmp_path / "missing.json")
    data = json.loads(Path(path).read_text())
    data["cameras"][0]["rotation"] = [[1, 0, 0], [0, 1, 0], [0, 0, 2]]
    (tmp_path / "scaled.json").write_text(json.dumps(data))
    with pytest.raises(CalibrationFileError, match="camera 'left' rotation: not a rotation matrix"):
        read_calibration(tmp_path / "scaled.json")
    (tmp_path / "broken.json").write_text('{"cameras": [\n  {"name": "a",\n  "size": [1, 2]\n')
    with pytest.raises(CalibrationFileError, match=r"broken.json:\d+: not JSON"):
        read_calibration(tmp_path / "broken.json")
    (tmp_path / "cam.yml").write_text("%YAML:1.0\nimage_width: 640\nimage_height: 480\n" + _matrix_yaml("camera_matrix", np.eye(3)))
    with pytest.raises(CalibrationFileError, match=r"cam.yml: rotation \(R or rvec\): missing"):
        read_calibration(tmp_path / "cam.yml")
    with pytest.raises(CalibrationFileError, match="unknown calibration format"):
        read_calibration(_touch(tmp_path / "rig.ini"))
    with pytest.raises(CalibrationFileError, match="up: 'w' is not an axis"):
        read_calibration(path, up="w")
    with pytest.raises(FileNotFoundError, match="no calibration file"):
        read_calibration(tmp_path / "absent.json")


def _touch(path):
    path.write_text("")
    return path
