"""Acclaim ASF (skeleton) and AMC (motion) files, as used by the CMU motion-capture database.

Forward kinematics follows the usual AMC convention: each bone has a local frame ``C`` given
by its ``axis`` Euler angles (fixed axes, in the given order) and, per frame, a rotation
``M`` from its ``dof`` angles in the same axis order; the bone's world rotation is
``R = R_parent C M C^-1`` and its end point ``p = p_parent + length R direction``. The root
takes ``order`` channels (translation and rotation, rotation axes in the root's ``axis``
order). Lengths are in ``:units length`` units: one unit is ``0.0254 / length`` metres (inches
scaled by the file's factor), unless ``length_unit_m`` is given. AMC files do not store a
frame rate: the caller gives it (CMU: 120 Hz).
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from ._mocap import Y_UP_TO_Z_UP, MotionCapture, MotionFileError, euler_matrix, overflow_checked

_ROOT = "root"


@dataclasses.dataclass(frozen=True)
class AsfBone:
    name: str
    direction: np.ndarray  # (3,) unit vector, world axes at rest
    length: float  # file units
    axis: np.ndarray  # (3,) degrees or radians as in the file
    axis_order: str  # e.g. "XYZ"
    dofs: tuple[str, ...]  # e.g. ("rx", "ry", "rz")


@dataclasses.dataclass(frozen=True)
class AsfSkeleton:
    """A parsed ASF file."""

    path: str
    length_unit: float  # the ``:units length`` factor
    degrees: bool
    root_order: tuple[str, ...]  # e.g. ("TX", "TY", "TZ", "RX", "RY", "RZ")
    root_axis: str
    root_position: np.ndarray
    root_orientation: np.ndarray
    bones: dict[str, AsfBone]
    children: dict[str, tuple[str, ...]]

    def order(self) -> list[tuple[str, str | None]]:
        """(bone, parent) pairs, parents first (depth-first from the root)."""
        out, stack = [], [(_ROOT, None)]
        while stack:
            name, parent = stack.pop()
            out.append((name, parent))
            stack.extend((child, name) for child in reversed(self.children.get(name, ())))
        return out


def _lines(path):
    with open(path, encoding="utf-8", errors="replace") as handle:
        for number, raw in enumerate(handle, start=1):
            line = raw.split("#", 1)[0].strip()
            if line:
                yield number, line


def _floats(path, number, words, count, what):
    if len(words) != count:
        raise MotionFileError(path, number, f"{what}: expected {count} numbers, got {len(words)}")
    try:
        values = np.array([float(w) for w in words])
    except ValueError:
        raise MotionFileError(path, number, f"{what}: non-numeric value in {' '.join(words)!r}") from None
    if not np.all(np.isfinite(values)):
        raise MotionFileError(path, number, f"{what}: non-finite value in {' '.join(words)!r}")
    return values


def _need_value(path, number, words):
    if len(words) < 2:
        raise MotionFileError(path, number, f"{words[0]!r} without a value")


def read_asf(path: str | os.PathLike) -> AsfSkeleton:
    """Parse an ASF skeleton file. Raises ``MotionFileError`` with the line number."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(f"no ASF file at {path!r}")
    section = None
    length_unit, degrees = 1.0, True
    root = {"order": ("TX", "TY", "TZ", "RX", "RY", "RZ"), "axis": "XYZ", "position": np.zeros(3), "orientation": np.zeros(3)}
    bones: dict[str, AsfBone] = {}
    children: dict[str, tuple[str, ...]] = {}
    parent_line: dict[str, int] = {}  # each bone's one parent, by the line that named it
    current: dict | None = None
    current_line = 0
    in_limits = False
    for number, line in _lines(path):
        words = line.split()
        if line.startswith(":"):
            section = words[0][1:].lower()
            if len(words) > 1 and section in ("version", "name"):
                continue
            continue
        if section == "units":
            if words[0] == "length":
                length_unit = float(_floats(path, number, words[1:], 1, "units length")[0])
            elif words[0] == "angle":
                _need_value(path, number, words)
                if words[1].lower() not in ("deg", "rad"):
                    raise MotionFileError(path, number, f"units angle must be deg or rad, got {words[1]!r}")
                degrees = words[1].lower() == "deg"
        elif section == "root":
            key = words[0].lower()
            if key == "order":
                order = tuple(w.upper() for w in words[1:])
                bad = [w for w in order if w not in ("TX", "TY", "TZ", "RX", "RY", "RZ")]
                if bad:
                    raise MotionFileError(path, number, f"unknown root channel(s) {bad}")
                root["order"] = order
            elif key == "axis":
                _need_value(path, number, words)
                root["axis"] = _axis_order(path, number, words[1])
            elif key == "position":
                root["position"] = _floats(path, number, words[1:], 3, "root position")
            elif key == "orientation":
                root["orientation"] = _floats(path, number, words[1:], 3, "root orientation")
        elif section == "bonedata":
            key = words[0].lower()
            if key == "begin":
                current, current_line, in_limits = {"dofs": ()}, number, False
            elif key == "end":
                if current is None:
                    raise MotionFileError(path, number, "'end' without 'begin'")
                for required in ("name", "direction", "length", "axis"):
                    if required not in current:
                        raise MotionFileError(path, current_line, f"bone block lacks '{required}'")
                bones[current["name"]] = AsfBone(
                    current["name"], current["direction"], current["length"], current["axis"], current["axis_order"], current["dofs"]
                )
                current = None
            elif current is None:
                raise MotionFileError(path, number, f"bone data outside a begin/end block: {line!r}")
            elif key == "id":
                continue
            elif key == "name":
                _need_value(path, number, words)
                current["name"] = words[1]
            elif key == "direction":
                direction = _floats(path, number, words[1:], 3, "direction")
                largest = np.abs(direction).max()
                if not largest > 0:
                    raise MotionFileError(path, number, "direction 0 0 0: a bone needs a direction")
                direction = direction / largest  # scaled first: the norm of (1e308, 1, 0) would overflow
                current["direction"] = direction / np.linalg.norm(direction)
            elif key == "length":
                current["length"] = float(_floats(path, number, words[1:], 1, "length")[0])
                if not current["length"] > 0:
                    raise MotionFileError(path, number, f"length {current['length']:g}: a bone's length must be positive")
            elif key == "axis":
                current["axis"] = _floats(path, number, words[1:4], 3, "axis")
                if len(words) != 5:
                    raise MotionFileError(path, number, "axis: expected three angles and an order such as XYZ")
                current["axis_order"] = _axis_order(path, number, words[4])
            elif key == "dof":
                dofs = tuple(w.lower() for w in words[1:])
                bad = [d for d in dofs if d not in ("rx", "ry", "rz", "tx", "ty", "tz", "l")]
                if bad:
                    raise MotionFileError(path, number, f"unknown dof(s) {bad}")
                current["dofs"] = dofs
            elif key == "limits" or in_limits:
                in_limits = True  # limits are informative only
            elif key.startswith("("):
                continue
            else:
                raise MotionFileError(path, number, f"unknown bone keyword {words[0]!r}")
        elif section == "hierarchy":
            if words[0].lower() in ("begin", "end"):
                continue
            parent = words[0]
            if parent != _ROOT and parent not in bones:
                raise MotionFileError(path, number, f"hierarchy names unknown bone {parent!r}")
            unknown = [w for w in words[1:] if w not in bones]
            if unknown:
                raise MotionFileError(path, number, f"hierarchy names unknown bone(s) {unknown}")
            for child in words[1:]:
                if child in parent_line:
                    raise MotionFileError(path, number, f"hierarchy gives bone {child!r} a second parent (first on line "
                                                        f"{parent_line[child]}): a skeleton is a tree")
                if child == parent or child == _ROOT:
                    raise MotionFileError(path, number, f"hierarchy gives {child!r} a parent it cannot have ({parent!r})")
                parent_line[child] = number
            children[parent] = children.get(parent, ()) + tuple(words[1:])
    if current is not None:
        raise MotionFileError(path, current_line, "bone block not closed with 'end' (truncated file?)")
    if not bones:
        raise MotionFileError(path, None, "no :bonedata found")
    if _ROOT not in children:
        raise MotionFileError(path, None, "no :hierarchy entry for the root")
    reached, stack = set(), [_ROOT]
    while stack:  # each bone has one parent, so this visits every bone reachable from the root once
        name = stack.pop()
        reached.add(name)
        stack.extend(children.get(name, ()))
    detached = [b for b in parent_line if b not in reached]
    if detached:
        raise MotionFileError(path, parent_line[detached[0]], f"hierarchy bone(s) {detached} are not connected to the root "
                                                              "(a cycle?)")
    return AsfSkeleton(
        path=path,
        length_unit=length_unit,
        degrees=degrees,
        root_order=root["order"],
        root_axis=root["axis"],
        root_position=root["position"],
        root_orientation=root["orientation"],
        bones=bones,
        children=children,
    )


