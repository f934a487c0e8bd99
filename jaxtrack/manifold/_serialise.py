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
import jax
import jax.numpy as jnp
import numpy as np

from ._kernels import linear_rbf_kernel, rbf_bias_kernel
from ._models import BCGPLVM, GPDM, GPLVM, KernelBackConstraint, MLPBackConstraint
from ._sparse import SparseGPLVM

FORMAT = "jaxtrack-manifold"
VERSION = 1
CLASSES = {"GPLVM": GPLVM, "BCGPLVM": BCGPLVM, "GPDM": GPDM, "SparseGPLVM": SparseGPLVM}


class ModelFileError(ValueError):
    """A model file that cannot be loaded (wrong format, version or class)."""


def _template(header, dtype):
    name, n, d, q = header["class"], header["frames"], header["dims"], header["latent_dim"]
    z = lambda *shape: jnp.zeros(shape, dtype)  # noqa: E731
    kernel = rbf_bias_kernel(dtype=dtype)
    if name == "GPLVM":
        return GPLVM(latent=z(n, q), kernel=kernel, data=z(n, d), mean=z(d), scale=z(d))
    if name == "SparseGPLVM":
        return SparseGPLVM(
            latent=z(n, q), inducing=z(header["inducing"], q), kernel=kernel, data=z(n, d), mean=z(d), scale=z(d),
            approximation=header["approximation"],
        )
    if name == "BCGPLVM":
        if header.get("back_constraint", "kernel") == "mlp":
            # The key only shapes the template; every leaf is then read from the file.
            mlp = eqx.nn.MLP(d, q, header["mlp_hidden"], header["mlp_depth"], activation=jnp.tanh, key=jax.random.key(0), dtype=dtype)
            back = MLPBackConstraint(projection=z(d, q), bias=z(q), mlp=mlp)
        else:
            back = KernelBackConstraint(weights=z(n, q), bias=z(q), inputs=z(n, d), gamma_x=z())
        return BCGPLVM(back=back, kernel=kernel, data=z(n, d), mean=z(d), scale=z(d))
    starts = header["sequence_starts"]
    return GPDM(
        latent=z(n, q), kernel=kernel, dynamics=linear_rbf_kernel(dtype=dtype), log_w=z(d), data=z(n, d),
        mean=z(d), scale=z(d), sequence_starts=tuple(starts),
    )


def save_model(path: str | os.PathLike, model, *, sequence_starts=None, extra: dict | None = None) -> None:
    """Write a fitted ``GPLVM``, ``BCGPLVM``, ``SparseGPLVM`` or ``GPDM`` with everything needed
    to use it.

    Args:
        sequence_starts: first frame of each training sequence, ending with N (for plots);
            a GPDM's own boundaries are used when omitted.
        extra: JSON-serialisable metadata (e.g. the pose layout the data came from).
    """
    name = type(model).__name__
    if name not in CLASSES:
        raise TypeError(f"cannot save a {name}; saveable models are {sorted(CLASSES)}")
    n, d = model.data.shape
    q = model.training_latent().shape[1]
    if sequence_starts is None:
        sequence_starts = model.sequence_starts if isinstance(model, GPDM) else (0, n)
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
    if isinstance(model, SparseGPLVM):
        header.update(inducing=int(model.inducing.shape[0]), approximation=model.approximation)
    if isinstance(model, BCGPLVM):
        if isinstance(model.back, MLPBackConstraint):
            header.update(back_constraint="mlp", mlp_hidden=int(model.back.mlp.width_size), mlp_depth=int(model.back.mlp.depth))
        else:
            header.update(back_constraint="kernel")
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
    if name not in CLASSES:
        raise ModelFileError(f"{os.fspath(path)}: unknown model class {name!r}")
    if expected_class is not None and name != expected_class:
        raise ModelFileError(f"{os.fspath(path)}: holds a {name}, but a {expected_class} is needed here")
    template = _template(header, np.dtype(header["dtype"]))
    with open(path, "rb") as handle:
        handle.readline()
        model = eqx.tree_deserialise_leaves(handle, template)
    return model, header
