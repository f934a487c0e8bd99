"""Saving and loading fitted manifold models.

A file is one JSON header line (format name and version, model class, shapes, dtype, the
training sequences' boundaries, and since version 2 the length and SHA-256 of the payload)
followed by the model's arrays in equinox's leaf format. Loading checks the payload against
the header, so a truncated or edited file is reported as such with its name, then rebuilds a
template of the recorded class and shapes and fills it, so a file from another class (when one
is expected) or another format version is refused clearly. Files are written atomically.
"""

from __future__ import annotations

import abc
import hashlib
import io
import itertools
import json
import os

import equinox as eqx
import jax
import numpy as np

from ..errors import ModelFileError
from ..io import atomic_write
from ._base import AbstractManifold

FORMAT = "jaxtrack-manifold"
VERSION = 3
READABLE_VERSIONS = (1, 2, 3)  # version 1 files carry no payload length or checksum, version 2 none of the header


class AbstractSaveableManifold(AbstractManifold):
    """A manifold that can be written to a file and read back: the class-specific header fields
    and a template of the right shapes to load the arrays into. Register a concrete class with
    ``@register_manifold`` so ``load_model`` finds it by name."""

    @abc.abstractmethod
    def header(self) -> dict:
        """Class-specific fields for a saved file's header (what ``template`` needs)."""

    @classmethod
    @abc.abstractmethod
    def template(cls, header: dict, dtype) -> AbstractSaveableManifold:
        """A model of this class with the header's shapes (zeros), for loading a file into."""


MANIFOLD_CLASSES: dict[str, type[AbstractSaveableManifold]] = {}


def register_manifold(cls):
    """Class decorator: make a manifold class saveable and loadable under its class name."""
    if not (isinstance(cls, type) and issubclass(cls, AbstractSaveableManifold)):
        raise TypeError(f"register_manifold takes an AbstractSaveableManifold subclass, got {cls!r}")
    MANIFOLD_CLASSES[cls.__name__] = cls
    return cls


def _header_digest(header: dict) -> str:
    """SHA-256 of the header's other fields, as canonical JSON (sorted keys)."""
    fields = {k: v for k, v in header.items() if k != "header_sha256"}
    return hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()


def save_model(path: str | os.PathLike, model, *, sequence_starts=None, extra: dict | None = None) -> None:
    """Write a fitted manifold (any registered ``AbstractManifold``: ``GPLVM``, ``BCGPLVM``,
    ``SparseGPLVM``, ``GPDM``) with everything needed to use it.

    Args:
        sequence_starts: first frame of each training sequence, ending with N (for plots);
            a GPDM's own boundaries are used when omitted.
        extra: JSON-serialisable metadata (e.g. the pose layout the data came from).
    """
    name = type(model).__name__
    if not isinstance(model, AbstractSaveableManifold) or MANIFOLD_CLASSES.get(name) is not type(model):
        raise TypeError(f"cannot save a {name}; saveable models are {sorted(MANIFOLD_CLASSES)}")
    bad = [jax.tree_util.keystr(where) for where, leaf in jax.tree_util.tree_leaves_with_path(model)
           if eqx.is_inexact_array(leaf) and not np.all(np.isfinite(np.asarray(leaf)))]
    if bad:
        raise ModelFileError(f"{os.fspath(path)}: not saved: the model's {', '.join(bad[:4])} are not finite (a fit that "
                             "diverged, or training data out of range)")
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
    payload = io.BytesIO()
    eqx.tree_serialise_leaves(payload, model)
    payload = payload.getvalue()
    header["payload_bytes"] = len(payload)
    header["payload_sha256"] = hashlib.sha256(payload).hexdigest()
    header["header_sha256"] = _header_digest(header)
    with atomic_write(path) as handle:  # an interrupted write leaves any old file whole
        handle.write((json.dumps(header) + "\n").encode())
        handle.write(payload)


