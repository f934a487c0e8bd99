"""2-D keypoints as pose detectors write them, mapped onto the library's 15 HumanEva joints.

Layouts (``KEYPOINT_LAYOUTS``), each with its joint correspondence stated per HumanEva joint:

- ``coco17`` (COCO, MMPose, RTMPose): nose, eyes, ears, shoulders, elbows, wrists, hips,
  knees, ankles, left before right;
- ``coco18`` (OpenPose's COCO model): nose, neck, then right before left;
- ``body25`` (OpenPose BODY_25): ``coco18``'s first 8 with a mid-hip at 8, then the legs, the
  face and six foot points;
- ``body25b`` (OpenPose BODY_25B): ``coco17``, then upper neck, head top and six foot points;
- ``halpe26`` (AlphaPose Halpe): ``coco17``, then head (top), neck, hip (mid) and six foot points.

Shoulders, elbows, wrists, hips, knees and ankles are the detectors' own points. The pelvis is
the detector's mid-hip where it has one, else the mean of its two hips (exact for our
skeleton, whose pelvis is the hips' midpoint). The thorax is the neck point (``coco18``,
``body25``, ``halpe26``; ``body25b``'s upper neck is higher, so its shoulders' mean) or the
shoulders' mean (``coco17``): the HumanEva thorax sits between the shoulders. The head is the
mean of the two ears (every layout has them; the head joint is the head's centre). These last
two are approximate (``KeypointLayout.approximate``): a likelihood should trust them less.

Readers: ``read_openpose_folder`` (one JSON file per frame, ``people[i].pose_keypoints_2d``
as OpenPose writes; several people per frame: the one the tracker follows, see
``follow_person``), ``read_coco_keypoints`` (a COCO results or annotations JSON, several images
in frame order), and ``load_keypoints`` / ``save_keypoints`` (a documented ``.npz``:
``keypoints`` (C, T, 15, 3) pixel u, v and confidence in [0, 1], ``camera_names`` (C,)). A
missing joint has confidence 0.
"""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np

from ..body import HUMANEVA_JOINTS
from ..errors import MotionFileError

_COCO17 = ("nose", "leye", "reye", "lear", "rear", "lshoulder", "rshoulder", "lelbow", "relbow", "lwrist", "rwrist",
           "lhip", "rhip", "lknee", "rknee", "lankle", "rankle")
_COCO18 = ("nose", "neck", "rshoulder", "relbow", "rwrist", "lshoulder", "lelbow", "lwrist", "rhip", "rknee", "rankle",
           "lhip", "lknee", "lankle", "reye", "leye", "rear", "lear")
_BODY25 = ("nose", "neck", "rshoulder", "relbow", "rwrist", "lshoulder", "lelbow", "lwrist", "midhip", "rhip", "rknee",
           "rankle", "lhip", "lknee", "lankle", "reye", "leye", "rear", "lear", "lbigtoe", "lsmalltoe", "lheel", "rbigtoe",
           "rsmalltoe", "rheel")
_BODY25B = _COCO17 + ("upperneck", "headtop", "lbigtoe", "lsmalltoe", "lheel", "rbigtoe", "rsmalltoe", "rheel")
_HALPE26 = _COCO17 + ("headtop", "neck", "midhip", "lbigtoe", "rbigtoe", "lsmalltoe", "rsmalltoe", "lheel", "rheel")

# HumanEva joint -> the detector points whose mean it is, in order of preference (the first
# rule whose points the layout has wins).
_RULES = {
    "pelvis": (("midhip",), ("lhip", "rhip")),
    "thorax": (("neck",), ("lshoulder", "rshoulder")),
    "head": (("lear", "rear"),),
}
APPROXIMATE_JOINTS = ("thorax", "head")  # not a point any detector marks: see the module docstring


