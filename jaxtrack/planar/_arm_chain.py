"""The baselines' body of paper 003 sec. 5.2: "a simpler kinematic chain model anchored at the
shoulders", 6 states. Per arm (left, then right): the upper arm's angle in the image
``phi`` (radians, from the image's x axis, v down), the elbow's angle ``theta`` relative to the
upper arm, and one prismatic scale ``d`` for both links (foreshortening). The torso's markers
(pelvis, thorax, head, shoulders) stay where the first frame puts them; each link is
``d`` times its first-frame reference length ``s0 * L_l`` (``s0`` from the first frame's spine,
``SPM_REFERENCE_LENGTHS``).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from .._custom_types import Array, Float
from ._spm import _UP, NUM_LINKS, SPM_LINKS, SPM_MARKERS, SPM_REFERENCE_LENGTHS, _wrap

ARM_STATE_DIM = 6
_LINK = {name: i for i, (name, *_rest) in enumerate(SPM_LINKS)}
_MARK = {name: i for i, name in enumerate(SPM_MARKERS)}
_SIDES = (("l", "lclavicle", "lupper_arm", "lforearm"), ("r", "rclavicle", "rupper_arm", "rforearm"))


class ArmAnchor(eqx.Module):
    """The fixed part of the arm-chain body.

    Attributes:
        markers: (9, 2) the first frame's markers (the torso's are kept, the arms' replaced).
        lengths: (2, 2) pixels: (upper arm, forearm) reference lengths of the left and right arm.
    """

    markers: Float[Array, "9 2"]
    lengths: Float[Array, "2 2"]


def arm_anchor(markers: Float[Array, "9 2"]) -> ArmAnchor:
    """The anchor of the first frame's markers: the reference lengths ``s0 * L_l`` with ``s0``
    the spine's pixels per metre."""
    markers = jnp.asarray(markers)
    s0 = jnp.linalg.norm(markers[_MARK["thorax"]] - markers[_MARK["pelvis"]]) / SPM_REFERENCE_LENGTHS[0]
    lengths = jnp.asarray([[SPM_REFERENCE_LENGTHS[_LINK[f"{s}upper_arm"]], SPM_REFERENCE_LENGTHS[_LINK[f"{s}forearm"]]]
                           for s in "lr"], markers.dtype) * s0
    return ArmAnchor(markers=markers, lengths=lengths)


def arm_markers(state: Float[Array, "*batch 6"], anchor: ArmAnchor) -> Float[Array, "*batch 9 2"]:
    """The 9 markers of arm-chain states: the anchor's torso, the arms from the states."""
    state = jnp.asarray(state)
    markers = jnp.broadcast_to(anchor.markers, state.shape[:-1] + anchor.markers.shape)
    for side, (s, *_links) in enumerate(_SIDES):
        phi, theta, d = state[..., 3 * side], state[..., 3 * side + 1], state[..., 3 * side + 2]
        shoulder = markers[..., _MARK[f"{s}shoulder"], :]
        upper = (d * anchor.lengths[side, 0])[..., None] * jnp.stack([jnp.cos(phi), jnp.sin(phi)], -1)
        fore = (d * anchor.lengths[side, 1])[..., None] * jnp.stack([jnp.cos(phi + theta), jnp.sin(phi + theta)], -1)
        markers = markers.at[..., _MARK[f"{s}elbow"], :].set(shoulder + upper)
        markers = markers.at[..., _MARK[f"{s}wrist"], :].set(shoulder + upper + fore)
    return markers


def arm_state_from_markers(markers: Float[Array, "*batch 9 2"], anchor: ArmAnchor) -> Float[Array, "*batch 6"]:
    """The arm-chain state nearest to ``markers``: the arms' angles exactly, ``d`` the mean of the
    two links' length ratios."""
    markers = jnp.asarray(markers)
    out = []
    for side, (s, *_links) in enumerate(_SIDES):
        upper = markers[..., _MARK[f"{s}elbow"], :] - markers[..., _MARK[f"{s}shoulder"], :]
        fore = markers[..., _MARK[f"{s}wrist"], :] - markers[..., _MARK[f"{s}elbow"], :]
        phi = jnp.arctan2(upper[..., 1], upper[..., 0])
        theta = _wrap(jnp.arctan2(fore[..., 1], fore[..., 0]) - phi)
        d = 0.5 * (jnp.linalg.norm(upper, axis=-1) / anchor.lengths[side, 0] + jnp.linalg.norm(fore, axis=-1) / anchor.lengths[side, 1])
        out += [phi, theta, d]
    return jnp.stack(out, axis=-1)


def arm_states_from_features(features: Float[Array, "*batch 16"]) -> Float[Array, "*batch 6"]:
    """Arm-chain states of SPM poses (``spm_features``): the upper arm's absolute angle summed up
    the chain from the image's up direction, the elbow's relative angle, ``d`` the mean of the
    two links' ``d``."""
    pairs = jnp.asarray(features).reshape(*jnp.shape(features)[:-1], NUM_LINKS, 2)
    theta = jnp.arctan2(pairs[..., 1], pairs[..., 0])
    d = jnp.linalg.norm(pairs, axis=-1)
    out = []
    for _s, clavicle, upper, fore in _SIDES:
        phi = _wrap(_UP + theta[..., 0] + theta[..., _LINK[clavicle]] + theta[..., _LINK[upper]])
        out += [phi, theta[..., _LINK[fore]], 0.5 * (d[..., _LINK[upper]] + d[..., _LINK[fore]])]
    return jnp.stack(out, axis=-1)
