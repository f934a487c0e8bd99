"""Saving and loading fitted manifold models.

A file is one JSON header line (format name and version, model class, shapes, dtype, the
training sequences' boundaries) followed by the model's arrays in equinox's leaf format.
Loading rebuilds a template of the recorded class and shapes and fills it, so a file from
another class (when one is expected) or another format version is refused clearly.
"""

from __future__ import annotations

import json
import os

import equinox as eqx
import numpy as np

from ._base import MANIFOLD_CLASSES, AbstractManifold

FORMAT = "jaxtrack-manifold"
VERSION = 1


class ModelFileError(ValueError):
    """A model file that cannot be loaded (wrong format, version or class)."""


def save_model(path: str | os.PathLike, model, *, sequence_starts=None, extra: dict | None = None) -> None:
    """Write a fitted manifold (any registered ``AbstractManifold``: ``GPLVM``, ``BCGPLVM``,
    ``SparseGPLVM``, ``GPDM``) with everything needed to use it.

    Args:
        sequence_starts: first frame of each training sequence, ending with N (for plots);
            a GPDM's own boundaries are used when omitted.
        extra: JSON-serialisable metadata (e.g. the pose layout the data came from).
    """
    name = type(model).__name__
    if not isinstance(model, AbstractManifold) or MANIFOLD_CLASSES.get(name) is not type(model):
        raise TypeError(f"cannot save a {name}; saveable models are {sorted(MANIFOLD_CLASSES)}")
    n, d = model.data.shape
    q = model.latent_dim
    if sequence_starts is None:
        sequence_starts = model.header().get("sequence_starts", (0, n))
    header = {
        "format": FORMAT,
        "version": VERSION,
        "class": name,
        "frames": n,
        "dims": d,
        "latent_dim": q,
        "dtype": str(model.data.dtype),
        "sequence_starts": [int(s) for s in sequence_starts],
        "extra": extra or {},
    }
    header.update(model.header())
    with open(path, "wb") as handle:
        handle.write((json.dumps(header) + "\n").encode())
        eqx.tree_serialise_leaves(handle, model)


def read_header(path: str | os.PathLike) -> dict:
    """The JSON header of a model file."""
    with open(path, "rb") as handle:
        line = handle.readline()
    try:
        header = json.loads(line)
    except (json.JSONDecodeError, UnicodeDecodeError):
        raise ModelFileError(f"{os.fspath(path)}: not a jaxtrack model file (no JSON header line)") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise ModelFileError(f"{os.fspath(path)}: not a jaxtrack model file (format {header.get('format')!r})")
    return header


def load_model(path: str | os.PathLike, expected_class: str | None = None):
    """Load a model saved by ``save_model``; returns ``(model, header)``.

    Raises:
        ModelFileError: for another format, another version, or a class other than
            ``expected_class`` (e.g. ``"BCGPLVM"`` when a back-constraint is needed).
    """
    header = read_header(path)
    if header.get("version") != VERSION:
        raise ModelFileError(f"{os.fspath(path)}: format version {header.get('version')}, this jaxtrack reads version {VERSION}")
    name = header.get("class")
    if name not in MANIFOLD_CLASSES:
        raise ModelFileError(f"{os.fspath(path)}: unknown model class {name!r}")
    if expected_class is not None and name != expected_class:
        raise ModelFileError(f"{os.fspath(path)}: holds a {name}, but a {expected_class} is needed here")
    template = MANIFOLD_CLASSES[name].template(header, np.dtype(header["dtype"]))
    with open(path, "rb") as handle:
        handle.readline()
        model = eqx.tree_deserialise_leaves(handle, template)
    return model, header