@dataclasses.dataclass(frozen=True)
class KeypointLayout:
    """A detector's keypoint layout and its correspondence to the 15 HumanEva joints.

    Attributes:
        name: the layout's name (``KEYPOINT_LAYOUTS`` key).
        names: (K,) the detector's points in its order.
        sources: per HumanEva joint (``body.HUMANEVA_JOINTS`` order), the indices of the points
            whose mean it is.
        approximate: per HumanEva joint, whether the correspondence is approximate.
    """

    name: str
    names: tuple[str, ...]
    sources: tuple[tuple[int, ...], ...]
    approximate: tuple[bool, ...]

    @property
    def num_points(self) -> int:
        return len(self.names)

    def to_humaneva(self, keypoints: np.ndarray) -> np.ndarray:
        """(..., K, 3) detector points (u, v, confidence) -> (..., 15, 3) HumanEva joints: the
        mean position of each joint's points, confidence the least of theirs (0 if any is
        missing, and then the position 0)."""
        keypoints = np.asarray(keypoints, np.float64)
        if keypoints.shape[-2:] != (self.num_points, 3):
            raise ValueError(f"{self.name} keypoints must be (..., {self.num_points}, 3), got {keypoints.shape}")
        out = np.zeros(keypoints.shape[:-2] + (len(self.sources), 3))
        for j, points in enumerate(self.sources):
            chosen = keypoints[..., points, :]
            confidence = np.min(chosen[..., 2], axis=-1)
            out[..., j, :2] = np.where(confidence[..., None] > 0, np.mean(chosen[..., :2], axis=-2), 0.0)
            out[..., j, 2] = confidence
        return out


def _layout(name: str, names: tuple[str, ...]) -> KeypointLayout:
    index = {n: i for i, n in enumerate(names)}
    sources = []
    for joint in HUMANEVA_JOINTS:
        rules = _RULES.get(joint, ((joint,),))
        rule = next(r for r in rules if all(n in index for n in r))
        sources.append(tuple(index[n] for n in rule))
    if name == "body25b":  # its upper neck sits above the thorax: the shoulders' mean instead
        sources[HUMANEVA_JOINTS.index("thorax")] = (index["lshoulder"], index["rshoulder"])
    return KeypointLayout(name, names, tuple(sources), tuple(j in APPROXIMATE_JOINTS for j in HUMANEVA_JOINTS))


KEYPOINT_LAYOUTS: dict[str, KeypointLayout] = {
    name: _layout(name, names)
    for name, names in (("coco17", _COCO17), ("coco18", _COCO18), ("body25", _BODY25), ("body25b", _BODY25B),
                        ("halpe26", _HALPE26))
}


def get_keypoint_layout(name: str) -> KeypointLayout:
    """The layout named ``name``; raises ``ValueError`` listing the known ones."""
    if name not in KEYPOINT_LAYOUTS:
        raise ValueError(f"unknown keypoint layout {name!r}; known: {', '.join(KEYPOINT_LAYOUTS)}")
    return KEYPOINT_LAYOUTS[name]


def follow_person(frames: list[np.ndarray]) -> np.ndarray:
    """One person per frame from each frame's (P_t, K, 3) detections: at the first frame with
    anyone, the most confident (mean confidence); then the one whose confident points are
    nearest (mean pixel distance) to the last chosen; a frame with nobody gives zeros
    (confidence 0). Returns (T, K, 3)."""
    sizes = [f.shape[1] for f in frames if f.shape[0]]
    if not sizes:
        raise ValueError("no person is detected in any frame")
    out = np.zeros((len(frames), sizes[0], 3))
    last = None
    for t, people in enumerate(frames):
        if not people.shape[0]:
            continue
        if last is None:
            choice = int(np.argmax(people[:, :, 2].mean(axis=1)))
        else:
            both = (people[:, :, 2] > 0) & (last[None, :, 2] > 0)
            distance = np.linalg.norm(people[:, :, :2] - last[None, :, :2], axis=-1)
            mean = np.where(both.any(axis=1), np.sum(np.where(both, distance, 0.0), axis=1) / np.maximum(both.sum(axis=1), 1), np.inf)
            choice = int(np.argmin(mean)) if np.isfinite(mean).any() else int(np.argmax(people[:, :, 2].mean(axis=1)))
        out[t] = people[choice]
        last = out[t]
    return out


