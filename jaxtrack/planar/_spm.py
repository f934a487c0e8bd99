"""The scaled prismatic model (SPM) of the upper body, paper 003 sec. 4 (after Cham and Rehg):
a 2-D kinematic chain in the image plane whose links each rotate in the plane and stretch
along their own axis (the prismatic joint absorbs foreshortening).

Markers are the library's joint names ``SPM_MARKERS`` (pelvis = 003's "base of spine", thorax
= its "neck"); links run between them as ``SPM_LINKS``. A state (``SPM_STATE_DIM`` = 19
numbers, 003's 25 less its hand links) is

    [tx, ty, log s, theta_0 .. theta_7, d_0 .. d_7]

with the pelvis at (tx, ty) pixels, ``s`` pixels per metre, ``theta_l`` link l's angle
relative to its parent link (the spine's relative to the image's up direction, radians) and
``d_l`` its length as a fraction of its 3-D reference length ``SPM_REFERENCE_LENGTHS[l]``
(the default skeleton's, metres): link l ends at its start plus
``s * L_l * d_l * (cos phi_l, sin phi_l)``, ``phi_l`` the sum of the angles up the chain.

The manifold learns the pose part in the wrap-free form ``spm_features``: per link the
relative link vector ``d_l (cos theta_l, sin theta_l)`` (16 numbers; a link seen end-on is
the origin, not a jump in angle).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ..body import HUMANEVA_JOINTS, humaneva_offsets

SPM_MARKERS = ("pelvis", "thorax", "head", "lshoulder", "lelbow", "lwrist", "rshoulder", "relbow", "rwrist")
SPM_LINKS = (  # (name, parent link or -1, start marker, end marker)
    ("spine", -1, "pelvis", "thorax"),
    ("neck", 0, "thorax", "head"),
    ("lclavicle", 0, "thorax", "lshoulder"),
    ("lupper_arm", 2, "lshoulder", "lelbow"),
    ("lforearm", 3, "lelbow", "lwrist"),
    ("rclavicle", 0, "thorax", "rshoulder"),
    ("rupper_arm", 5, "rshoulder", "relbow"),
    ("rforearm", 6, "relbow", "rwrist"),
)
NUM_LINKS = len(SPM_LINKS)
SPM_STATE_DIM = 3 + 2 * NUM_LINKS
SPM_FEATURE_DIM = 2 * NUM_LINKS
_PARENTS = tuple(parent for _, parent, _, _ in SPM_LINKS)
_STARTS = tuple(SPM_MARKERS.index(start) for _, _, start, _ in SPM_LINKS)
_ENDS = tuple(SPM_MARKERS.index(end) for _, _, _, end in SPM_LINKS)
SPM_REFERENCE_LENGTHS = tuple(
    float(np.linalg.norm(humaneva_offsets()[HUMANEVA_JOINTS.index(end)])) for _, _, _, end in SPM_LINKS
)
"""Each link's 3-D length on the default skeleton, metres (spine 0.50, neck 0.22, ...)."""
_UP = -np.pi / 2  # the image's up direction (v grows downwards)
SPINE_TO_NECK = (0, 1)  # marker indices of 003's "base of spine" and "neck"


def _wrap(angle):
    return jnp.mod(angle + jnp.pi, 2 * jnp.pi) - jnp.pi


def spm_forward(state: Float[Array, "*batch 19"]) -> Float[Array, "*batch 9 2"]:
    """Marker positions (pixels, ``SPM_MARKERS`` order) of SPM states (module docstring)."""
    state = jnp.asarray(state)
    lengths = jnp.asarray(SPM_REFERENCE_LENGTHS, state.dtype)
    scale = jnp.exp(state[..., 2])
    theta, d = state[..., 3 : 3 + NUM_LINKS], state[..., 3 + NUM_LINKS :]
    markers = [None] * len(SPM_MARKERS)
    markers[0] = state[..., 0:2]
    phis = []
    for link, (parent, start, end) in enumerate(zip(_PARENTS, _STARTS, _ENDS)):
        phi = (_UP if parent < 0 else phis[parent]) + theta[..., link]
        phis.append(phi)
        step = (scale * lengths[link] * d[..., link])[..., None] * jnp.stack([jnp.cos(phi), jnp.sin(phi)], axis=-1)
        markers[end] = markers[start] + step
    return jnp.stack(markers, axis=-2)