def read_header(path: str | os.PathLike) -> dict:
    """The JSON header of a model file."""
    with open(path, "rb") as handle:
        line = handle.readline()
    try:
        header = json.loads(line)
    except (json.JSONDecodeError, UnicodeDecodeError):
        raise ModelFileError(f"{os.fspath(path)}: not a jaxtrack model file (no JSON header line)") from None
    if not isinstance(header, dict):
        raise ModelFileError(f"{os.fspath(path)}: not a jaxtrack model file (its header is a JSON {type(header).__name__}, "
                             "not an object)")
    if header.get("format") != FORMAT:
        raise ModelFileError(f"{os.fspath(path)}: not a jaxtrack model file (format {header.get('format')!r})")
    return header


def load_model(path: str | os.PathLike, expected_class: str | None = None):
    """Load a model saved by ``save_model``; returns ``(model, header)``.

    Raises:
        ModelFileError: for another format, another version, a class other than
            ``expected_class`` (e.g. ``"BCGPLVM"`` when a back-constraint is needed), a payload
            whose length or checksum differs from the header's (truncated or edited), or a
            header or payload that does not fit its class.
    """
    where = os.fspath(path)
    header = read_header(path)
    if header.get("version") not in READABLE_VERSIONS:
        raise ModelFileError(f"{where}: format version {header.get('version')}, this jaxtrack reads versions {READABLE_VERSIONS}")
    name = header.get("class")
    if name not in MANIFOLD_CLASSES:
        raise ModelFileError(f"{where}: unknown model class {name!r}")
    if expected_class is not None and name != expected_class:
        raise ModelFileError(f"{where}: holds a {name}, but a {expected_class} is needed here")
    with open(path, "rb") as handle:
        handle.readline()
        payload = handle.read()
    if "payload_bytes" in header or header.get("version", 1) >= 2:
        expected = header.get("payload_bytes")
        if len(payload) != expected:
            cut = "truncated" if isinstance(expected, int) and len(payload) < expected else "edited"
            raise ModelFileError(f"{where}: {cut}: the arrays take {len(payload)} bytes, the header says {expected}")
        if hashlib.sha256(payload).hexdigest() != header.get("payload_sha256"):
            raise ModelFileError(f"{where}: edited or corrupted: the arrays' SHA-256 differs from the header's")
    if header.get("version", 1) >= 3 and header.get("header_sha256") != _header_digest(header):
        raise ModelFileError(f"{where}: edited or corrupted: the header's SHA-256 differs from the one it records")
    try:
        build = MANIFOLD_CLASSES[name].template
        dtype = np.dtype(header["dtype"])
        # The shapes first, without allocating: a header that asks for more than the file holds is refused.
        needed = sum(leaf.size * leaf.dtype.itemsize for leaf in jax.tree.leaves(eqx.filter_eval_shape(build, header, dtype))
                     if hasattr(leaf, "dtype"))
        if needed > len(payload):
            raise ModelFileError(f"{where}: the header describes {needed} bytes of arrays, the file holds {len(payload)}")
        model = eqx.tree_deserialise_leaves(io.BytesIO(payload), build(header, dtype))
    except ModelFileError:
        raise
    except Exception as err:  # any failure to rebuild the recorded model is the file's fault
        raise ModelFileError(f"{where}: the header does not describe the arrays that follow it "
                             f"({type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''})") from err
    bad = [jax.tree_util.keystr(at) for at, leaf in jax.tree_util.tree_leaves_with_path(model)
           if eqx.is_inexact_array(leaf) and not np.all(np.isfinite(np.asarray(leaf)))]
    if bad:  # an edited file of a version without checksums, or one written before save_model refused them
        raise ModelFileError(f"{where}: the model's {', '.join(bad[:4])} are not finite")
    frames = header.get("frames")
    starts = header.get("sequence_starts", [0, frames])
    if (not isinstance(starts, list) or len(starts) < 2 or not all(isinstance(v, int) and not isinstance(v, bool) for v in starts)
            or starts[0] != 0 or starts[-1] != frames or any(b <= a for a, b in itertools.pairwise(starts))):
        raise ModelFileError(f"{where}: sequence_starts must rise from 0 to the {frames} frames, got {starts!r}")
    return model, header