def _points(values, count: int | None, where: str, line_of: str) -> np.ndarray:
    """One person's (K, 3) points from a flat list of u, v, confidence; ``count`` None: any
    whole number of points."""
    array = np.asarray(values, np.float64).reshape(-1) if isinstance(values, list) else None
    if array is None or array.size % 3 or (count is not None and array.size != 3 * count):
        wanted = "u, v, confidence per point" if count is None else f"{3 * count} numbers (u, v, confidence for {count} points)"
        got = array.size if array is not None else type(values).__name__
        raise MotionFileError(where, None, f"{line_of}: expected {wanted}, got {got}")
    if not np.all(np.isfinite(array)):
        raise MotionFileError(where, None, f"{line_of}: NaN or infinite values")
    return array.reshape(-1, 3)


def _read_json(path: str):
    """A JSON file's contents; ``MotionFileError`` with the line where it is not JSON."""
    try:
        with open(path) as handle:
            return json.load(handle)
    except json.JSONDecodeError as err:
        raise MotionFileError(path, err.lineno, f"not JSON: {err.msg}") from None


# Layouts by their number of points; BODY_25 and BODY_25B share 25 (``detect_layout``).
LAYOUTS_BY_POINT_COUNT = {17: ("coco17",), 18: ("coco18",), 25: ("body25", "body25b"), 26: ("halpe26",)}
HEAD_SPREAD_LIMIT = 0.15  # BODY_25B's points 0-4 (nose, eyes, ears) span under this fraction of the person's height
MIN_LAYOUT_FRAMES = 5  # confident detections needed to tell BODY_25 from BODY_25B


