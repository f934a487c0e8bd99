"""A person's stature and the limb lengths it implies.

The default limb lengths (``DEFAULT_LIMB_LENGTHS``) are those of a 1.77 m adult in the
proportions of standard anthropometric tables (segment lengths as fractions of stature, e.g.
Winter, *Biomechanics and Motor Control of Human Movement*, Fig. 4.1: thigh 0.245 H, shank
0.246 H, upper arm 0.186 H, forearm 0.146 H). A stated height scales all of them alike; what a
person's own proportions add on top is left to the calibration's prior
(``likelihood.calibrate_body``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from ._skeleton import DEFAULT_LIMB_LENGTHS

ANKLE_TO_SOLE = 0.08  # metres from the ankle joint to the floor, standing
HEAD_CENTRE_TO_CROWN = 0.11  # metres from the head joint (the head's centre) to the crown
MIN_STATURE, MAX_STATURE = 0.5, 2.6  # metres: the range a person's height is accepted in


def stature(limb_lengths: Mapping[str, float] | None = None) -> float:
    """Standing height (metres) of a skeleton with these limb lengths: sole to ankle, shin,
    thigh, spine, neck and head centre to crown."""
    L = {**DEFAULT_LIMB_LENGTHS, **dict(limb_lengths or {})}
    return ANKLE_TO_SOLE + L["shin"] + L["thigh"] + L["spine"] + L["neck"] + HEAD_CENTRE_TO_CROWN


DEFAULT_STATURE = stature()


def check_height(height: float, what: str = "height") -> float:
    """A person's height in metres, or ``ValueError`` naming the problem (millimetres or
    centimetres given, a non-finite or impossible value)."""
    try:
        value = float(height)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a number of metres, got {height!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"{what} must be finite, got {height!r}")
    if 100 <= value <= 260:
        raise ValueError(f"{what} {value:g} looks like centimetres; give it in metres ({value / 100:g})")
    if 1000 <= value <= 2600:
        raise ValueError(f"{what} {value:g} looks like millimetres; give it in metres ({value / 1000:g})")
    if not MIN_STATURE <= value <= MAX_STATURE:
        raise ValueError(f"{what} {value:g} m is not a person's height (accepted: {MIN_STATURE:g}-{MAX_STATURE:g} m)")
    return value


def limb_lengths_for_height(height: float) -> dict[str, float]:
    """The default proportions scaled to a standing ``height`` (metres)."""
    factor = check_height(height) / DEFAULT_STATURE
    return {limb: length * factor for limb, length in DEFAULT_LIMB_LENGTHS.items()}
