"""One person followed in every camera: several people's detections associated across the
views by the consistency of their triangulation, and the association kept through time.

A detector finds everyone in each image. Which of them is the person to track is a question
for the cameras together: each camera's most confident detection can be a bystander, and
then the views describe different people (a body "measured" on them is a child's). As
Pose2Sim's person association does, a combination of detections is judged by how well its
triangulation reprojects onto them:

- **The people at one frame** (``find_people``). Every pair of detections in two cameras is
  triangulated (``triangulate``: the confident joints, least squares on their rays) and kept
  where both reproject within ``CONSISTENT`` of the person's size plus ``DETECTOR_PX`` (the
  error is the median over the joints, in each camera's pixels: the bound scales with the
  person, as a detector's error mostly does, above a detector's pixel floor). Each other
  camera adds its detection that reprojects best, where it is within the bound, and the
  joints are triangulated again. The people are taken
  greedily: most cameras first, then the smallest error, no detection used twice.
- **Through time** (``associate_people``). The person chosen at the first frame where anyone
  is seen by two cameras (``person``: 0, the one seen by most cameras; the list is said) is
  followed: in each later frame, of that frame's people, the one whose joints lie nearest the
  person's last ones (their centroid over the joints both hold), within the distance a
  person can cover since last seen (``MAX_SPEED``, plus ``REACH_SLACK``). Where nobody is that
  near, or no two cameras agree, the person is missing in that frame (confidence 0): one camera
  alone cannot say whom it sees, and two cameras that disagree with the others may see two
  people whose rays happen to meet (the people with more cameras are taken first).

Lens distortion is ignored here (``camera_rays``): the bound is a tenth of a person's size.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from ..camera import CameraRig
from ._start import triangulate

CONSISTENT = 0.1  # the bound on the median reprojection error: a tenth of the detection's size ...
DETECTOR_PX = 8.0  # ... plus a detector's pixel error, which does not shrink with the person (pixels)
MIN_JOINTS = 5  # confident joints two cameras must share to be triangulated together
MAX_SPEED = 3.0  # m/s: how far the person's joints may go between the frames they are seen in (a jog)
REACH_SLACK = 0.3  # metres, added to that distance (the triangulation's own error, a limb's swing)


@dataclasses.dataclass(frozen=True)
class Person:
    """One person found in several cameras at one frame.

    Attributes:
        detections: per camera, the index of the person's detection in that camera's frame, or
            None where the camera does not see them.
        joints: (15, 3) triangulated joints, metres (NaN where fewer than two cameras see one).
        error: the worst camera's median reprojection error, in units where ``CONSISTENT`` is
            the bound (pixels over the detection's size plus ``DETECTOR_PX / CONSISTENT``).
    """

    detections: tuple[int | None, ...]
    joints: np.ndarray
    error: float

    @property
    def num_cameras(self) -> int:
        return sum(d is not None for d in self.detections)

    def centre(self) -> np.ndarray:
        """(3,) the mean of the triangulated joints, metres."""
        return np.nanmean(self.joints, axis=0)


def _project(rig: CameraRig, points) -> np.ndarray:
    """(C, ..., 2) pinhole pixels of world points (..., 3) in every camera (NaN behind it)."""
    K, R, t = (np.asarray(x, np.float64) for x in (rig.K, rig.R, rig.t))
    camera = np.einsum("cij,...j->c...i", R, np.asarray(points, np.float64)) + t.reshape((len(t),) + (1,) * (np.ndim(points) - 1) + (3,))
    z = camera[..., 2:]
    pixels = np.einsum("cij,c...j->c...i", K, camera)[..., :2] / np.where(z > 0, z, np.nan)
    return pixels


def detection_size(detection) -> float:
    """A detection's size in pixels: the larger side of its confident points' box (at least 1)."""
    seen = detection[:, 2] > 0
    if seen.sum() < 2:
        return 1.0
    points = detection[seen, :2]
    return float(max(np.ptp(points[:, 0]), np.ptp(points[:, 1]), 1.0))


def _error_scale(detection) -> float:
    """Pixels per unit of the association's error: an error of ``CONSISTENT`` is a tenth of the
    detection's size plus ``DETECTOR_PX``."""
    return detection_size(detection) + DETECTOR_PX / CONSISTENT


def _error(pixels, detection, min_joints: int = 1) -> float:
    """The median distance between projected joints (15, 2) and a detection (15, 3) over the
    joints both hold, over ``_error_scale`` (inf where they share under ``min_joints``)."""
    shared = (detection[:, 2] > 0) & np.all(np.isfinite(pixels), axis=-1)
    if shared.sum() < max(min_joints, 1):
        return np.inf
    return float(np.median(np.linalg.norm(pixels[shared] - detection[shared, :2], axis=-1))) / _error_scale(detection)


def _errors(rig: CameraRig, joints, chosen) -> np.ndarray:
    """(C,) per camera with a detection in ``chosen`` ((C, 15, 3) or None rows), ``_error`` of
    ``joints`` (15, 3) projected (inf where it has none)."""
    pixels = _project(rig, joints)
    return np.array([np.inf if detection is None else _error(pixels[c], detection) for c, detection in enumerate(chosen)])


def _triangulated(rig: CameraRig, chosen) -> np.ndarray:
    """(15, 3) joints triangulated from one detection (15, 3) or None per camera (NaN where
    fewer than two cameras see a joint)."""
    pixels = np.zeros((len(chosen), 15, 2))
    weights = np.zeros((len(chosen), 15))
    for c, detection in enumerate(chosen):
        if detection is not None:
            pixels[c], weights[c] = detection[:, :2], detection[:, 2]
    points, seen = triangulate(rig, pixels, weights)
    return np.where(seen[:, None], points, np.nan)


def _person(rig: CameraRig, frame, indices) -> Person:
    chosen = [None if i is None else frame[c][i] for c, i in enumerate(indices)]
    joints = _triangulated(rig, chosen)
    errors = _errors(rig, joints, chosen)
    used = [c for c, i in enumerate(indices) if i is not None]
    return Person(tuple(indices), joints, float(np.max(errors[used])))


def _grown(rig: CameraRig, frame, person: Person) -> Person:
    """The person with every other camera's best-reprojecting detection added where it is
    within ``CONSISTENT`` (triangulated again, and kept only if every camera stays within)."""
    indices = list(person.detections)
    pixels = _project(rig, person.joints)
    for c, detections in enumerate(frame):
        if indices[c] is not None or not len(detections):
            continue
        errors = [_error(pixels[c], detection, MIN_JOINTS) for detection in detections]
        best = int(np.argmin(errors))
        indices[c] = best if errors[best] <= CONSISTENT else None
    grown = _person(rig, frame, indices)
    return grown if grown.error <= CONSISTENT else person


def find_people(rig: CameraRig, frame) -> list[Person]:
    """The people seen consistently by two cameras or more in one frame (module docstring),
    most cameras first, then the smallest error.

    Args:
        rig: the cameras (C).
        frame: per camera, the frame's detections (P_c, 15, 3): pixels u, v and confidence.
    """
    C = len(frame)
    candidates = []
    for a, b in itertools.combinations(range(C), 2):
        for i, first in enumerate(frame[a]):
            for j, second in enumerate(frame[b]):
                if ((first[:, 2] > 0) & (second[:, 2] > 0)).sum() < MIN_JOINTS:
                    continue
                indices = [None] * C
                indices[a], indices[b] = i, j
                pair = _person(rig, frame, indices)
                if pair.error <= CONSISTENT:
                    candidates.append(_grown(rig, frame, pair))
    candidates.sort(key=lambda p: (-p.num_cameras, p.error))
    people, used = [], set()
    for person in candidates:
        taken = {(c, i) for c, i in enumerate(person.detections) if i is not None}
        if not taken & used:
            people.append(person)
            used |= taken
    return people


def joint_distance(joints, other) -> float:
    """How far apart two (15, 3) triangulations are (metres): the distance between the
    centroids of the joints both hold (a mean over the joints: a detector's noise on each
    averages out, and a joint one of them lacks does not move it), inf where they share none."""
    both = np.all(np.isfinite(joints), axis=-1) & np.all(np.isfinite(other), axis=-1)
    return float(np.linalg.norm(np.mean(joints[both] - other[both], axis=0))) if both.any() else np.inf


@dataclasses.dataclass(frozen=True)
class Association:
    """What ``associate_people`` did.

    Attributes:
        keypoints: (C, T, 15, 3) the followed person's detections (confidence 0 where missing).
        people: the people found at the first frame (``find_people``), the chosen one at ``chosen``.
        first_frame: that frame.
        found_again: the frames where the person was lost and found again.
        missing: the number of frames where no camera holds the person.
    """

    keypoints: np.ndarray
    people: list[Person]
    chosen: int
    first_frame: int
    found_again: tuple[int, ...]
    missing: int


def associate_people(rig: CameraRig, people, *, fps: float, person: int = 0) -> Association:
    """One person followed through every camera's detections (module docstring).

    Args:
        rig: the cameras (C), in the detections' pixels.
        people: per camera, per frame, (P_ct, 15, 3) detections (``io.read_keypoint_people``).
        fps: the frame rate (how far a missing person may go).
        person: which of the people found at the first frame to follow (0: seen by most cameras).

    Raises:
        ValueError: cameras with different numbers of frames, nobody seen by two cameras in any
            frame, or ``person`` beyond the people found.
    """
    C = len(people)
    if C != len(rig.names):
        raise ValueError(f"{C} cameras' detections for {len(rig.names)} cameras")
    T = len(people[0])
    if any(len(p) != T for p in people):
        raise ValueError("the cameras' detections hold different numbers of frames: " + ", ".join(str(len(p)) for p in people))
    frames = [[np.asarray(people[c][t], np.float64).reshape(-1, 15, 3) for c in range(C)] for t in range(T)]
    first, found = next(((t, p) for t in range(T) if (p := find_people(rig, frames[t]))), (None, []))
    if first is None:
        raise ValueError("no person is seen consistently by two cameras in any frame (check the calibration, and that the "
                         "keypoint sources are given in the cameras' order)")
    if not 0 <= person < len(found):
        raise ValueError(f"person {person} asked for, but {len(found)} {'person was' if len(found) == 1 else 'people were'} "
                         f"found at frame {first}")
    keypoints = np.zeros((C, T, 15, 3))
    last, last_seen, again, missing = found[person].joints, first, [], first
    for t in range(first, T):
        if t == first:
            chosen = found[person]
        else:
            reach = REACH_SLACK + MAX_SPEED * (t - last_seen) / fps
            near = [(d, p) for p in find_people(rig, frames[t]) if (d := joint_distance(p.joints, last)) <= reach]
            if not near:
                missing += 1
                continue
            chosen = min(near, key=lambda pair: pair[0])[1]
            if t - last_seen > 1:
                again.append(t)
        for c, i in enumerate(chosen.detections):
            if i is not None:
                keypoints[c, t] = frames[t][c][i]
        last, last_seen = np.where(np.isfinite(chosen.joints), chosen.joints, last), t
    return Association(keypoints, found, person, first, tuple(again), missing)


def describe_people(association: Association, camera_names) -> list[str]:
    """One line per person found at the first frame: the cameras that see them, where they
    stand (x, y, metres) and which is followed."""
    lines = []
    for k, person in enumerate(association.people):
        cameras = ", ".join(str(n) for n, d in zip(camera_names, person.detections) if d is not None)
        x, y, _ = person.centre()
        mark = " (followed)" if k == association.chosen else ""
        lines.append(f"person {k}{mark}: seen by {cameras}, at x {x:.2f} m, y {y:.2f} m; reprojection error "
                     f"{100 * person.error / CONSISTENT:.0f} % of the bound")
    return lines


def associated_keypoints(rig: CameraRig, people, *, fps: float, person: int = 0, say=None) -> np.ndarray:
    """``associate_people``'s (C, T, 15, 3) keypoints of one person, with what it found said to
    ``say``: the people at the first frame, the one followed, the frames it is missing in."""
    association = associate_people(rig, people, fps=fps, person=person)
    if say is not None:
        T = association.keypoints.shape[1]
        say(f"keypoints: {len(association.people)} {'person' if len(association.people) == 1 else 'people'} seen by two "
            f"cameras or more at frame {association.first_frame}, associated across the cameras by their triangulation "
            "(--person to choose):")
        for line in describe_people(association, rig.names):
            say(f"  {line}")
        again = association.found_again
        say(f"  person {association.chosen} followed through {T - association.missing} of {T} frames"
            + (f"; missing (no two cameras agree) in {association.missing}" if association.missing else "")
            + (f"; found again at frame{'s' if len(again) > 1 else ''} {', '.join(map(str, again[:8]))}"
               + (" ..." if len(again) > 8 else "") if again else ""))
    return association.keypoints
