"""Multi-view sequence files: one ``.npz`` per sequence, readable and writable with NumPy alone.

Keys (all optional except ``fps``; ``C`` cameras, ``T`` frames, ``J`` joints, ``D`` pose numbers):

================  =====================  ===================================================
key               shape, dtype           meaning
================  =====================  ===================================================
fps               (), float              frames per second
subject           (), str                who is filmed: sequences of one subject share a body
joint_names       (J,), str              joint names, root first
parents           (J,), int              parent of each joint, -1 for the root
joints3d          (T, J, 3), float       joint positions, metres, world frame, Z up
pose              (T, D), float          jaxtrack pose vectors (``Skeleton.pose_layout``)
pose_layout       (D,), str              names of the pose entries (required with ``pose``)
skeleton_offsets  (J, 3), float          rest offsets of the subject's skeleton, metres
capsule_radii     (K,), float            radii of the subject's body capsules, metres
camera_K          (C, 3, 3), float       intrinsics, pixels
camera_R          (C, 3, 3), float       world-to-camera rotations
camera_t          (C, 3), float          world-to-camera translations, metres
camera_dist       (C, 5), float          OpenCV distortion (k1, k2, p1, p2, k3)
image_size        (C, 2), int            (width, height) in pixels
camera_names      (C,), str              camera names
silhouettes       (C, T, H, W), uint8    0/1 or 0/255 foreground masks
images            (C, T, H, W, 3), uint8 RGB frames
keypoints2d       (C, T, 15, 3), float   2-D detections of the 15 HumanEva joints per view:
                                         pixels (u, v) and a confidence in [0, 1] (0: missing);
                                         ``io.read_openpose_folder`` and ``io.read_coco_keypoints``
                                         convert what detectors write
================  =====================  ===================================================

Writing one from another tool::

    np.savez("walk.npz", fps=60.0, joints3d=joints_in_metres, joint_names=np.array(names))
"""

from __future__ import annotations

import dataclasses
import functools
import os
from collections.abc import Mapping

import numpy as np

from ..errors import SequenceFileError
from ._output import atomic_write, output_file

ARRAY_KEYS = (
    "subject",
    "joint_names",
    "parents",
    "joints3d",
    "pose",
    "pose_layout",
    "skeleton_offsets",
    "capsule_radii",
    "camera_K",
    "camera_R",
    "camera_t",
    "camera_dist",
    "image_size",
    "camera_names",
    "silhouettes",
    "images",
    "keypoints2d",
)
CAMERA_KEYS = ("camera_K", "camera_R", "camera_t", "camera_dist", "image_size", "camera_names")


def eqx_replace(module, **changes):
    """Copy an equinox module with some fields replaced."""
    import equinox as eqx

    names = list(changes)
    return eqx.tree_at(lambda m: [getattr(m, n) for n in names], module, [changes[n] for n in names])


