"""Camera calibration files in the layouts people already have, read into a ``CameraRig`` in
jaxtrack's world (Z up, metres):

- **JSON** (documented here, written by ``save_calibration``)::

      {"units": "m", "up": "z",
       "cameras": [{"name": "C1", "size": [640, 480],
                    "matrix": [[fx, 0, cx], [0, fy, cy], [0, 0, 1]],
                    "distortion": [k1, k2, p1, p2, k3],
                    "rotation": [[...3x3 world-to-camera...]] or [rx, ry, rz] (Rodrigues),
                    "translation": [tx, ty, tz]}]}

- **TOML** as aniposelib, Pose2Sim and FreeMoCap write it: one table per camera with ``name``,
  ``size`` (width, height), ``matrix``, ``distortions``, ``rotation`` (Rodrigues) and
  ``translation``; a ``[metadata]`` table is skipped; ``fisheye = true`` is refused.
- **OpenCV FileStorage**, YAML (``%YAML:1.0``) or XML, one file per camera, as
  ``cv::FileStorage`` writes ``!!opencv-matrix`` entries: the intrinsics as ``camera_matrix``
  (or ``K``, ``cameraMatrix``), the distortion as ``distortion_coefficients`` (or ``dist``,
  ``D``, ``distCoeffs``), the extrinsics as ``R`` or ``rotation`` (3x3) or ``rvec`` (Rodrigues)
  with ``T`` / ``t`` / ``tvec`` / ``translation``, and the size as ``image_width`` and
  ``image_height`` (or ``image_size``).

Every layout maps world to camera: ``x_cam = R X + t``, OpenCV's pinhole and distortion model.
The world is converted to jaxtrack's: ``units`` "m" or "mm" (None: millimetres when the
cameras' median distance from the world origin is over 50, which no room in metres has), and
``up`` the world axis pointing up, "z", "y", "-y", ... (None: the axis the cameras' image-up
directions agree on, as cameras are mounted upright). A missing or malformed entry raises
``CalibrationFileError`` naming the file and the entry.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import xml.etree.ElementTree as ElementTree

import numpy as np

from ..errors import JaxtrackError
from ._output import atomic_write

UNITS = {"m": 1.0, "mm": 1e-3}
AXES = {"x": 0, "y": 1, "z": 2}


class CalibrationFileError(JaxtrackError):
    """A camera calibration file that cannot be read; the message names the file and the entry."""

    def __init__(self, path, message: str):
        super().__init__(f"{path}: {message}")
        self.path = path


def rodrigues(vector) -> np.ndarray:
    """(3,) axis-angle vector (radians) -> (3, 3) rotation matrix (OpenCV's ``Rodrigues``)."""
    v = np.asarray(vector, np.float64).reshape(3)
    angle = np.linalg.norm(v)
    if angle < 1e-12:
        return np.eye(3)
    k = v / angle
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross


def _array(path, entry, value, shape) -> np.ndarray:
    try:
        array = np.asarray(value, np.float64)
    except (TypeError, ValueError):
        raise CalibrationFileError(path, f"{entry}: not numbers") from None
    if array.size != int(np.prod(shape)):
        raise CalibrationFileError(path, f"{entry}: {array.size} numbers, expected {int(np.prod(shape))} ({'x'.join(map(str, shape))})")
    array = array.reshape(shape)
    if not np.all(np.isfinite(array)):
        raise CalibrationFileError(path, f"{entry}: contains NaN or infinite values")
    return array


def _camera(path, name, matrix, distortion, rotation, translation, size) -> dict:
    """One camera's checked arrays: K (3, 3), dist (5,), R (3, 3), t (3,), size (2,)."""
    K = _array(path, f"camera {name!r} matrix", matrix, (3, 3))
    if K[0, 0] <= 0 or K[1, 1] <= 0 or not np.allclose(K[2], [0, 0, 1]):
        raise CalibrationFileError(path, f"camera {name!r} matrix: needs positive focal lengths and last row (0, 0, 1)")
    dist = np.zeros(5)
    if distortion is not None:
        values = np.asarray(distortion, np.float64).ravel()
        if values.size not in (4, 5, 8) and values.size != 0:
            raise CalibrationFileError(path, f"camera {name!r} distortion: {values.size} coefficients, expected 4, 5 or 8 (OpenCV order)")
        if values.size == 8 and np.any(values[5:] != 0):
            raise CalibrationFileError(path, f"camera {name!r} distortion: the rational model (k4-k6) is not supported")
        dist[: min(5, values.size)] = values[:5]
        if not np.all(np.isfinite(dist)):
            raise CalibrationFileError(path, f"camera {name!r} distortion: contains NaN or infinite values")
    rotation = np.asarray(rotation, np.float64)
    R = rodrigues(_array(path, f"camera {name!r} rotation", rotation, (3,))) if rotation.size == 3 else _array(
        path, f"camera {name!r} rotation", rotation, (3, 3))
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-4) or np.linalg.det(R) < 0:
        raise CalibrationFileError(path, f"camera {name!r} rotation: not a rotation matrix")
    t = _array(path, f"camera {name!r} translation", translation, (3,))
    if isinstance(size, _Missing):
        return {"name": str(name), "K": K, "dist": dist, "R": R, "t": t, "size": size}
    size = _array(path, f"camera {name!r} size", size, (2,))
    if np.any(size < 1) or np.any(size != np.round(size)):
        raise CalibrationFileError(path, f"camera {name!r} size: must be (width, height) in whole pixels, got {size.tolist()}")
    return {"name": str(name), "K": K, "dist": dist, "R": R, "t": t, "size": size.astype(np.int64)}


