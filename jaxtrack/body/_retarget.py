"""Retargeting: which source joints give each of the 15 HumanEva joints.

A mapping sends each HumanEva joint name to one source joint name, or to a tuple of names
whose positions are averaged. The pelvis is taken as the midpoint of the two hips in the
presets, so that the hips sit symmetrically about it as in the body model.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ._skeleton import HUMANEVA_JOINTS

# CMU ASF/AMC (positions are bone end points).
CMU_TO_HUMANEVA: dict[str, str | tuple[str, ...]] = {
    "pelvis": ("lhipjoint", "rhipjoint"),
    "thorax": "thorax",
    "lshoulder": "lclavicle",
    "lelbow": "lhumerus",
    "lwrist": "lradius",
    "rshoulder": "rclavicle",
    "relbow": "rhumerus",
    "rwrist": "rradius",
    "lhip": "lhipjoint",
    "lknee": "lfemur",
    "lankle": "ltibia",
    "rhip": "rhipjoint",
    "rknee": "rfemur",
    "rankle": "rtibia",
    "head": ("upperneck", "head"),
}

# Bandai Namco Research Motion Dataset BVH (positions are joint origins).
BANDAI_TO_HUMANEVA: dict[str, str | tuple[str, ...]] = {
    "pelvis": ("UpperLeg_L", "UpperLeg_R"),
    "thorax": "Neck",
    "lshoulder": "UpperArm_L",
    "lelbow": "LowerArm_L",
    "lwrist": "Hand_L",
    "rshoulder": "UpperArm_R",
    "relbow": "LowerArm_R",
    "rwrist": "Hand_R",
    "lhip": "UpperLeg_L",
    "lknee": "LowerLeg_L",
    "lankle": "Foot_L",
    "rhip": "UpperLeg_R",
    "rknee": "LowerLeg_R",
    "rankle": "Foot_R",
    "head": "Head",
}

IDENTITY_MAPPING: dict[str, str] = {name: name for name in HUMANEVA_JOINTS}

PRESETS = {"cmu": CMU_TO_HUMANEVA, "bandai": BANDAI_TO_HUMANEVA, "humaneva": IDENTITY_MAPPING}


def guess_mapping(joint_names: Sequence[str]) -> dict:
    """The preset whose source joints are all present in ``joint_names``.

    Raises:
        ValueError: when no preset fits (pass a mapping explicitly).
    """
    names = set(joint_names)
    for mapping in PRESETS.values():
        needed = {n for v in mapping.values() for n in ((v,) if isinstance(v, str) else v)}
        if needed <= names:
            return dict(mapping)
    raise ValueError(
        "no built-in joint mapping fits this skeleton (presets: cmu, bandai, humaneva); give one "
        f"from the 15 HumanEva joints to these source joints: {sorted(names)}"
    )


def retarget_positions(
    positions: np.ndarray, joint_names: Sequence[str], mapping: Mapping[str, str | Sequence[str]] | None = None
) -> np.ndarray:
    """Source joint positions (T, J_src, 3) -> HumanEva joint positions (T, 15, 3).

    Args:
        positions: source joint trajectories, metres.
        joint_names: the J_src source names.
        mapping: HumanEva joint -> source joint (or joints, averaged); guessed if omitted.
    """
    names = list(joint_names)
    if mapping is None:
        mapping = guess_mapping(names)
    missing_targets = [j for j in HUMANEVA_JOINTS if j not in mapping]
    if missing_targets:
        raise ValueError(f"the joint mapping does not say where {missing_targets} come from")
    unknown = [j for j in mapping if j not in HUMANEVA_JOINTS]
    if unknown:
        raise ValueError(f"the joint mapping names {unknown}, which are not HumanEva joints {HUMANEVA_JOINTS}")
    positions = np.asarray(positions, np.float64)
    if positions.ndim != 3 or positions.shape[1:] != (len(names), 3):
        raise ValueError(f"positions must be (T, {len(names)}, 3), got {positions.shape}")
    out = []
    for joint in HUMANEVA_JOINTS:
        sources = mapping[joint]
        sources = (sources,) if isinstance(sources, str) else tuple(sources)
        absent = [s for s in sources if s not in names]
        if absent:
            raise ValueError(f"the mapping takes {joint!r} from {absent}, which the source skeleton lacks")
        out.append(np.mean([positions[:, names.index(s)] for s in sources], axis=0))
    return np.stack(out, axis=1)
