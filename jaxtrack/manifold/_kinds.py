"""The manifold-kind registry: every kind of pose manifold jaxtrack can fit, by name, in one
table that ``jaxtrack fit``, ``jaxtrack experiment``, ``jaxtrack track`` and
``tracking.fit_manifold`` all read.

A kind is a maker (training joint-angle sequences -> an unfitted ``AbstractManifold``), its
default latent dimension, its family (which trackers can run on it) and its preconditions.
Register one of your own with ``register_manifold_kind(ManifoldKind(...))``; loaded with
``--plugin``, it is then a ``--model`` of ``jaxtrack fit`` and a ``--manifold`` of ``jaxtrack
experiment``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from .._registries import Registry, check_name
from ._active_set import make_active_set_gplvm
from ._bc_gpdm import make_bc_gpdm
from ._models import make_bc_gplvm, make_gpdm, make_gplvm
from ._sparse import make_sparse_gplvm
from ._sparse_bc_gplvm import make_sparse_bc_gplvm
from ._spectral import fit_spectral

FAMILIES = ("gp", "spectral")
"""``"gp"``: a latent variable model whose ``prior()`` the GP-manifold trackers (MRPF, GPAPF,
LatentPF) run on; ``"spectral"``: a ``SpectralEmbedding``, whose graph GLE-GbPF walks."""


@dataclasses.dataclass(frozen=True)
class ManifoldKind:
    """How to make one kind of pose manifold.

    Attributes:
        name: the registry name (``jaxtrack fit --model NAME``, ``experiment --manifold NAME``).
        description: one line for ``--help`` and the docs.
        make: ``(sequences, latent_dim, *, key, **options) -> AbstractManifold``: the unfitted
            model (float64) of the training joint-angle sequences (a list of (T_i, A) arrays);
            ``model.fit(...)`` then fits it.
        latent_dim: the latent dimension when nobody names one.
        family: one of ``FAMILIES``.
        options: the maker's keyword options and their defaults (``--manifold-option K=V``).
        min_frames: the fewest frames every training sequence needs.
        min_total: the fewest training frames in all.
        trackable: whether ``jaxtrack experiment`` fits it for trackers (the kinds whose
            tracking was measured); every kind can be fitted and saved with ``jaxtrack fit``.
    """

    name: str
    description: str
    make: Callable[..., Any]
    latent_dim: int = 2
    family: str = "gp"
    options: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    min_frames: int = 1
    min_total: int = 0
    trackable: bool = True

    def __post_init__(self):
        check_name("manifold kind", self.name)
        if not callable(self.make):
            raise TypeError(f"manifold kind {self.name!r}: make must be a callable")
        if self.family not in FAMILIES:
            raise ValueError(f"manifold kind {self.name!r}: family must be one of {FAMILIES}, got {self.family!r}")
        if isinstance(self.latent_dim, bool) or not isinstance(self.latent_dim, int) or self.latent_dim < 1:
            raise ValueError(f"manifold kind {self.name!r}: latent_dim must be a positive integer, got {self.latent_dim!r}")

    def problem(self, lengths, latent_dim: int) -> str | None:
        """Why this kind cannot be fitted in ``latent_dim`` dimensions on training sequences of
        these lengths (frames), or None: checked before any fitting."""
        lengths = [int(n) for n in lengths]
        total = sum(lengths)
        if not lengths:
            return "there are no training sequences"
        if total <= latent_dim + 1:
            return f"{total} training frames are too few for a {latent_dim}-D latent space (need more than {latent_dim + 1})"
        if min(lengths) < self.min_frames:
            return (f"a {self.name} needs {self.min_frames} or more frames in every training sequence "
                    f"(one has {min(lengths)})")
        if total < self.min_total:
            return f"a {self.name} needs at least {self.min_total} training frames, got {total}"
        return None

    def build(self, sequences, latent_dim: int | None = None, *, key=None, **options):
        """The unfitted model of the training joint-angle sequences ((T_i, A) arrays), in
        ``latent_dim`` dimensions (None: the kind's own); ``options`` override ``self.options``.
        Raises ``ValueError`` naming the problem (``problem``) or an unknown option."""
        latent_dim = self.latent_dim if latent_dim is None else latent_dim
        unknown = sorted(set(options) - set(self.options))
        if unknown:
            raise ValueError(f"manifold kind {self.name!r} takes no option {', '.join(map(repr, unknown))}"
                             f" (it takes: {', '.join(self.options) or 'none'})")
        sequences = [np.asarray(s, np.float64) for s in sequences]
        why = self.problem([len(s) for s in sequences], latent_dim)
        if why is not None:
            raise ValueError(why)
        return self.make(sequences, latent_dim, key=key, **{**self.options, **options})


_KINDS: Registry[ManifoldKind] = Registry("manifold kind", ManifoldKind, "register_manifold_kind")


def register_manifold_kind(kind: ManifoldKind, *, replace: bool = False) -> ManifoldKind:
    """Add a manifold kind to the registry (``replace=True`` to redefine a name); returns it."""
    return _KINDS.register(kind, replace=replace)


def unregister_manifold_kind(name: str) -> None:
    """Remove a manifold kind from the registry."""
    _KINDS.unregister(name)


def get_manifold_kind(name: str) -> ManifoldKind:
    """The kind registered as ``name``; raises ``ValueError`` listing the names otherwise."""
    return _KINDS.get(name)


def manifold_kinds(*, family: str | None = None, trackable: bool | None = None) -> tuple[str, ...]:
    """The registered kind names, in registration order, optionally of one ``family`` and
    (``trackable=True``) only those ``jaxtrack experiment`` fits for trackers."""
    return tuple(kind.name for kind in _KINDS.recipes()
                 if (family is None or kind.family == family) and (trackable is None or kind.trackable == trackable))


def _concatenated(maker):
    """A maker of one pose matrix as a maker of sequences (the frames stacked)."""
    return lambda sequences, latent_dim, *, key=None, **options: maker(np.concatenate(sequences), latent_dim, **options)


def _spectral(graph):
    return lambda sequences, latent_dim, *, key=None, **options: fit_spectral(sequences, graph, latent_dim=latent_dim, **options)


def _sparse_gplvm(sequences, latent_dim, *, key=None, num_inducing=150, **options):
    poses = np.concatenate(sequences)
    return make_sparse_gplvm(poses, latent_dim, num_inducing=min(int(num_inducing), poses.shape[0]), **options)


def _sparse_bc_gplvm(sequences, latent_dim, *, key=None, num_inducing=150, **options):
    poses = np.concatenate(sequences)
    return make_sparse_bc_gplvm(poses, latent_dim, num_inducing=min(int(num_inducing), poses.shape[0]), **options)


def _active_set_gplvm(sequences, latent_dim, *, key=None, active=200, **options):
    poses = np.concatenate(sequences)
    return make_active_set_gplvm(poses, latent_dim, active=min(int(active), poses.shape[0]), **options)


def _bc_gplvm_mlp(sequences, latent_dim, *, key=None, **options):
    if key is None:
        raise ValueError("a bc-gplvm-mlp needs a PRNG key to initialise its MLP (key=...)")
    return make_bc_gplvm(np.concatenate(sequences), latent_dim, back_constraint="mlp", key=key, **options)


for _kind in (
    ManifoldKind("bc-gplvm", "back-constrained GPLVM with a kernel back-constraint (000 eqs. 21-22)", _concatenated(make_bc_gplvm)),
    ManifoldKind("gpdm", "Gaussian process dynamical model (001 eqs. 5-11)",
                 lambda sequences, latent_dim, *, key=None, **options: make_gpdm(sequences, latent_dim, **options), min_frames=2),
    ManifoldKind("bc-gpdm", "GPDM under 000's kernel back-constraint",
                 lambda sequences, latent_dim, *, key=None, **options: make_bc_gpdm(sequences, latent_dim, **options), min_frames=2),
    ManifoldKind("gle", "Generalised Laplacian Eigenmap with its RBF networks (002 eqs. 2-6)", _spectral("gle"),
                 latent_dim=3, family="spectral", min_frames=5),
    # A temporal graph links each frame to its neighbours in time: two frames per sequence keep it
    # connected. GLE cuts each sequence into gait cycles, which need five.
    ManifoldKind("tle", "temporal Laplacian Eigenmap with its RBF networks (002)", _spectral("tle"),
                 latent_dim=3, family="spectral", min_frames=2),
    ManifoldKind("le", "Laplacian Eigenmap on a k-nearest-neighbour graph, with its RBF networks (002)", _spectral("le"),
                 latent_dim=3, family="spectral", min_total=11),
    ManifoldKind("gplvm", "GPLVM, MAP latent points (Lawrence 2005)", _concatenated(make_gplvm), trackable=False),
    ManifoldKind("bc-gplvm-mlp", "back-constrained GPLVM with an MLP back-constraint (000 sec. 4)", _bc_gplvm_mlp,
                 trackable=False),
    ManifoldKind("sparse-gplvm", "sparse GPLVM with inducing points (004; at most one per frame)", _sparse_gplvm,
                 options={"num_inducing": 150}, trackable=False),
    ManifoldKind("sparse-bc-gplvm", "sparse GPLVM under 000's kernel back-constraint, 150 inducing points (004 sec. 5.1)",
                 _sparse_bc_gplvm, options={"num_inducing": 150}),
    ManifoldKind("active-set-gplvm", "GPLVM on an IVM active set, the other points by 003 eq. 2 (003 Algorithm 1)",
                 _active_set_gplvm, options={"active": 200, "init": "isomap"}, trackable=False),
):
    register_manifold_kind(_kind)
del _kind