def _axis_order(path, number, word):
    order = word.upper()
    if sorted(order) != ["X", "Y", "Z"]:
        raise MotionFileError(path, number, f"axis order must be a permutation of XYZ, got {word!r}")
    return order


def read_amc(path: str | os.PathLike, skeleton: AsfSkeleton) -> tuple[list[str], np.ndarray]:
    """Parse an AMC motion file against its skeleton.

    Returns ``(channels, values)``: channel names ``"bone.dof"`` and a (T, channels) array in
    the ASF's units (``:units angle``); an AMC that declares the other angle unit (``:RADIANS``
    or ``:DEGREES``) has its rotations converted. Frames must be numbered consecutively.
    """
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(f"no AMC file at {path!r}")
    layout = [tuple(c.split(".", 1)) for c in amc_channels(skeleton)]
    index = {key: i for i, key in enumerate(layout)}
    sizes = {"root": len(skeleton.root_order), **{n: len(b.dofs) for n, b in skeleton.bones.items()}}
    frames: list[np.ndarray] = []
    seen: set[str] = set()
    current = None
    frame_line = 0
    radians = None  # the file's own :RADIANS / :DEGREES, if it says
    first_number = None

    def close(number):
        if current is None:
            return
        missing = [n for n, k in sizes.items() if k and n not in seen]
        if missing:
            raise MotionFileError(path, frame_line, f"frame {len(frames) + 1} lacks bone(s) {missing[:5]}")
        frames.append(current)

    for number, line in _lines(path):
        if line.startswith(":"):
            keyword = line.split()[0].upper()
            if keyword in (":RADIANS", ":DEGREES"):
                if current is not None:
                    raise MotionFileError(path, number, f"{keyword} after the first frame")
                radians = keyword == ":RADIANS"
            continue
        words = line.split()
        if len(words) == 1 and words[0].isdigit():
            close(number)
            frame_number = int(words[0])
            first_number = frame_number if first_number is None else first_number
            if frame_number != first_number + len(frames):
                raise MotionFileError(path, number, f"frame number {frame_number} where {first_number + len(frames)} was expected "
                                                    "(frames must be numbered consecutively; a repeated or missing frame?)")
            current, seen, frame_line = np.zeros(len(layout)), set(), number
            continue
        if current is None:
            raise MotionFileError(path, number, f"motion data before the first frame number: {line!r}")
        name = words[0]
        if name not in sizes:
            raise MotionFileError(path, number, f"unknown bone {name!r} (not in {os.path.basename(skeleton.path)})")
        values = _floats(path, number, words[1:], sizes[name], f"bone {name!r}")
        dofs = [d for n, d in layout if n == name]
        for dof, value in zip(dofs, values):
            current[index[(name, dof)]] = value
        seen.add(name)
    close(None)
    if not frames:
        raise MotionFileError(path, None, "no frames found")
    values = np.stack(frames)
    if radians is not None and radians == skeleton.degrees:
        # The AMC's angles are in the other unit than its ASF's: convert them to the ASF's,
        # which is what the values are read in (translations and lengths are left alone).
        rotation = np.array([d.lower().startswith("r") for _, d in layout])
        values[:, rotation] = np.degrees(values[:, rotation]) if radians else np.radians(values[:, rotation])
    return [f"{n}.{d}" for n, d in layout], values