def _required(path, table: dict, keys, what: str):
    for key in keys:
        if key in table:
            return table[key]
    raise CalibrationFileError(path, f"{what}: missing (looked for {', '.join(map(repr, keys))})")


_SIZE_PAIRS = (("width", "height"), ("image_width", "image_height"))


def _size(path, table: dict, keys, what: str):
    """A camera's image size: one of ``keys`` (width, height), or a width and height pair
    (``width`` / ``height``, ``image_width`` / ``image_height``)."""
    for key in keys:
        if key in table:
            return table[key]
    for width, height in _SIZE_PAIRS:
        if width in table and height in table:
            return [table[width], table[height]]
    looked = ", ".join([*map(repr, keys), *(f"{w!r} and {h!r}" for w, h in _SIZE_PAIRS)])
    return _Missing(f"{what}: missing (looked for {looked})")


@dataclasses.dataclass(frozen=True)
class _Missing:
    """An image size the file does not give: what was looked for (``read_calibration`` takes it
    from ``image_sizes``, or raises this)."""

    why: str


def _read_json(path) -> tuple[list[dict], str | None, str | None]:
    try:
        with open(path) as handle:
            data = json.load(handle)
    except json.JSONDecodeError as err:
        raise CalibrationFileError(f"{path}:{err.lineno}", f"not JSON: {err.msg}") from None
    if not isinstance(data, dict) or not isinstance(data.get("cameras"), list) or not data["cameras"]:
        raise CalibrationFileError(path, "'cameras': missing or empty (a calibration JSON is {\"cameras\": [...]})")
    cameras = []
    for i, cam in enumerate(data["cameras"]):
        if not isinstance(cam, dict):
            raise CalibrationFileError(path, f"cameras[{i}]: not an object")
        name = cam.get("name", f"cam{i}")
        cameras.append(_camera(path, name, _required(path, cam, ("matrix", "K"), f"cameras[{i}] matrix"),
                               cam.get("distortion", cam.get("dist")),
                               _required(path, cam, ("rotation", "R", "rvec"), f"cameras[{i}] rotation"),
                               _required(path, cam, ("translation", "t", "tvec"), f"cameras[{i}] translation"),
                               _size(path, cam, ("size", "image_size"), f"cameras[{i}] size")))
    return cameras, data.get("units"), data.get("up")


def _read_toml(path) -> list[dict]:
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except tomllib.TOMLDecodeError as err:
        raise CalibrationFileError(path, f"not TOML: {err}") from None
    cameras = []
    for key, table in data.items():
        if key == "metadata" or not isinstance(table, dict):
            continue
        if table.get("fisheye"):
            raise CalibrationFileError(path, f"[{key}]: a fisheye camera; jaxtrack models OpenCV's pinhole distortion only")
        cameras.append(_camera(path, table.get("name", key), _required(path, table, ("matrix",), f"[{key}] matrix"),
                               table.get("distortions", table.get("distortion")),
                               _required(path, table, ("rotation",), f"[{key}] rotation"),
                               _required(path, table, ("translation",), f"[{key}] translation"),
                               _size(path, table, ("size",), f"[{key}] size")))
    if not cameras:
        raise CalibrationFileError(path, "no camera tables (aniposelib, Pose2Sim and FreeMoCap write one [cam_...] table per camera)")
    return cameras


_YAML_MATRIX = re.compile(r"^(\w+):\s*!!opencv-matrix\s*$")
_YAML_SCALAR = re.compile(r"^(\w+):\s*(\S.*?)\s*$")


