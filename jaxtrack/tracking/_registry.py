"""The tracker registry: what a tracker is to the pipeline (a recipe that fits its dynamics on
motion data once and builds its filter for a test sequence), and the name -> recipe table that
the experiment, the command line, the demo and the benchmarks read.

Register a tracker of your own with ``register_tracker(TrackerRecipe(...))``; it then runs
through ``jaxtrack.experiment.run_experiment`` and, loaded with ``--plugin``, through
``jaxtrack experiment`` and ``jaxtrack track``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from .._registries import Registry, check_name
from ..manifold import ManifoldPrior, get_manifold_kind, manifold_kinds

# A likelihood gradient per particle, in evaluations (measured by benchmarks/bench_gradient.py;
# docs/trackers.md, "Gradient-refined particles").
GRADIENT_COST = 50.0
# The latent trackers' default pose residual, a fading start: scale 0.05 of the pose random walk's
# steps and a factor of 0.9 a frame, so the filter starts at the given pose (not at its
# projection onto the manifold) and is back on the manifold within 20-30 frames (docs/gle.md,
# "Starting off the manifold").
FADING_START = (0.05, 0.9)
@dataclasses.dataclass(frozen=True)
class Budget:
    """Likelihood evaluations per frame, the annealing layers they may be split into, and the
    gradient-refined moves (``LangevinRefinement``) per particle they must also pay for.

    A refined move costs one likelihood gradient per particle, counted as ``gradient_cost``
    evaluations (its measured cost), so ``N (layers + refine_steps * gradient_cost)`` stays
    within ``evaluations``.
    """

    evaluations: int
    layers: int = 1
    refine_steps: int = 0
    gradient_cost: float = GRADIENT_COST

    def __post_init__(self):
        for name in ("evaluations", "layers"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"budget {name} must be a positive integer, got {value!r}")
        if isinstance(self.refine_steps, bool) or not isinstance(self.refine_steps, int) or self.refine_steps < 0:
            raise ValueError(f"budget refine_steps must be a non-negative integer, got {self.refine_steps!r}")
        if not self.gradient_cost > 0:
            raise ValueError(f"budget gradient_cost must be positive, got {self.gradient_cost!r}")
        if self.particles_for(1) < 1:  # the annealed trackers check their layers themselves (TrackerRecipe.check_budget)
            raise ValueError(f"a budget of {self.evaluations} evaluations cannot pay for one particle and {self.refine_steps} "
                             f"refined moves at {self.gradient_cost:g} evaluations a gradient")

    def particles_for(self, layers: int) -> int:
        """Particles per layer of a tracker with ``layers`` layers per frame."""
        return int(self.evaluations // (layers + self.refine_steps * self.gradient_cost))

    @property
    def particles(self) -> int:
        """Particles of a one-layer tracker (SIR and its kin)."""
        return self.particles_for(1)

    @property
    def per_layer(self) -> int:
        """Particles per layer when the budget is split into ``layers`` equal layers."""
        return self.particles_for(self.layers)


@dataclasses.dataclass(frozen=True)
class MotionData:
    """The motion a tracker's dynamics are fitted on, in float64.

    Attributes:
        training: (T_i, D) pose sequences the manifold was fitted on.
        validation: (T_i, D) pose sequences held out for the dynamics (000 sec. 5.2).
        manifold: the fitted manifold precomputed for tracking, or None.
        model: the fitted manifold itself (an ``AbstractManifold``), or None: for trackers that
            walk a model's own structure (GLE-GbPF walks a ``SpectralEmbedding``'s graph).
        training_starts: first frame of each training sequence in the manifold's data, ending
            with the total.
        stored: what a model file stored beside its manifold (its header's ``extra``), for a
            tracker whose dynamics were fitted with the manifold and saved with it (VLMM-PF's
            prototypes from ``jaxtrack fit --model vlmm``); empty when the manifold was fitted
            here.
    """

    training: tuple[np.ndarray, ...]
    validation: tuple[np.ndarray, ...]
    manifold: ManifoldPrior | None = None
    training_starts: tuple[int, ...] | None = None
    model: Any = None
    stored: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    @property
    def pose_dim(self) -> int:
        return int(self.validation[0].shape[1])


@dataclasses.dataclass(frozen=True)
class TrackerRecipe:
    """How to make one tracker.

    Attributes:
        name: the registry name (``--methods NAME``).
        label: the column header in tables and plots.
        description: one line for ``--help`` and the docs.
        fit: ``(key, MotionData) -> fitted`` (a dynamics module, or a pytree of them), run once
            per experiment in float64.
        build: ``(fitted, likelihood, Budget) -> AbstractFilter``, run per test sequence on the
            fitted parameters cast to the tracking precision; one-layer trackers take
            ``budget.particles`` particles, annealed ones ``budget.per_layer`` per layer (both
            leave room for gradient-refined moves, which ``build_tracker`` adds).
        needs_manifold: whether ``fit`` reads ``MotionData.manifold``.
        manifold: the manifold kind the tracker runs on by default (a registered kind,
            ``manifold.manifold_kinds()``), fitted for it unless the experiment names one of its
            family for every tracker.
        manifolds: the manifold kinds the tracker can run on; None: every registered kind of
            its default kind's family (``ManifoldKind.family``), those of plugins included.
        velocity: whether the tracker's dynamics carry a Kalman-tracked velocity
            (``dynamics.StateVelocity``) unless the experiment says otherwise for every tracker:
            on for the one-layer manifold trackers, whose step is the prior's; off for the
            annealed ones, whose layers find the step in the likelihood, and for the plain
            baselines (docs/trackers.md, "Dynamics that move").
        annealed: whether the budget is split into ``Budget.layers`` equal layers.
        min_layers: the fewest layers the tracker works with.
        latent_dim: the latent dimension of the tracker's manifold unless the experiment names
            one for every tracker (None: the kind's own, ``ManifoldKind.latent_dim``).
        residual: for a tracker whose pose is decoded from a latent point, the default scale of
            an off-manifold pose residual (``dynamics.PoseResidual``; 0: none, except the fading
            start where frame 0's pose is far from its projection, ``build_for_start``) unless the
            experiment names one for every such tracker; None for a tracker whose state holds
            the pose itself (or whose estimate projects onto the manifold), which takes none.
        residual_decay: that default residual's factor per frame (``PoseResidual.decay``; 1: a
            random walk; below 1 a fading start: the filter starts at the given pose and fades
            onto its manifold).
    """

    name: str
    label: str
    description: str
    fit: Callable[[Any, MotionData], Any]
    build: Callable[[Any, Any, Budget], Any]
    needs_manifold: bool = False
    manifold: str = "bc-gplvm"
    manifolds: tuple[str, ...] | None = None
    velocity: bool = False
    annealed: bool = False
    min_layers: int = 1
    latent_dim: int | None = None
    residual: float | None = None
    residual_decay: float = 1.0

    def __post_init__(self):
        check_name("tracker", self.name)
        if not (callable(self.fit) and callable(self.build)):
            raise TypeError(f"tracker {self.name!r}: fit and build must be callables")
        known = manifold_kinds()
        if self.manifold not in known or (self.manifolds is not None and (self.manifold not in self.manifolds
                                                                          or not set(self.manifolds) <= set(known))):
            raise ValueError(f"tracker {self.name!r}: manifold {self.manifold!r} and manifolds {self.manifolds} must be "
                             f"registered manifold kinds ({', '.join(known)}), the first among the second")
        if self.residual is not None and not (np.isfinite(self.residual) and self.residual >= 0):
            raise ValueError(f"tracker {self.name!r}: residual must be a scale >= 0 or None, got {self.residual!r}")
        if not 0 < self.residual_decay <= 1:
            raise ValueError(f"tracker {self.name!r}: residual_decay must be in (0, 1], got {self.residual_decay!r}")
        if self.latent_dim is not None and (isinstance(self.latent_dim, bool) or not isinstance(self.latent_dim, int)
                                            or self.latent_dim < 1):
            raise ValueError(f"tracker {self.name!r}: latent_dim must be a positive integer or None, got {self.latent_dim!r}")

    @property
    def family(self) -> str:
        """The family of the tracker's manifold (``ManifoldKind.family``: "gp" or "spectral")."""
        return get_manifold_kind(self.manifold).family

    @property
    def runs_on(self) -> tuple[str, ...]:
        """The registered manifold kinds this tracker can run on."""
        return self.manifolds if self.manifolds is not None else manifold_kinds(family=self.family, trackable=True)

    def manifold_for(self, requested: str | None) -> str:
        """The manifold kind this tracker runs on when the experiment asks for ``requested``
        (None: the tracker's own). A request names the manifold of every tracker of its family
        (``ManifoldKind.family``): a tracker of the other family keeps its own. Raises
        ``ValueError`` for an unknown kind, or one of its family the tracker cannot run on."""
        if requested is None:
            return self.manifold
        if get_manifold_kind(requested).family != self.family:
            return self.manifold
        if requested not in self.runs_on:
            raise ValueError(f"{self.label} cannot run on a {requested} manifold (it runs on: {', '.join(self.runs_on)})")
        return requested

    def latent_dim_for(self, kind: str, requested: int | None) -> int:
        """The latent dimension of this tracker's ``kind`` manifold when the experiment asks for
        ``requested`` (None: the tracker's own, else the kind's, ``ManifoldKind.latent_dim``)."""
        if requested is not None:
            return requested
        return get_manifold_kind(kind).latent_dim if self.latent_dim is None else self.latent_dim

    def velocity_for(self, requested: bool | None) -> bool:
        """Whether this tracker carries a velocity when the experiment asks for ``requested``
        (None: the tracker's own default)."""
        return self.velocity if requested is None else bool(requested)

    def residual_for(self, requested: float | None) -> float:
        """The scale of this tracker's pose residual when the experiment asks for ``requested``
        (None: the tracker's own default); 0 for a tracker that takes none."""
        if self.residual is None:
            return 0.0
        return self.residual if requested is None else float(requested)

    def residual_decay_for(self, requested_scale: float | None, requested_decay: float | None) -> float:
        """The decay of this tracker's pose residual: ``requested_decay`` if given; else its own
        with its own scale (``requested_scale`` None), and 1 (a random walk) with a requested one."""
        if requested_decay is not None:
            return float(requested_decay)
        return self.residual_decay if requested_scale is None else 1.0

    def check_budget(self, budget: Budget) -> None:
        """Raise ``ValueError`` if this tracker cannot spend ``budget``."""
        if not self.annealed:
            return
        if budget.layers < self.min_layers:
            raise ValueError(f"{self.label} needs at least {self.min_layers} layers, got {budget.layers}")
        if budget.per_layer < 1:
            raise ValueError(f"a budget of {budget.evaluations} evaluations cannot pay for one particle through {budget.layers} "
                             f"annealing layers of {self.label}" + (f" and {budget.refine_steps} refined moves" if budget.refine_steps
                                                                    else "") + f"; give at least {budget.layers} or fewer --layers")
        if budget.evaluations % budget.layers and not budget.refine_steps:
            raise ValueError(
                f"a budget of {budget.evaluations} likelihood evaluations cannot be split into {budget.layers} equal "
                f"annealing layers for {self.label}; use a multiple of {budget.layers}"
            )


_TRACKERS: Registry[TrackerRecipe] = Registry("tracker", TrackerRecipe, "register_tracker")


def register_tracker(recipe: TrackerRecipe, *, replace: bool = False) -> TrackerRecipe:
    """Add a tracker to the registry (``replace=True`` to redefine a name); returns it."""
    return _TRACKERS.register(recipe, replace=replace)


def unregister_tracker(name: str) -> None:
    """Remove a tracker from the registry."""
    _TRACKERS.unregister(name)


def available_trackers() -> tuple[str, ...]:
    """The registered tracker names, in registration order (the built-in ones first)."""
    return _TRACKERS.names()


def get_tracker(name: str) -> TrackerRecipe:
    """The recipe registered as ``name``; raises ``ValueError`` listing the names otherwise."""
    return _TRACKERS.get(name)


def tracker_index(name: str) -> int:
    """The position of ``name`` in the registry (registration order). Keys do not follow it: a
    tracker's keys follow its name (``tracking.tracker_stream``)."""
    get_tracker(name)
    return _TRACKERS.names().index(name)