def load_asf_amc(
    asf_path: str | os.PathLike, amc_path: str | os.PathLike, fps: float, *, length_unit_m: float | None = None
) -> MotionCapture:
    """Load a CMU-style ASF/AMC pair into world-frame joint positions (metres, Z up).

    Args:
        fps: the frame rate the AMC was recorded at (AMC files do not store it; CMU: 120).
        length_unit_m: metres per ASF length unit (default ``0.0254 / :units length``).

    Returns:
        A ``MotionCapture`` whose joints are the root and the end point of every bone.
    """
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    skeleton = read_asf(asf_path)
    _channels, values = read_amc(amc_path, skeleton)
    return motion_from_amc_values(
        skeleton, values, fps, length_unit_m=length_unit_m, source=f"{os.fspath(asf_path)} + {os.fspath(amc_path)}"
    )


def amc_channels(skeleton: AsfSkeleton) -> list[str]:
    """The AMC channel layout ``"bone.dof"``: root channels, then each bone's dofs in
    ``:bonedata`` order (also the column order of the GPmat CMU ``.mat`` files)."""
    return [f"root.{c.lower()}" for c in skeleton.root_order] + [
        f"{n}.{d}" for n, b in skeleton.bones.items() for d in b.dofs
    ]


@overflow_checked
def motion_from_amc_values(
    skeleton: AsfSkeleton, values, fps: float, *, length_unit_m: float | None = None, source: str = "amc values"
) -> MotionCapture:
    """Forward kinematics of AMC channel values (T, channels) in ``amc_channels`` order.

    Values are in file units (degrees unless the ASF says radians; lengths in ASF units).
    """
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    channels = amc_channels(skeleton)
    values = np.asarray(values, np.float64)
    if values.ndim != 2 or values.shape[1] != len(channels):
        raise ValueError(f"{source}: expected (T, {len(channels)}) AMC channel values, got {values.shape}")
    scale = length_unit_m if length_unit_m is not None else 0.0254 / skeleton.length_unit
    to_rad = np.pi / 180.0 if skeleton.degrees else 1.0
    column = {c: i for i, c in enumerate(channels)}
    T = values.shape[0]
    order = skeleton.order()
    names = [n for n, _ in order]
    parents = [names.index(p) if p is not None else -1 for _, p in order]
    world_R, world_p = {}, {}
    root_t, root_r = np.zeros((T, 3)), np.zeros((T, 3))
    for ch in skeleton.root_order:
        col = values[:, column[f"root.{ch.lower()}"]]
        if ch[0] == "T":
            root_t[:, "XYZ".index(ch[1])] = col * scale
        else:
            root_r[:, "XYZ".index(ch[1])] = col * to_rad
    root_r_ordered = np.stack([root_r[:, "XYZ".index(a)] for a in skeleton.root_axis], axis=-1)
    world_R[_ROOT] = euler_matrix(root_r_ordered, skeleton.root_axis)
    world_p[_ROOT] = root_t + skeleton.root_position * scale
    for name, parent in order[1:]:
        bone = skeleton.bones[name]
        C = euler_matrix(bone.axis * to_rad, bone.axis_order)
        angles = np.zeros((T, 3))
        for dof in bone.dofs:
            if dof[0] == "r":
                angles[:, "xyz".index(dof[1])] = values[:, column[f"{name}.{dof}"]] * to_rad
        M = euler_matrix(np.stack([angles[:, "XYZ".index(a)] for a in bone.axis_order], axis=-1), bone.axis_order)
        world_R[name] = world_R[parent] @ C @ M @ C.T
        world_p[name] = world_p[parent] + bone.length * scale * np.einsum("tij,j->ti", world_R[name], bone.direction)
    positions = np.stack([world_p[n] for n in names], axis=1) @ Y_UP_TO_Z_UP.T
    radians = values.copy()
    for i, c in enumerate(channels):
        radians[:, i] *= to_rad if c.split(".")[1][0] == "r" else scale
    return MotionCapture(
        joint_names=tuple(names),
        parents=tuple(parents),
        positions=positions,
        fps=float(fps),
        channels=tuple(tuple(c.split(".", 1)) for c in channels),
        values=radians,
        source=source,
    )