def spm_from_markers(markers: Float[Array, "*batch 9 2"], scale=None) -> Float[Array, "*batch 19"]:
    """The SPM state whose markers are ``markers`` (exact: ``spm_forward`` gives them back).

    Args:
        markers: (..., 9, 2) pixels in ``SPM_MARKERS`` order.
        scale: (...) pixels per metre; None takes the spine as seen whole (``d_0 = 1``).
    """
    markers = jnp.asarray(markers)
    lengths = jnp.asarray(SPM_REFERENCE_LENGTHS, markers.dtype)
    vectors = markers[..., _ENDS, :] - markers[..., _STARTS, :]
    norms = jnp.sqrt(jnp.sum(vectors**2, axis=-1) + 1e-30)
    if scale is None:
        scale = norms[..., 0] / lengths[0]
    scale = jnp.asarray(scale, markers.dtype)
    phi = jnp.arctan2(vectors[..., 1], vectors[..., 0])
    parent_phi = jnp.stack([jnp.full_like(phi[..., 0], _UP) if p < 0 else phi[..., p] for p in _PARENTS], axis=-1)
    theta = _wrap(phi - parent_phi)
    d = norms / (scale[..., None] * lengths)
    return jnp.concatenate([markers[..., 0, :], jnp.log(scale)[..., None], theta, d], axis=-1)


def spm_features(state: Float[Array, "*batch 19"]) -> Float[Array, "*batch 16"]:
    """The pose part of SPM states as relative link vectors ``d_l (cos theta_l, sin theta_l)``
    (per link, interleaved): what the manifold learns."""
    theta, d = state[..., 3 : 3 + NUM_LINKS], state[..., 3 + NUM_LINKS :]
    features = jnp.stack([d * jnp.cos(theta), d * jnp.sin(theta)], axis=-1)
    return features.reshape(*features.shape[:-2], SPM_FEATURE_DIM)


def spm_state(features: Float[Array, "*batch 16"], translation: Float[Array, "*batch 2"],
              log_scale: Float[Array, "*batch"]) -> Float[Array, "*batch 19"]:
    """SPM states from ``spm_features`` and the global part (pelvis pixels, log pixels per metre)."""
    pairs = features.reshape(*features.shape[:-1], NUM_LINKS, 2)
    theta = jnp.arctan2(pairs[..., 1], pairs[..., 0])
    d = jnp.sqrt(jnp.sum(pairs**2, axis=-1) + 1e-30)
    return jnp.concatenate([translation, jnp.asarray(log_scale)[..., None], theta, d], axis=-1)


def spine_to_neck(markers: Float[Array, "*batch 9 2"]) -> Float[Array, "*batch"]:
    """003's body size: the image distance from the base of the spine to the neck, pixels."""
    a, b = SPINE_TO_NECK
    return jnp.sqrt(jnp.sum((markers[..., b, :] - markers[..., a, :]) ** 2, axis=-1))


def markers_from_joints(joints2d, joint_names=HUMANEVA_JOINTS):
    """The SPM markers (..., 9, 2) among 2-D joints (..., J, 2) named ``joint_names``."""
    missing = [m for m in SPM_MARKERS if m not in joint_names]
    if missing:
        raise ValueError(f"the joints lack the SPM markers {missing}")
    return jnp.asarray(joints2d)[..., [list(joint_names).index(m) for m in SPM_MARKERS], :]
