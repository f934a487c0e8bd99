"""Training data as paper 003 makes it (sec. 4): 3-D motion seen from many viewpoints on the
view sphere, its projected markers converted to SPM states.

Each frame's pelvis is moved to the sphere's centre horizontally (its height kept), so the
data hold the posture as each camera sees it and not the path walked; a camera at azimuth
``a`` and elevation ``e`` looks at the centre from ``distance`` metres. The scale ``s`` of a
state is the camera's focal length over the pelvis's depth (pixels per metre), so ``d_l``
is link l's projected length over its reference length: 1 for a link of the default length
seen side-on, less when it points at the camera.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..body import HUMANEVA_JOINTS
from ..camera import CameraRig, look_at, make_rig, project_points
from ._spm import SPM_MARKERS, spm_from_markers

TRAINING_AZIMUTHS = tuple(range(0, 360, 30))  # degrees: 12 around
TRAINING_ELEVATIONS = (0, 20)  # degrees above the horizon


def view_sphere_rig(azimuths=TRAINING_AZIMUTHS, elevations=TRAINING_ELEVATIONS, *, distance: float = 4.0,
                    target_height: float = 1.2, width: int = 320, height: int = 240, focal_ratio: float = 1.2,
                    dtype=jnp.float64) -> CameraRig:
    """One camera per (azimuth, elevation) pair, degrees, each ``distance`` metres from the point
    ``(0, 0, target_height)`` and looking at it (width x height pixels, focal length
    ``focal_ratio * width``)."""
    f = focal_ratio * width
    K = np.array([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1.0]])
    target = np.array([0.0, 0.0, target_height])
    Rs, ts, names = [], [], []
    for e in elevations:
        for a in azimuths:
            ar, er = np.radians(a), np.radians(e)
            eye = target + distance * np.array([np.cos(er) * np.cos(ar), np.cos(er) * np.sin(ar), np.sin(er)])
            R, t = look_at(eye, target)
            Rs.append(R)
            ts.append(t)
            names.append(f"az{a:g}_el{e:g}")
    if not Rs:
        raise ValueError("the view sphere needs at least one azimuth and one elevation")
    C = len(Rs)
    return make_rig(np.repeat(K[None], C, 0), np.stack(Rs), np.stack(ts), [(width, height)] * C, names=names, dtype=dtype)


def centred_joints(joints3d, joint_names=HUMANEVA_JOINTS) -> np.ndarray:
    """(T, J, 3) joints with each frame's pelvis moved onto the vertical axis through the origin."""
    joints3d = np.asarray(joints3d, np.float64)
    if joints3d.ndim != 3 or joints3d.shape[-1] != 3:
        raise ValueError(f"joints3d must be (frames, joints, 3), got shape {joints3d.shape}")
    pelvis = joints3d[:, list(joint_names).index("pelvis")]
    shift = np.concatenate([pelvis[:, :2], np.zeros((len(pelvis), 1))], axis=1)
    return joints3d - shift[:, None]


def project_markers(rig: CameraRig, joints3d, joint_names=HUMANEVA_JOINTS) -> tuple[np.ndarray, np.ndarray]:
    """The SPM markers of 3-D joints in every view: ``(markers (C, T, 9, 2) pixels, scale (C, T)
    pixels per metre)``, the scale being the focal length over the pelvis's depth."""
    missing = [m for m in SPM_MARKERS if m not in joint_names]
    if missing:
        raise ValueError(f"the joints lack the SPM markers {missing}")
    points = jnp.asarray(np.asarray(joints3d)[:, [list(joint_names).index(m) for m in SPM_MARKERS]], rig.K.dtype)
    uv, depth, in_front = project_points(rig, points)  # (T, 9, C, ...)
    if not bool(jnp.all(in_front)):
        raise ValueError("a marker is behind a camera of the view sphere: move the cameras further away")
    focal = rig.K[:, 0, 0]
    scale = focal[None, :] / depth[:, 0, :]  # (T, C)
    return np.asarray(jnp.moveaxis(uv, 2, 0)), np.asarray(scale.T)


def spm_training_set(joint_sequences, rig: CameraRig | None = None, *, joint_names=HUMANEVA_JOINTS, every: int = 1) -> list[np.ndarray]:
    """003's training data: every sequence of 3-D joints ((T_i, J, 3), metres) centred
    (``centred_joints``) and seen by every camera of ``rig`` (default ``view_sphere_rig()``),
    as SPM state sequences ((T_i / every, 19) each, one per sequence and view, views inner)."""
    rig = view_sphere_rig() if rig is None else rig
    out = []
    for joints in joint_sequences:
        joints = centred_joints(joints, joint_names)[:: max(1, int(every))]
        markers, scale = project_markers(rig, joints, joint_names)
        states = np.asarray(spm_from_markers(jnp.asarray(markers), jnp.asarray(scale)))
        out.extend(states[c] for c in range(states.shape[0]))
    return out