def _opencv_yaml(path) -> dict:
    """The top-level entries of an OpenCV FileStorage YAML file: numbers and matrices."""
    with open(path) as handle:
        lines = handle.read().splitlines()
    if not lines or not lines[0].startswith("%YAML"):
        raise CalibrationFileError(path, "not an OpenCV FileStorage YAML file (its first line is %YAML:1.0)")
    entries: dict = {}
    i = 1
    while i < len(lines):
        line = lines[i].split("#", 1)[0].rstrip()
        i += 1
        if not line or line == "---" or line.startswith(" "):
            continue
        matrix = _YAML_MATRIX.match(line)
        if matrix:
            fields: dict = {}
            while i < len(lines) and lines[i].startswith(" "):
                text = lines[i].strip()
                i += 1
                key, _, value = text.partition(":")
                if key == "data":
                    while "]" not in value and i < len(lines):
                        value += " " + lines[i].strip()
                        i += 1
                fields[key.strip()] = value.strip()
            try:
                rows, cols = int(fields["rows"]), int(fields["cols"])
                data = [float(v) for v in fields["data"].strip("[] ").replace(",", " ").split()]
            except (KeyError, ValueError):
                raise CalibrationFileError(f"{path}:{i}", f"{matrix.group(1)}: an opencv-matrix needs rows, cols and data") from None
            if len(data) != rows * cols:
                raise CalibrationFileError(f"{path}:{i}", f"{matrix.group(1)}: {len(data)} values for {rows}x{cols}")
            entries[matrix.group(1)] = np.asarray(data).reshape(rows, cols)
            continue
        scalar = _YAML_SCALAR.match(line)
        if scalar:
            value = scalar.group(2).strip('"')
            try:
                entries[scalar.group(1)] = [float(v) for v in value.strip("[]").split(",")] if value.startswith("[") else float(value)
            except ValueError:
                entries[scalar.group(1)] = value
    return entries


def _opencv_xml(path) -> dict:
    """The top-level entries of an OpenCV FileStorage XML file: numbers and matrices."""
    try:
        root = ElementTree.parse(path).getroot()
    except ElementTree.ParseError as err:
        raise CalibrationFileError(f"{path}:{err.position[0]}", f"not XML: {err}") from None
    if root.tag != "opencv_storage":
        raise CalibrationFileError(path, f"not an OpenCV FileStorage XML file (root <{root.tag}>, expected <opencv_storage>)")
    entries: dict = {}
    for node in root:
        if node.get("type_id") == "opencv-matrix":
            try:
                rows, cols = int(node.findtext("rows")), int(node.findtext("cols"))
                data = [float(v) for v in (node.findtext("data") or "").split()]
            except (TypeError, ValueError):
                raise CalibrationFileError(path, f"{node.tag}: an opencv-matrix needs rows, cols and data") from None
            if len(data) != rows * cols:
                raise CalibrationFileError(path, f"{node.tag}: {len(data)} values for {rows}x{cols}")
            entries[node.tag] = np.asarray(data).reshape(rows, cols)
        else:
            text = (node.text or "").split()
            try:
                entries[node.tag] = float(text[0]) if len(text) == 1 else [float(v) for v in text]
            except ValueError:
                entries[node.tag] = " ".join(text)
    return entries


def _read_opencv(path) -> dict:
    entries = _opencv_xml(path) if path.lower().endswith(".xml") else _opencv_yaml(path)
    name = os.path.splitext(os.path.basename(path))[0]
    if "image_width" in entries or "image_height" in entries:
        size = [_required(path, entries, ("image_width",), "image_width"), _required(path, entries, ("image_height",), "image_height")]
    else:
        keys = ("image_size", "imageSize", "size")
        size = next((entries[k] for k in keys if k in entries),
                    _Missing("image size: missing (looked for 'image_width' and 'image_height', " + ", ".join(map(repr, keys)) + ")"))
    return _camera(path, name, _required(path, entries, ("camera_matrix", "cameraMatrix", "K", "intrinsics"), "camera_matrix"),
                   next((entries[k] for k in ("distortion_coefficients", "distCoeffs", "dist", "D") if k in entries), None),
                   _required(path, entries, ("R", "rotation", "rvec", "rvecs", "Rot"), "rotation (R or rvec)"),
                   _required(path, entries, ("T", "t", "tvec", "tvecs", "translation"), "translation (T or tvec)"), size)


def _up_rotation(path, up: str) -> np.ndarray:
    """(3, 3) rotation taking the file's world (``up`` its up axis) to jaxtrack's Z-up world."""
    match = re.fullmatch(r"([+-]?)([xyz])", str(up).strip().lower())
    if not match:
        raise CalibrationFileError(path, f"up: {up!r} is not an axis (x, y, z, -x, -y or -z)")
    axis = np.zeros(3)
    axis[AXES[match.group(2)]] = -1.0 if match.group(1) == "-" else 1.0
    first = np.roll(np.abs(axis), 1)  # another axis of the file's world, kept horizontal
    return np.stack([first, np.cross(axis, first), axis])  # rows: new x, new y, new z (= up)