@dataclasses.dataclass(frozen=True, eq=False)
class Sequence:
    """One multi-view sequence (see the module docstring for the keys, shapes and units).

    Construct with keyword arguments and call ``validate()`` (``load_sequence`` and
    ``save_sequence`` do), or use ``Sequence.create(...)`` which validates.
    """

    fps: float
    subject: str | None = None
    joint_names: np.ndarray | None = None
    parents: np.ndarray | None = None
    joints3d: np.ndarray | None = None
    pose: np.ndarray | None = None
    pose_layout: np.ndarray | None = None
    skeleton_offsets: np.ndarray | None = None
    capsule_radii: np.ndarray | None = None
    camera_K: np.ndarray | None = None
    camera_R: np.ndarray | None = None
    camera_t: np.ndarray | None = None
    camera_dist: np.ndarray | None = None
    image_size: np.ndarray | None = None
    camera_names: np.ndarray | None = None
    silhouettes: np.ndarray | None = None
    images: np.ndarray | None = None
    keypoints2d: np.ndarray | None = None

    @classmethod
    def create(cls, **fields) -> Sequence:
        """Build, normalise dtypes and validate; raises ``SequenceFileError`` naming the key."""
        return _normalise_and_validate(fields, source="sequence")

    def replace(self, **changes) -> Sequence:
        """A validated copy with some keys changed (``None`` removes a key)."""
        fields = {k: getattr(self, k) for k in ("fps",) + ARRAY_KEYS}
        fields.update(changes)
        return _normalise_and_validate(fields, source="sequence")

    def resized(self, width: int, height: int) -> Sequence:
        """The sequence at a lower image resolution: silhouettes block-averaged (see
        ``jaxtrack.image.downsample_silhouettes``), intrinsics rescaled with pixel centres kept
        (``CameraRig.resized``), keypoints moved with the pixels, images dropped; ``width`` and
        ``height`` must divide the size."""
        import numpy as np

        from ..image import downsample_silhouettes

        if not self.has_cameras:
            raise SequenceFileError("the sequence has no cameras to resize")
        rig = self.rig(dtype=np.float64).resized(width, height)
        silhouettes = None if self.silhouettes is None else downsample_silhouettes(self.silhouettes, width, height)
        keypoints = None
        if self.keypoints2d is not None:  # pixel centres at integer coordinates, as the intrinsics
            scale = np.asarray([width, height], np.float64) / np.asarray(self.image_size, np.float64)  # (C, 2)
            keypoints = self.keypoints2d.copy()
            moved = (keypoints[..., :2] + 0.5) * scale[:, None, None, :] - 0.5
            keypoints[..., :2] = np.where(keypoints[..., 2:] > 0, moved, keypoints[..., :2])  # missing ones stay put
        return self.replace(
            camera_K=np.asarray(rig.K), image_size=np.asarray(rig.image_size), silhouettes=silhouettes, images=None,
            keypoints2d=keypoints,
        )

    def cropped(self, frames: int) -> Sequence:
        """The first ``frames`` frames (every per-frame key cut; 1 <= frames <= num_frames)."""
        if isinstance(frames, bool) or not isinstance(frames, int) or not 1 <= frames <= self.num_frames:
            raise SequenceFileError(f"cannot crop a sequence of {self.num_frames} frames to {frames!r}")
        cut = {key: getattr(self, key)[:frames] for key in ("joints3d", "pose") if getattr(self, key) is not None}
        cut.update({key: getattr(self, key)[:, :frames] for key in ("silhouettes", "images", "keypoints2d")
                    if getattr(self, key) is not None})
        return self.replace(**cut)

    @property
    def num_frames(self) -> int:
        for key in ("joints3d", "pose"):
            value = getattr(self, key)
            if value is not None:
                return int(value.shape[0])
        for key in ("silhouettes", "images", "keypoints2d"):
            value = getattr(self, key)
            if value is not None:
                return int(value.shape[1])
        return 0

    @property
    def has_cameras(self) -> bool:
        return self.camera_K is not None

    def rig(self, dtype=None):
        """The sequence's cameras as a ``CameraRig``; raises if the file has none."""
        from ..camera import make_rig

        if not self.has_cameras:
            raise SequenceFileError("the sequence has no cameras (camera_K, camera_R, camera_t, image_size)")
        kwargs = {} if dtype is None else {"dtype": dtype}
        return make_rig(
            self.camera_K,
            self.camera_R,
            self.camera_t,
            self.image_size,
            dist=self.camera_dist,
            names=None if self.camera_names is None else [str(n) for n in self.camera_names],
            **kwargs,
        )

    def body(self, dtype=None):
        """The subject's ``BodyModel`` (HumanEva skeleton) from ``skeleton_offsets`` and
        ``capsule_radii``; defaults stand in for keys the file lacks."""
        import jax.numpy as jnp

        from ..body import HUMANEVA_JOINTS, check_joint_names, humaneva_body, with_offsets

        if self.joint_names is not None:
            check_joint_names([str(n) for n in self.joint_names], HUMANEVA_JOINTS, "sequence joint_names")
        body = humaneva_body(dtype=dtype or jnp.float32)
        if self.skeleton_offsets is not None:
            body = eqx_replace(body, skeleton=with_offsets(body.skeleton, self.skeleton_offsets))
        if self.capsule_radii is not None:
            if self.capsule_radii.shape != body.radii.shape:
                raise SequenceFileError(
                    f"key 'capsule_radii': has {self.capsule_radii.shape[0]} radii, the body has {body.num_capsules} capsules"
                )
            body = eqx_replace(body, radii=jnp.asarray(self.capsule_radii, body.radii.dtype))
        return body

    def binary_silhouettes(self) -> np.ndarray:
        """Silhouettes as float32 (C, T, H, W) in {0, 1}."""
        if self.silhouettes is None:
            raise SequenceFileError("the sequence has no silhouettes")
        sil = self.silhouettes
        return (sil > 0).astype(np.float32) if sil.max() <= 1 else (sil == 255).astype(np.float32)

    def to_dict(self) -> dict[str, np.ndarray]:
        out = {"fps": np.asarray(self.fps, np.float64)}
        for key in ARRAY_KEYS:
            value = getattr(self, key)
            if value is not None:
                out[key] = np.asarray(value) if key == "subject" else value
        return out