def head_spread(people: np.ndarray, *, min_confidence: float = 0.3) -> np.ndarray:
    """(P,) how far apart points 0-4 lie (their bounding box's diagonal) over the person's height
    (the vertical extent of their confident points), for detections (P, K, 3) whose points 0-4
    and at least 8 points in all are confident; NaN otherwise. BODY_25B puts the nose, eyes and
    ears there (a head: about 0.05-0.1 of the height), BODY_25 the nose, neck, right shoulder,
    elbow and wrist (an arm: 0.25 and more)."""
    people = np.asarray(people, np.float64)
    confident = people[..., 2] >= min_confidence
    usable = confident[:, :5].all(axis=1) & (confident.sum(axis=1) >= 8)
    head = people[:, :5, :2]
    diagonal = np.linalg.norm(head.max(axis=1) - head.min(axis=1), axis=-1)
    v = people[..., 1]
    height = np.where(confident, v, -np.inf).max(axis=1) - np.where(confident, v, np.inf).min(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(usable & (height > 0), diagonal / height, np.nan)


def detect_layout(frames: list[np.ndarray], where: str) -> tuple[str, str]:
    """The keypoint layout of a detector's frames (each (P_t, K, 3)), told from K, and for K = 25
    (BODY_25 or BODY_25B) from the data (``head_spread``, median over the confident detections).
    Returns ``(layout, why)``; raises ``MotionFileError`` when K names no layout, or 25 points
    cannot be told apart, naming the candidates and ``--keypoint-layout``."""
    counts = {f.shape[1] for f in frames if f.shape[0]}
    if not counts:
        raise MotionFileError(where, None, "no person is detected in any frame")
    if len(counts) > 1:
        raise MotionFileError(where, None, f"detections of different point counts {sorted(counts)} (one detector's output has one)")
    count = counts.pop()
    candidates = LAYOUTS_BY_POINT_COUNT.get(count)
    if candidates is None:
        known = ", ".join(f"{' or '.join(names)} {k}" for k, names in LAYOUTS_BY_POINT_COUNT.items())
        raise MotionFileError(where, None, f"{count} points per person is no known layout (points per person: {known})")
    if len(candidates) == 1:
        return candidates[0], f"{count} points"
    spreads = np.concatenate([head_spread(f) for f in frames if f.shape[0]])
    spreads = spreads[np.isfinite(spreads)]
    if spreads.size < MIN_LAYOUT_FRAMES:
        raise MotionFileError(where, None, f"{count} points per person: {' or '.join(candidates)}, and only {spreads.size} "
                                           f"confident detections to tell them apart (need {MIN_LAYOUT_FRAMES}); give "
                                           f"--keypoint-layout {' or '.join(candidates)}")
    spread = float(np.median(spreads))
    layout = "body25b" if spread < HEAD_SPREAD_LIMIT else "body25"
    part = "the head's (nose, eyes, ears)" if layout == "body25b" else "an arm's (nose, neck, right shoulder, elbow, wrist)"
    return layout, (f"{count} points, told from the data: points 0-4 span {100 * spread:.0f} % of the person's height "
                    f"(median over {spreads.size} detections), {part}")


def _openpose_people(folder: str, count: int | None) -> list[np.ndarray]:
    """Per frame file (sorted by name), every detected person's (K, 3) points stacked (P_t, K, 3).
    A person entry with an empty ``pose_keypoints_2d`` (OpenPose writes these) is a person not
    detected: left out. ``count``: the points per person (None: the first person's)."""
    names = sorted(n for n in os.listdir(folder) if n.endswith(".json"))
    if not names:
        raise MotionFileError(folder, None, "no .json keypoint files in the folder")
    frames = []
    for name in names:
        path = os.path.join(folder, name)
        data = _read_json(path)
        people = data.get("people") if isinstance(data, dict) else None
        if not isinstance(people, list):
            raise MotionFileError(path, None, "no 'people' list (an OpenPose keypoint file has one per frame)")
        found = []
        for i, person in enumerate(people):
            values = person.get("pose_keypoints_2d") if isinstance(person, dict) else None
            if isinstance(values, list) and not values:
                continue  # not detected
            found.append(_points(values, count, path, f"people[{i}].pose_keypoints_2d"))
            count = found[-1].shape[0]
        frames.append(np.stack(found) if found else None)
    return [np.zeros((0, count or 0, 3)) if f is None else f for f in frames]


def _humaneva_people(frames: list[np.ndarray], layout: str | None, where: str, say) -> list[np.ndarray]:
    """Each frame's (P_t, 15, 3) HumanEva joints from a reader's frames (each (P_t, K, 3), K the
    layout's when it was given), the layout told from them when not given (``detect_layout``,
    said)."""
    if layout is None:
        layout, why = detect_layout(frames, where)
        if say is not None:
            say(f"{where}: keypoint layout {layout} ({why})")
    layout_ = get_keypoint_layout(layout)
    return [layout_.to_humaneva(f if f.shape[0] else np.zeros((0, layout_.num_points, 3))) for f in frames]


def read_openpose_people(folder: str | os.PathLike, layout: str | None = None, *, say=None) -> list[np.ndarray]:
    """One camera's OpenPose output (one ``*_keypoints.json`` per frame, sorted by name) ->
    every person detected in each frame, (P_t, 15, 3) HumanEva joints in pixels with
    confidences. ``layout`` None: told from the data (``detect_layout``; ``say`` is given the
    choice and why). An empty person entry is a person not detected: left out."""
    folder = os.fspath(folder)
    frames = _openpose_people(folder, None if layout is None else get_keypoint_layout(layout).num_points)
    return _humaneva_people(frames, layout, folder, say)


def read_openpose_folder(folder: str | os.PathLike, layout: str | None = None, *, say=None) -> np.ndarray:
    """``read_openpose_people`` with one person followed through the frames (``follow_person``):
    (T, 15, 3). A frame with nobody, or only empty person entries, has every joint missing
    (confidence 0)."""
    return follow_person(read_openpose_people(folder, layout, say=say))


def read_coco_people(path: str | os.PathLike, layout: str | None = None, *, images=None, say=None) -> list[np.ndarray]:
    """A COCO keypoint JSON (a results list, or a dict with ``annotations`` and ``images``) of
    one camera -> every person detected in each frame, (P_t, 15, 3): frames are the image ids in
    ascending order (or ``images``, ids in frame order); a detection's ``score`` scales its
    points' visibilities (COCO's v in {0, 1, 2} reads as 0, 0.5, 1). ``layout`` None: told
    from the data (``detect_layout``)."""
    path = os.fspath(path)
    data = _read_json(path)
    annotations = data.get("annotations") if isinstance(data, dict) else data
    if not isinstance(annotations, list):
        raise MotionFileError(path, None, "expected a list of detections or a dict with 'annotations'")
    by_image: dict = {}
    count = None if layout is None else get_keypoint_layout(layout).num_points
    for i, item in enumerate(annotations):
        if not isinstance(item, dict) or "image_id" not in item:
            raise MotionFileError(path, None, f"detection {i}: needs 'image_id' and 'keypoints'")
        points = _points(item.get("keypoints"), count, path, f"detection {i} keypoints")
        count = points.shape[0]
        visible = points[:, 2]
        if "score" not in item:  # annotations: visibility flags 0, 1, 2
            visible = visible / 2.0
        points[:, 2] = np.clip(visible * float(item.get("score", 1.0)), 0.0, 1.0)
        by_image.setdefault(item["image_id"], []).append(points)
    order = list(images) if images is not None else sorted(by_image)
    frames = [np.stack(by_image[i]) if i in by_image else np.zeros((0, count or 0, 3)) for i in order]
    return _humaneva_people(frames, layout, path, say)


def read_coco_keypoints(path: str | os.PathLike, layout: str | None = None, *, images=None, say=None) -> np.ndarray:
    """``read_coco_people`` with one person followed through the frames (``follow_person``):
    (T, 15, 3)."""
    return follow_person(read_coco_people(path, layout, images=images, say=say))


def save_keypoints(path: str | os.PathLike, keypoints, camera_names) -> None:
    """Write (C, T, 15, 3) HumanEva keypoints (pixels u, v and confidence) with the cameras'
    names as the documented ``.npz``."""
    keypoints = check_keypoints(keypoints, len(camera_names), where=os.fspath(path))
    np.savez(path, keypoints=keypoints, camera_names=np.asarray([str(n) for n in camera_names]))


def load_keypoints(path: str | os.PathLike) -> tuple[np.ndarray, tuple[str, ...]]:
    """Read a keypoint ``.npz`` (``save_keypoints``): ``(keypoints (C, T, 15, 3), camera names)``."""
    where = os.fspath(path)
    with np.load(path, allow_pickle=False) as data:
        missing = [k for k in ("keypoints", "camera_names") if k not in data]
        if missing:
            raise MotionFileError(where, None, f"missing key(s) {', '.join(missing)} (a keypoint file has keypoints and camera_names)")
        names = tuple(str(n) for n in data["camera_names"])
        return check_keypoints(data["keypoints"], len(names), where=where), names


def check_keypoints(keypoints, num_views: int, *, where: str = "keypoints") -> np.ndarray:
    """(C, T, 15, 3) finite float64 keypoints with confidences in [0, 1]; raises
    ``MotionFileError`` naming ``where`` otherwise."""
    array = np.asarray(keypoints, np.float64)
    if array.ndim != 4 or array.shape[0] != num_views or array.shape[2:] != (len(HUMANEVA_JOINTS), 3):
        raise MotionFileError(where, None, f"keypoints must be (views={num_views}, frames, {len(HUMANEVA_JOINTS)}, 3), got "
                                           f"{array.shape}")
    if not np.all(np.isfinite(array)):
        raise MotionFileError(where, None, "keypoints contain NaN or infinite values")
    if np.any(array[..., 2] < 0) or np.any(array[..., 2] > 1):
        raise MotionFileError(where, None, "keypoint confidences must lie in [0, 1]")
    return array


KEYPOINT_FORMATS = ("npz", "openpose", "coco")
_FORMAT_TOLD = {"openpose": "folders of per-frame JSON: OpenPose", "coco": "a .json file: COCO", "npz": "an .npz: jaxtrack's keypoint file"}


def keypoint_format_of(sources) -> str:
    """The keypoint format told from what is given: a folder (of per-frame ``.json``) is
    OpenPose, a ``.json`` file COCO, an ``.npz`` this library's file. Raises ``ValueError``
    naming a source that is none of these, or sources of different kinds."""
    kinds = {}
    for source in (os.fspath(s) for s in sources):
        if os.path.isdir(source):
            kinds[source] = "openpose"
        elif source.lower().endswith(".json"):
            kinds[source] = "coco"
        elif source.lower().endswith(".npz"):
            kinds[source] = "npz"
        elif not os.path.exists(source):
            raise ValueError(f"{source}: no such keypoint file or folder")
        else:
            raise ValueError(f"{source}: not a keypoint source (an OpenPose folder of per-frame .json, a COCO .json or a "
                             "keypoint .npz)")
    found = set(kinds.values())
    if len(found) > 1:
        raise ValueError("keypoint sources of different formats: " + ", ".join(f"{s} ({k})" for s, k in kinds.items()))
    return found.pop()


def read_keypoint_sources(sources, file_format: str | None = None, *, layout: str | None = None, camera_names=None,
                          say=None) -> np.ndarray:
    """(C, T, 15, 3) HumanEva keypoints from a detector's files: one documented ``.npz`` holding
    every camera (``file_format="npz"``; its camera names must equal ``camera_names`` when
    given), or one source per camera in the cameras' order: an OpenPose folder of per-frame
    JSON files (``"openpose"``) or a COCO keypoint JSON (``"coco"``), one person followed in
    each (``follow_person``; ``tracking.associate_people`` follows one across the cameras).
    ``file_format`` None: told from the sources (``keypoint_format_of``); ``layout`` None: told
    from the data (``detect_layout``). ``say`` is given what was told and why.

    Raises:
        ValueError: on an unknown format, a count of sources that does not match the cameras,
            or cameras whose sources hold different numbers of frames.
    """
    people, file_format = read_keypoint_people(sources, file_format, layout=layout, camera_names=camera_names, say=say)
    if file_format == "npz":
        return people
    return np.stack([follow_person(frames) for frames in people])


def read_keypoint_people(sources, file_format: str | None = None, *, layout: str | None = None, camera_names=None,
                         say=None):
    """Every person each camera's detector found: ``(people, file_format)``, ``people`` a list
    per camera of (P_t, 15, 3) arrays per frame for OpenPose folders and COCO files, the
    (C, T, 15, 3) array itself for an ``.npz`` (one person). Arguments and errors as
    ``read_keypoint_sources``'s."""
    sources = [os.fspath(s) for s in sources]
    if file_format is None:
        file_format = keypoint_format_of(sources)
        if say is not None:
            say(f"keypoints: {_FORMAT_TOLD[file_format]} (told from what was given; --keypoint-format to say otherwise)")
    if file_format not in KEYPOINT_FORMATS:
        raise ValueError(f"keypoint format must be one of {KEYPOINT_FORMATS}, got {file_format!r}")
    names = None if camera_names is None else [str(n) for n in camera_names]
    if file_format == "npz":
        if len(sources) != 1:
            raise ValueError(f"the npz keypoint format is one file holding every camera's keypoints, got {len(sources)} files")
        keypoints, found = load_keypoints(sources[0])
        if names is not None and list(found) != names:
            raise ValueError(f"{sources[0]}: keypoints of cameras {list(found)}, but the cameras are {names}")
        return keypoints, file_format
    if names is not None and len(sources) != len(names):
        raise ValueError(f"{len(names)} cameras: give one {file_format} keypoint source per camera, in their order "
                         f"(got {len(sources)})")
    read = read_openpose_people if file_format == "openpose" else read_coco_people
    per_view = [read(source, layout, say=say) for source in sources]
    if len({len(k) for k in per_view}) != 1:
        raise ValueError("the cameras' keypoint sources hold different numbers of frames: "
                         + ", ".join(f"{s} {len(k)}" for s, k in zip(sources, per_view)))
    return per_view, file_format