def _detect_up(cameras) -> str:
    """The signed world axis nearest the mean of the cameras' image-up directions."""
    ups = np.stack([-cam["R"][1] for cam in cameras])  # camera -y (image up) in world coordinates
    mean = ups.mean(axis=0)
    axis = int(np.argmax(np.abs(mean)))
    return ("-" if mean[axis] < 0 else "") + "xyz"[axis]


def read_calibration(paths, *, units: str | None = None, up: str | None = None, dtype=None, image_sizes=None, say=None):
    """Read a calibration (one JSON or TOML file of every camera, or one OpenCV YAML/XML file
    per camera, in order) into a ``CameraRig`` in jaxtrack's world: Z up, metres (module
    docstring; ``units`` and ``up`` None: read from a JSON file's fields or told from the cameras).
    ``image_sizes``: (width, height) per camera, in order (e.g. its video's), for the cameras
    whose file gives no image size; ``say`` is told which took it.

    Raises:
        FileNotFoundError: a file that does not exist.
        CalibrationFileError: a malformed file, naming the file and the entry.
    """
    from ..camera import make_rig

    paths = [os.fspath(paths)] if isinstance(paths, (str, os.PathLike)) else [os.fspath(p) for p in paths]
    if not paths:
        raise ValueError("read_calibration needs at least one file")
    for path in paths:
        if not os.path.isfile(path):
            raise FileNotFoundError(f"no calibration file at {path!r}")
    kinds = {os.path.splitext(p)[1].lower() for p in paths}
    file_units = file_up = None
    if kinds <= {".json", ".toml"}:
        if len(paths) != 1:
            raise ValueError("a JSON or TOML calibration holds every camera: give one file")
        if paths[0].lower().endswith(".json"):
            cameras, file_units, file_up = _read_json(paths[0])
        else:
            cameras = _read_toml(paths[0])
    elif kinds <= {".yaml", ".yml", ".xml"}:
        cameras = [_read_opencv(p) for p in paths]
    else:
        raise CalibrationFileError(", ".join(paths), "unknown calibration format (.json, .toml, or OpenCV .yaml / .yml / .xml)")
    where = paths[0] if len(paths) == 1 else ", ".join(paths)
    for i, camera in enumerate(cameras):
        if isinstance(camera["size"], _Missing):
            if image_sizes is None or i >= len(image_sizes):
                raise CalibrationFileError(paths[min(i, len(paths) - 1)], f"{camera['size'].why}; give the image size in the file "
                                           "(track --video takes it from the videos)")
            camera["size"] = np.asarray([int(v) for v in image_sizes[i]], np.int64)
            if say is not None:
                say(f"calibration: camera {camera['name']!r} gives no image size: {camera['size'][0]}x{camera['size'][1]}, "
                    "its video's")
    units = units or file_units
    if units is None:
        centres = np.stack([-cam["R"].T @ cam["t"] for cam in cameras])
        units = "mm" if np.median(np.linalg.norm(centres, axis=1)) > 50.0 else "m"
    if units not in UNITS:
        raise CalibrationFileError(where, f"units: {units!r}, expected 'm' or 'mm'")
    world = _up_rotation(where, up or file_up or _detect_up(cameras))
    names = [cam["name"] for cam in cameras]
    if len(set(names)) != len(names):
        raise CalibrationFileError(where, f"camera names repeat: {names}")
    kwargs = {} if dtype is None else {"dtype": dtype}
    return make_rig(np.stack([c["K"] for c in cameras]), np.stack([c["R"] @ world.T for c in cameras]),
                    np.stack([c["t"] * UNITS[units] for c in cameras]), np.stack([c["size"] for c in cameras]),
                    dist=np.stack([c["dist"] for c in cameras]), names=names, **kwargs)


def save_calibration(path, rig) -> str:
    """Write a ``CameraRig`` as the documented JSON (metres, Z up); returns the path."""
    cameras = [{"name": str(name), "size": [int(w), int(h)], "matrix": np.asarray(K, np.float64).tolist(),
                "distortion": np.asarray(d, np.float64).tolist(), "rotation": np.asarray(R, np.float64).tolist(),
                "translation": np.asarray(t, np.float64).tolist()}
               for name, (w, h), K, d, R, t in zip(rig.names, rig.image_size, rig.K, rig.dist, rig.R, rig.t)]
    path = os.fspath(path)
    with atomic_write(path) as handle:
        handle.write(json.dumps({"units": "m", "up": "z", "cameras": cameras}, indent=1).encode())
    return path
