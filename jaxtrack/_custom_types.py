"""jaxtyping aliases and the dimension-name glossary used across jaxtrack.

Dimension names used in annotations:

- ``frames``: time steps T of a sequence.
- ``particles``: particles N of a filter (any leading batch of poses is written ``*batch``).
- ``joints``: skeleton joints J (15 for the HumanEva set).
- ``dofs``: length D of a pose vector (translation + every rotational degree of freedom).
- ``capsules``: body-shape primitives K.
- ``views``: cameras C of a rig.
- ``height width``: image rows H and columns W, in pixels.
- ``points``: any number of 3-D points.
- ``runs``: independent runs of a tracker (a batch of PRNG keys).
"""

from jaxtyping import Array, ArrayLike, Bool, Float, Int, Key, PRNGKeyArray, Shaped, UInt8

__all__ = [
    "Array",
    "ArrayLike",
    "Bool",
    "Float",
    "Int",
    "Key",
    "PRNGKeyArray",
    "Shaped",
    "UInt8",
]
