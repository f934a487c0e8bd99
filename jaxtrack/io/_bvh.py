"""Biovision hierarchy (BVH) files.

Each joint's local transform is a translation followed by its rotation channels applied in
the order listed (``Zrotation Xrotation Yrotation`` gives ``Rz @ Rx @ Ry``). The translation
is the joint's ``OFFSET``, or, when the joint has position channels (as every joint of the
Bandai Namco files does), the channel values, which then hold the full local translation.
World positions are ``p_j = p_parent + R_parent t_j`` with ``R_j = R_parent R_local_j``.
``End Site`` blocks add no joint. Units are the file's (usually centimetres): give
``unit_m`` or let it be guessed from the skeleton's height.
"""

from __future__ import annotations

import os

import numpy as np

from ._mocap import Y_UP_TO_Z_UP, MotionCapture, MotionFileError, euler_matrix, overflow_checked

_CHANNELS = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")

MIN_FRAME_TIME = 1e-4  # seconds: 10 kHz, beyond any motion capture
MAX_FRAME_TIME = 10.0  # seconds: slower than any motion capture


def read_bvh(path: str | os.PathLike):
    """Parse a BVH file.

    Returns:
        ``(names, parents, offsets (J, 3), channels [(joint, channel)], frame_time, values
        (T, channels))`` in file units and degrees.
    """
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(f"no BVH file at {path!r}")
    with open(path, encoding="utf-8", errors="replace") as handle:
        lines = handle.read().splitlines()
    names: list[str] = []
    parents: list[int] = []
    offsets: list[np.ndarray] = []
    channels: list[tuple[str, str]] = []
    stack: list[int] = []
    pending: int | None = None  # joint whose '{' is expected next
    in_end_site = 0
    i = 0

    def fail(number, message):
        raise MotionFileError(path, number, message)

    while i < len(lines):
        number, words = i + 1, lines[i].split()
        i += 1
        if not words:
            continue
        key = words[0]
        if key == "HIERARCHY":
            continue
        if key in ("ROOT", "JOINT"):
            if len(words) < 2:
                fail(number, f"{key} without a name")
            if key == "ROOT" and names:
                fail(number, "a second ROOT (only one skeleton per file is supported)")
            if key == "JOINT" and not stack:
                fail(number, "JOINT outside the ROOT block")
            names.append(" ".join(words[1:]))
            parents.append(stack[-1] if stack else -1)
            offsets.append(np.zeros(3))
            pending = len(names) - 1
        elif key == "End":
            in_end_site = 1
        elif key == "{":
            if in_end_site == 1:
                in_end_site = 2
            elif pending is not None:
                stack.append(pending)
                pending = None
            else:
                fail(number, "unexpected '{'")
        elif key == "}":
            if in_end_site == 2:
                in_end_site = 0
            elif stack:
                stack.pop()
            else:
                fail(number, "unbalanced '}'")
        elif key == "OFFSET":
            if len(words) != 4:
                fail(number, f"OFFSET needs 3 numbers, got {len(words) - 1}")
            try:
                value = np.array([float(w) for w in words[1:]])
            except ValueError:
                fail(number, f"non-numeric OFFSET {' '.join(words[1:])!r}")
            if not np.all(np.isfinite(value)):
                fail(number, f"non-finite OFFSET {' '.join(words[1:])!r}")
            if in_end_site == 0:
                if not stack:
                    fail(number, "OFFSET outside a joint")
                offsets[stack[-1]] = value
        elif key == "CHANNELS":
            if not stack:
                fail(number, "CHANNELS outside a joint")
            try:
                count = int(words[1])
            except (IndexError, ValueError):
                fail(number, "CHANNELS needs a count")
            listed = words[2:]
            if len(listed) != count:
                fail(number, f"CHANNELS says {count} but lists {len(listed)}")
            for name in listed:
                if name not in _CHANNELS:
                    fail(number, f"unknown channel {name!r}")
                channels.append((names[stack[-1]], name))
        elif key == "MOTION":
            break
        else:
            fail(number, f"unexpected {key!r} in the hierarchy")
    else:
        raise MotionFileError(path, len(lines), "no MOTION section (truncated file?)")
    if stack or pending is not None:
        raise MotionFileError(path, i, "hierarchy not closed before MOTION")
    if not names:
        raise MotionFileError(path, i, "no joints in the hierarchy")

    def header(prefix):
        nonlocal i
        while i < len(lines) and not lines[i].strip():
            i += 1
        if i >= len(lines) or not lines[i].strip().startswith(prefix):
            raise MotionFileError(path, i + 1, f"expected '{prefix}'")
        value = lines[i].split(":", 1)[1].strip()
        i += 1
        return i, value

    number, frames_text = header("Frames:")
    try:
        num_frames = int(frames_text)
    except ValueError:
        raise MotionFileError(path, number, f"non-numeric frame count {frames_text!r}") from None
    number, time_text = header("Frame Time:")
    try:
        frame_time = float(time_text)
    except ValueError:
        raise MotionFileError(path, number, f"non-numeric frame time {time_text!r}") from None
    if not MIN_FRAME_TIME <= frame_time <= MAX_FRAME_TIME:  # also NaN and inf
        raise MotionFileError(path, number, f"Frame Time {time_text}: must be a number of seconds between {MIN_FRAME_TIME:g} "
                                            f"({1 / MIN_FRAME_TIME:g} Hz) and {MAX_FRAME_TIME:g}")
    values = []
    for k in range(i, len(lines)):
        words = lines[k].split()
        if not words:
            continue
        if len(words) != len(channels):
            raise MotionFileError(path, k + 1, f"frame has {len(words)} values, the hierarchy declares {len(channels)} channels")
        try:
            row = [float(w) for w in words]
        except ValueError:
            bad = next(w for w in words if not _is_float(w))
            raise MotionFileError(path, k + 1, f"non-numeric value {bad!r}") from None
        if not np.all(np.isfinite(row)):
            bad = next(w for w, v in zip(words, row) if not np.isfinite(v))
            raise MotionFileError(path, k + 1, f"non-finite value {bad!r} (channel {int(np.argmin(np.isfinite(row))) + 1})")
        values.append(row)
    if len(values) != num_frames:
        raise MotionFileError(path, len(lines), f"header says {num_frames} frames, found {len(values)} (truncated file?)")
    return names, parents, np.stack(offsets), channels, frame_time, np.array(values).reshape(num_frames, len(channels))