def load_sequence(path: str | os.PathLike) -> Sequence:
    """Read and validate a sequence file.

    Raises:
        FileNotFoundError: if the file does not exist.
        SequenceFileError: if it is not an npz archive, lacks ``fps``, has an unknown key, or a
            key with the wrong shape, dtype, units or values (the message names the key).
    """
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(f"no sequence file at {path!r}")
    if os.path.isdir(path):
        raise SequenceFileError(f"{path}: is a folder, not a sequence file")
    with open(path, "rb") as handle:
        magic = handle.read(6)
    if magic.startswith(b"\x93NUMPY"):
        raise SequenceFileError(f"{path}: is a single NumPy array (.npy), not a .npz sequence file of named keys")
    if not magic.startswith(b"PK"):
        raise SequenceFileError(f"{path}: not a .npz sequence file (an .npz is a zip archive; this file starts {magic!r})")
    try:
        with open(path, "rb") as handle, np.load(handle, allow_pickle=False) as archive:  # the handle closes on any error
            fields = {key: archive[key] for key in archive.files}
    except Exception as err:  # a corrupt archive fails in zipfile, zlib, struct or NumPy's header parser: the file's fault
        raise SequenceFileError(f"{path}: not a readable .npz sequence file ({type(err).__name__}: {err})") from err
    unknown = sorted(set(fields) - set(ARRAY_KEYS) - {"fps"})
    if unknown:
        raise SequenceFileError(f"{path}: unknown key(s) {unknown}; known keys are fps, {', '.join(ARRAY_KEYS)}")
    return _normalise_and_validate(fields, source=path)


def save_sequence(path: str | os.PathLike, sequence: Sequence | Mapping) -> str:
    """Validate and write a sequence (compressed npz) atomically (a temporary file renamed over
    the target). Writes exactly the keys that are set; ``.npz`` is appended to a name without
    it. Returns the file written."""
    if not isinstance(sequence, Sequence):
        sequence = Sequence.create(**dict(sequence))
    else:
        sequence = _normalise_and_validate(sequence.to_dict(), source="sequence")
    path = output_file(path, ".npz")
    directory = os.path.dirname(path)
    if directory:
        os.makedirs(directory, exist_ok=True)
    with atomic_write(path) as handle:
        np.savez_compressed(handle, **sequence.to_dict())
    return path


@functools.cache
def _standard_layout() -> tuple[str, ...]:
    from ..body import humaneva_skeleton

    return tuple(humaneva_skeleton().pose_layout)


MAX_BONE = 1.5  # metres: the longest human bone (the femur) is about 0.5 m
MAX_RADIUS = 1.0  # metres: a capsule radius
MAX_CAMERA_DISTANCE = 1000.0  # metres from the world's origin


