"""Binary masks packed 32 pixels of a row to a ``uint32`` word, for the fixed-point loops of
hysteresis: one growth of a packed mask by its 8 neighbours touches 1/32 of the array a boolean
one does (shifts with a carry between neighbouring words, ORs of neighbouring rows).

Bit ``j`` of word ``k`` of a row is the pixel in column ``32 k + j``; the columns past the width
are padding and stay False as long as every growth is ANDed with a mask whose padding is False.
"""

from __future__ import annotations

import jax.numpy as jnp

WORD = 32


def pack(mask):
    """(..., H, W) bool -> (..., H, ceil(W / 32)) uint32."""
    width = mask.shape[-1]
    words = -(-width // WORD)
    mask = jnp.pad(mask, [(0, 0)] * (mask.ndim - 1) + [(0, words * WORD - width)])
    bits = mask.reshape(mask.shape[:-1] + (words, WORD)).astype(jnp.uint32)
    return jnp.sum(bits << jnp.arange(WORD, dtype=jnp.uint32), axis=-1, dtype=jnp.uint32)


def unpack(words, width: int):
    """(..., H, n) uint32 -> (..., H, width) bool (``pack``'s inverse)."""
    bits = (words[..., None] >> jnp.arange(WORD, dtype=jnp.uint32)) & 1
    return bits.reshape(words.shape[:-1] + (words.shape[-1] * WORD,))[..., :width].astype(bool)


def grow(words):
    """Each pixel of a packed mask ORed with its 8 neighbours (outside the image: False)."""
    zero = jnp.zeros_like(words[..., :1])
    before = jnp.concatenate([zero, words[..., :-1]], axis=-1)  # the word to each word's left
    after = jnp.concatenate([words[..., 1:], zero], axis=-1)
    left = (words << 1) | (before >> (WORD - 1))  # each pixel gets its left neighbour's bit
    right = (words >> 1) | (after << (WORD - 1))
    rows = words | left | right
    pad = [(0, 0)] * (rows.ndim - 2) + [(1, 1), (0, 0)]
    rows = jnp.pad(rows, pad)
    return rows[..., :-2, :] | rows[..., 1:-1, :] | rows[..., 2:, :]