def _is_float(word):
    try:
        float(word)
        return True
    except ValueError:
        return False


@overflow_checked
def load_bvh(path: str | os.PathLike, *, unit_m: float | None = None, y_up: bool = True) -> MotionCapture:
    """Load a BVH file into world-frame joint positions (metres, Z up).

    Args:
        unit_m: metres per file unit; if omitted, centimetres are assumed when the rest
            skeleton is taller than 3 units, metres otherwise.
        y_up: the file's up axis is Y (the BVH custom); set False for Z-up files.
    """
    path = os.fspath(path)
    names, parents, offsets, channels, frame_time, values = read_bvh(path)
    if unit_m is None:
        unit_m = 0.01 if _rest_height(parents, offsets) > 3.0 else 1.0
    T, J = values.shape[0], len(names)
    translations = np.broadcast_to(offsets, (T, J, 3)).copy()
    rotations = np.broadcast_to(np.eye(3), (T, J, 3, 3)).copy()
    per_joint: dict[int, list[tuple[str, int]]] = {}
    for column, (joint, channel) in enumerate(channels):
        per_joint.setdefault(names.index(joint), []).append((channel, column))
    for j, listed in per_joint.items():
        position = [(ch, col) for ch, col in listed if ch.endswith("position")]
        for ch, col in position:
            translations[:, j, "XYZ".index(ch[0])] = values[:, col]
        rotation = [(ch, col) for ch, col in listed if ch.endswith("rotation")]
        if rotation:
            order = "".join(ch[0] for ch, _ in rotation)
            angles = np.radians(np.stack([values[:, col] for _, col in rotation], axis=-1))
            # Intrinsic rotations in the listed order == fixed axes in the reverse order.
            rotations[:, j] = euler_matrix(angles[:, ::-1], order[::-1])
    world_R = np.zeros_like(rotations)
    world_p = np.zeros_like(translations)
    for j, parent in enumerate(parents):
        if parent < 0:
            world_R[:, j] = rotations[:, j]
            world_p[:, j] = translations[:, j]
        else:
            world_R[:, j] = world_R[:, parent] @ rotations[:, j]
            world_p[:, j] = world_p[:, parent] + np.einsum("tij,tj->ti", world_R[:, parent], translations[:, j])
    positions = world_p * unit_m
    if y_up:
        positions = positions @ Y_UP_TO_Z_UP.T
    converted = values.copy()
    for column, (_, channel) in enumerate(channels):
        converted[:, column] = np.radians(values[:, column]) if channel.endswith("rotation") else values[:, column] * unit_m
    return MotionCapture(
        joint_names=tuple(names),
        parents=tuple(parents),
        positions=positions,
        fps=1.0 / frame_time,
        channels=tuple(channels),
        values=converted,
        source=path,
    )


def _rest_height(parents, offsets):
    positions = np.zeros_like(offsets)
    for j, parent in enumerate(parents):
        positions[j] = offsets[j] + (positions[parent] if parent >= 0 else 0.0)
    return float(np.ptp(positions, axis=0).max())