def _standard_pose_order(source, pose: np.ndarray, layout: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pose columns matched to the HumanEva pose layout by name (reordered when the file names
    the same entries in another order); a layout naming other entries is refused."""
    names = [str(n) for n in layout]
    standard = _standard_layout()
    if tuple(names) == standard:
        return pose, layout
    if len(set(names)) != len(names):
        repeated = sorted({n for n in names if names.count(n) > 1})
        _fail(source, "pose_layout", f"names {repeated} more than once")
    if set(names) != set(standard):
        unknown = [n for n in names if n not in standard]
        missing = [n for n in standard if n not in names]
        _fail(source, "pose_layout", f"is not the HumanEva pose layout: unknown entries {unknown[:5]}, missing {missing[:5]} "
                                     "(retarget the motion onto the HumanEva skeleton with 'jaxtrack convert')")
    order = [names.index(n) for n in standard]
    return pose[:, order], np.array(standard)


def _fail(source, key, message):
    raise SequenceFileError(f"{source}: key {key!r}: {message}")


def _as_strings(source, key, value):
    arr = np.asarray(value)
    if arr.ndim != 1 or not (arr.dtype.kind in "UST" or (arr.dtype == object and all(isinstance(v, str) for v in arr))):
        _fail(source, key, f"must be a 1-D array of strings, got dtype {arr.dtype} and shape {arr.shape}")
    return arr.astype(str)


def _as_float(source, key, value, ndim, trailing=()):
    arr = np.asarray(value)
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        _fail(source, key, f"must hold numbers, got dtype {arr.dtype}")
    if arr.ndim != ndim or (trailing and arr.shape[ndim - len(trailing) :] != tuple(trailing)):
        want = "(" + ", ".join(["*"] * (ndim - len(trailing)) + [str(t) for t in trailing]) + ")"
        _fail(source, key, f"must have shape {want}, got {arr.shape}")
    arr = arr.astype(np.float64) if not np.issubdtype(arr.dtype, np.floating) else arr
    if not np.all(np.isfinite(arr)):
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(arr))[0])
        _fail(source, key, f"contains a non-finite value at index {bad}")
    return arr


UNIT_HEIGHTS = (("inches", 30.0, 80.0), ("centimetres", 80.0, 260.0), ("millimetres", 800.0, 2600.0))  # a person's size


def _not_metres(joints: np.ndarray) -> str:
    """Why joint positions over 100 are not metres, with the units the person's size suggests
    (the median over frames of the joints' largest extent along an axis)."""
    size = float(np.median(np.ptp(joints, axis=1).max(axis=-1))) if joints.shape[1] > 1 else float("nan")
    units = next((name for name, low, high in UNIT_HEIGHTS if low <= size <= high), None)
    reading = f"they look like {units}" if units else "a person is 1-2.2 m tall"
    return f"values up to {np.abs(joints).max():.0f} and a person {size:.3g} units tall: {reading}; store metres"


def _normalise_and_validate(fields: Mapping, source: str) -> Sequence:
    f = dict(fields)
    f = {k: v for k, v in f.items() if v is not None}
    if "fps" not in f:
        raise SequenceFileError(f"{source}: missing required key 'fps'")
    fps = np.asarray(f["fps"])
    if fps.shape != () or fps.dtype.kind not in "iuf" or not (np.isfinite(fps) and fps > 0):
        _fail(source, "fps", f"must be a positive scalar, got {fps!r}")
    out: dict = {"fps": float(fps)}
    if "subject" in f:
        subject = np.asarray(f["subject"])
        if subject.shape != () or subject.dtype.kind != "U" or not str(subject).strip():
            _fail(source, "subject", f"must be one non-empty string (who is filmed), got {subject!r}")
        out["subject"] = str(subject).strip()

    lengths: dict[str, tuple[int, str]] = {}  # dimension name -> (size, key that set it)
    # Plausibility limits (metres): a file beyond them holds another unit or corrupt numbers.

    def agree(dim, size, key):
        if dim == "frames" and size < 1:
            _fail(source, key, "has no frames (an empty sequence)")
        if dim in lengths and lengths[dim][0] != size:
            _fail(source, key, f"has {size} {dim} but {lengths[dim][1]!r} has {lengths[dim][0]}")
        lengths.setdefault(dim, (size, key))

    for key in ("joint_names", "pose_layout", "camera_names"):
        if key in f:
            out[key] = _as_strings(source, key, f[key])
    if "joint_names" in out:
        agree("joints", len(out["joint_names"]), "joint_names")
    if "parents" in f:
        parents = np.asarray(f["parents"])
        if parents.ndim != 1 or not np.issubdtype(parents.dtype, np.integer):
            _fail(source, "parents", f"must be a 1-D integer array, got dtype {parents.dtype} shape {parents.shape}")
        J = len(parents)
        if np.sum(parents == -1) != 1 or np.any(parents < -1) or np.any(parents >= J):
            _fail(source, "parents", "must hold exactly one root (-1) and indices of other joints")
        for joint in range(J):  # each joint must reach the root within J steps: no cycle
            node, steps = joint, 0
            while node != -1 and steps <= J:
                node, steps = int(parents[node]), steps + 1
            if node != -1:
                _fail(source, "parents", f"joint {joint}'s chain of parents never reaches the root (a cycle)")
        agree("joints", J, "parents")
        out["parents"] = parents.astype(np.int64)
    if "joints3d" in f:
        joints = _as_float(source, "joints3d", f["joints3d"], 3, (3,))
        if joints.size and np.abs(joints).max() > 100.0:
            _fail(source, "joints3d", _not_metres(joints))
        agree("frames", joints.shape[0], "joints3d")
        agree("joints", joints.shape[1], "joints3d")
        out["joints3d"] = joints
    if "skeleton_offsets" in f:
        offsets = _as_float(source, "skeleton_offsets", f["skeleton_offsets"], 2, (3,))
        agree("joints", offsets.shape[0], "skeleton_offsets")
        zero = np.flatnonzero(np.abs(offsets[1:]).max(axis=1) < 1e-6) + 1  # the root's offset may be zero
        if zero.size:
            _fail(source, "skeleton_offsets", f"joint(s) {zero[:5].tolist()} sit on their parent (zero offset): a bone needs a length")
        reach = np.abs(offsets).max(axis=1)  # components, not norms: no overflow on absurd values
        if reach.max() > MAX_BONE:
            _fail(source, "skeleton_offsets", f"joint {int(np.argmax(reach))} sits {reach.max():.3g} m from its parent along an "
                                              f"axis: no human bone is longer than {MAX_BONE:g} m (millimetres stored as metres?)")
        out["skeleton_offsets"] = offsets
    if "capsule_radii" in f:
        radii = _as_float(source, "capsule_radii", f["capsule_radii"], 1)
        if np.any(radii <= 0):
            _fail(source, "capsule_radii", "radii must be positive")
        if np.any(radii > MAX_RADIUS):
            _fail(source, "capsule_radii", f"a radius of {radii.max():.3g} m: no limb is thicker than {2 * MAX_RADIUS:g} m "
                                           "(millimetres stored as metres?)")
        out["capsule_radii"] = radii
    if "pose" in f:
        pose = _as_float(source, "pose", f["pose"], 2)
        if "pose_layout" not in out:
            _fail(source, "pose_layout", "is required when 'pose' is present (names of the pose entries)")
        if len(out["pose_layout"]) != pose.shape[1]:
            _fail(source, "pose", f"has {pose.shape[1]} entries per frame but pose_layout names {len(out['pose_layout'])}")
        agree("frames", pose.shape[0], "pose")
        out["pose"], out["pose_layout"] = _standard_pose_order(source, pose, out["pose_layout"])
    elif "pose_layout" in out:
        _fail(source, "pose_layout", "is present without 'pose'")

    present = [k for k in CAMERA_KEYS if k in f]
    if present:
        for required in ("camera_K", "camera_R", "camera_t", "image_size"):
            if required not in f:
                _fail(source, required, f"is required with the other camera keys {present}")
        K = _as_float(source, "camera_K", f["camera_K"], 3, (3, 3))
        R = _as_float(source, "camera_R", f["camera_R"], 3, (3, 3))
        t = _as_float(source, "camera_t", f["camera_t"], 2, (3,))
        dist = _as_float(source, "camera_dist", f["camera_dist"], 2, (5,)) if "camera_dist" in f else np.zeros((K.shape[0], 5))
        size = np.asarray(f["image_size"])
        if size.ndim != 2 or size.shape[1] != 2 or not np.issubdtype(size.dtype, np.integer) or np.any(size < 1):
            _fail(source, "image_size", f"must be a (C, 2) array of positive integers (width, height), got {size.dtype} {size.shape}")
        for key, arr in (("camera_K", K), ("camera_R", R), ("camera_t", t), ("camera_dist", dist), ("image_size", size)):
            agree("cameras", arr.shape[0], key)
        if "camera_names" in out:
            agree("cameras", len(out["camera_names"]), "camera_names")
        for c in range(K.shape[0]):
            # A rotation's entries lie in [-1, 1]: anything larger is refused before the product (1e300 overflows it).
            if np.abs(R[c]).max() > 1.0 + 1e-5 or not np.allclose(R[c] @ R[c].T, np.eye(3), atol=1e-5) or np.linalg.det(R[c]) < 0:
                _fail(source, "camera_R", f"camera {c} is not a rotation matrix")
            if K[c, 0, 0] <= 0 or K[c, 1, 1] <= 0 or not np.allclose(K[c, 2], [0, 0, 1]):
                _fail(source, "camera_K", f"camera {c} must have positive focal lengths and last row (0, 0, 1)")
        far = np.abs(t).max(axis=1)  # |camera centre| = |t| for a rotation R; components: no overflow
        if np.any(far > MAX_CAMERA_DISTANCE):
            c = int(np.argmax(far))
            _fail(source, "camera_t", f"camera {c} sits {far[c]:.3g} m from the origin along an axis: a capture volume is not "
                                      f"larger than {MAX_CAMERA_DISTANCE:g} m (millimetres stored as metres?)")
        out.update(camera_K=K, camera_R=R, camera_t=t, camera_dist=dist, image_size=size.astype(np.int64))

    for key, ndim in (("silhouettes", 4), ("images", 5)):
        if key not in f:
            continue
        arr = np.asarray(f[key])
        if arr.dtype == bool:
            arr = arr.astype(np.uint8)
        if arr.dtype != np.uint8:
            _fail(source, key, f"must be uint8, got {arr.dtype}")
        if arr.ndim != ndim or (key == "images" and arr.shape[-1] != 3):
            want = "(C, T, H, W)" if key == "silhouettes" else "(C, T, H, W, 3)"
            _fail(source, key, f"must have shape {want}, got {arr.shape}")
        if key == "silhouettes":
            values = np.unique(arr)
            if not (np.all(np.isin(values, (0, 1))) or np.all(np.isin(values, (0, 255)))):
                _fail(source, key, f"must hold 0/1 or 0/255 values, found {values[:6].tolist()}")
        agree("cameras", arr.shape[0], key)
        agree("frames", arr.shape[1], key)
        if "image_size" in out:
            for c, (w, h) in enumerate(out["image_size"]):
                if arr.shape[2:4] != (h, w):
                    _fail(source, key, f"camera {c} frames are {arr.shape[3]}x{arr.shape[2]} (width x height) but image_size says {w}x{h}")
        out[key] = arr
    if "keypoints2d" in f:
        keypoints = _as_float(source, "keypoints2d", f["keypoints2d"], 4, (15, 3))
        confidence = keypoints[..., 2]
        if np.any(confidence < 0) or np.any(confidence > 1):
            bad = tuple(int(i) for i in np.argwhere((confidence < 0) | (confidence > 1))[0])
            _fail(source, "keypoints2d", f"confidence {confidence[bad]:g} at (camera, frame, joint) {bad} is not in [0, 1]")
        agree("cameras", keypoints.shape[0], "keypoints2d")
        agree("frames", keypoints.shape[1], "keypoints2d")
        out["keypoints2d"] = keypoints.astype(np.float32)
    return Sequence(**out)
