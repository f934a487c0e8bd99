"""Settings of the HumanEva-style experiment (defaults: paper 000 sec. 6.1)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

from ..body import check_height
from ..errors import ConfigurationError
from ..likelihood import DEFAULT_LIKELIHOOD, get_likelihood
from ..manifold import DEFAULT_OPTIMISER, OPTIMISERS, manifold_kinds
from ..tracking import BODY_CHOICES, GRADIENT_COST, PAPER_TRACKERS, Budget, get_tracker


@dataclasses.dataclass(frozen=True)
class ExperimentConfig:
    """Attributes:
        methods: registered tracker names (``jaxtrack.tracking.available_trackers()``).
        budget: likelihood evaluations per frame (one-layer trackers: that many particles;
            annealed ones: ``layers`` layers of ``budget / layers``).
        layers: annealing layers of the annealed trackers (GPAPF's last one is its full-pose
            layer).
        runs: runs per tracker, each with its own key.
        batch_runs: track a tracker's runs on a test sequence in one compiled call (``jax.vmap``
            over the runs' keys; ``tracking.track_runs``): the same runs up to float rounding,
            fewer dispatches; frames/s is then the batch's frames over its time, compile included.
        latent_dim: dimension of every manifold's latent space (None: each tracker's own,
            ``TrackerRecipe.latent_dim``: MRPF 2, GPAPF and LatentPF 3; else the kind's,
            ``ManifoldKind.latent_dim``: 2 for the GP models, 3 for the spectral ones).
            One manifold is fitted per (kind, latent dimension) the trackers need.
        fit_steps: L-BFGS iterations for the manifold.
        fit_optimiser: the manifold fit's L-BFGS (``jaxtrack.manifold.fit_model``): "lbfgs"
            (``manifold.DEFAULT_OPTIMISER``, as ``jaxtrack fit``: one evaluation per loop
            iteration, compiles in about half the time) or "optax" (optax's, zoom line search:
            the tracking tables of docs/trackers.md measured before 2026-11-26).
        likelihood_scale: temperature of the silhouette likelihood, ``ln p = -scale * cost``.
        frames: track only the first ``frames`` frames of each test sequence (None: all).
        seed: base PRNG seed; the tracker named ``m`` runs with keys folded from
            ``fold_in(key(seed), tracking.tracker_stream(m))`` (a hash of its name).
        calibrate_shape: fit the body's capsule radii to each test sequence's first frame at
            its initial pose before tracking (``jaxtrack.likelihood.calibrate_shape``).
        ground_prior: multiply every tracker's likelihood by the ground plane's prior, the feet
            kept out of the floor (``jaxtrack.likelihood.GroundPlanePrior``; the floor at world
            z = 0, the ankle's clearance above it fitted on the validation motion).
        resolution: (width, height) to track at: the test silhouettes are block-averaged down
            to it and the cameras rescaled (None: as recorded).
        pixel_samples: score 000 eq. 12 on this many stratified sample pixels per view and
            frame (``jaxtrack.likelihood.SampledSilhouetteLikelihood``) instead of every pixel
            of the window: a cost independent of the image size (None or 0: every pixel;
            "auto": by the image size tracked at, ``likelihood.default_pixel_samples``: every
            pixel up to 160x120, 2048 up to 320x240, 4096 above).
        body: the test subjects' bodies (``tracking.BODY_CHOICES``): "auto" (the file's
            skeleton, else the one fitted to its joints, else a training or validation take's
            of the same ``subject``, else calibrated from the first frames' silhouettes),
            "joints" (fitted to the joints even over a file's skeleton), "default" (the default
            body, never calibrated) or "calibrate" (limb lengths and radii always fitted to the
            first frames' silhouettes, ``likelihood.calibrate_body``).
        height: the test subjects' standing height in metres, the calibration's prior (None: the
            default proportions, loosely).
        refine_steps: gradient-refined (MALA) moves per particle per frame after the weighting
            (``jaxtrack.filters.LangevinRefinement``), paid for out of ``budget`` at
            ``gradient_cost`` evaluations a gradient (fewer particles); 0 for none.
        gradient_cost: what a likelihood gradient counts as, in evaluations (measured by
            ``benchmarks/bench_gradient.py``).
        velocity: True: every tracker's dynamics carry a Kalman-tracked velocity of the root (in
            its heading frame) and, where the dynamics support it, of the pose (MRPF on a
            BC-GPLVM) or the latent point (latent random walk), fitted on the validation motion
            (``jaxtrack.dynamics.StateVelocity``); False: none does; None: each tracker's own
            (``TrackerRecipe.velocity``: MRPF and LatentPF).
        manifold: the manifold every manifold tracker of its family runs on (a registered kind,
            ``manifold.manifold_kinds(trackable=True)``), or None
            for each tracker's own (``TrackerRecipe.manifold``: the one its paper uses).
        likelihood: the registered likelihood every test scene is tracked with
            (``likelihood.available_likelihoods()``; default the silhouettes' of 000 eq. 12).
        likelihood_options: that likelihood's options (``LikelihoodRecipe.options``).
        residual: the scale of the off-manifold pose residual of every tracker whose pose is
            decoded from a latent point (``jaxtrack.dynamics.PoseResidual``; 0: none), relative
            to the pose random walk's steps; None: each tracker's own (``TrackerRecipe.residual``).
    """

    methods: tuple[str, ...] = PAPER_TRACKERS
    budget: int = 500
    layers: int = 5
    runs: int = 5
    batch_runs: bool = False
    latent_dim: int | None = None
    fit_steps: int = 300
    fit_optimiser: str = DEFAULT_OPTIMISER
    likelihood_scale: float = 100.0
    frames: int | None = None
    seed: int = 0
    calibrate_shape: bool = False
    ground_prior: bool = True
    resolution: tuple[int, int] | None = None
    pixel_samples: int | str | None = "auto"
    body: str = "auto"
    height: float | None = None
    refine_steps: int = 0
    gradient_cost: float = GRADIENT_COST
    velocity: bool | None = None
    manifold: str | None = None
    residual: float | None = None
    likelihood: str = DEFAULT_LIKELIHOOD
    likelihood_options: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        if not self.methods:
            raise ConfigurationError("the experiment needs at least one tracker in methods")
        if len(set(self.methods)) != len(self.methods):
            raise ConfigurationError(f"methods lists a tracker twice: {list(self.methods)}")
        recipes = [get_tracker(m) for m in self.methods]  # unknown names: ValueError listing the registered ones
        if self.runs < 1:
            raise ConfigurationError(f"runs must be positive, got {self.runs}")
        if self.frames is not None and self.frames < 1:
            raise ConfigurationError(f"frames must be positive, got {self.frames}")
        if (self.latent_dim is not None and self.latent_dim < 1) or self.fit_steps < 1:
            raise ConfigurationError("latent_dim and fit_steps must be positive")
        if self.fit_optimiser not in OPTIMISERS:
            raise ConfigurationError(f"fit_optimiser must be one of {OPTIMISERS}, got {self.fit_optimiser!r}")
        if not self.likelihood_scale > 0:
            raise ConfigurationError(f"likelihood_scale must be positive, got {self.likelihood_scale}")
        if self.resolution is not None and (len(self.resolution) != 2 or min(self.resolution) < 1):
            raise ConfigurationError(f"resolution must be (width, height) in pixels, got {self.resolution}")
        if self.pixel_samples not in (None, 0, "auto") and (isinstance(self.pixel_samples, bool)
                                                             or not isinstance(self.pixel_samples, int) or self.pixel_samples < 4):
            raise ConfigurationError(f"pixel_samples must be a whole number >= 4 (per view and frame; one per stratum), 0 or None "
                                     f"(every pixel) or 'auto', got {self.pixel_samples!r}")
        if self.body not in BODY_CHOICES:
            raise ConfigurationError(f"body must be one of {BODY_CHOICES}, got {self.body!r}")
        if self.height is not None:
            try:
                check_height(self.height)
            except ValueError as err:
                raise ConfigurationError(str(err)) from None
        if self.residual is not None and (isinstance(self.residual, bool) or not isinstance(self.residual, (int, float))
                                          or not (math.isfinite(self.residual) and self.residual >= 0)):
            raise ConfigurationError(f"residual must be a scale >= 0 or None (each tracker's own), got {self.residual!r}")
        if self.manifold is not None and self.manifold not in manifold_kinds(trackable=True):
            raise ConfigurationError(f"manifold must be one of {manifold_kinds(trackable=True)} or None (each tracker's own), "
                                     f"got {self.manifold!r}")
        try:
            recipe = get_likelihood(self.likelihood)
        except ValueError as err:
            raise ConfigurationError(str(err)) from None
        unknown = sorted(set(self.likelihood_options) - set(recipe.options))
        if unknown:
            raise ConfigurationError(f"likelihood {self.likelihood!r} takes no option {', '.join(map(repr, unknown))} "
                                     f"(it takes: {', '.join(recipe.options) or 'none'})")
        budget = self.tracking_budget
        for recipe in recipes:
            recipe.check_budget(budget)
            if recipe.needs_manifold:
                recipe.manifold_for(self.manifold)

    def as_dict(self) -> dict:
        """The settings as plain JSON values (results.json's "config")."""
        out = dataclasses.asdict(self)
        out["likelihood_options"] = dict(self.likelihood_options)
        return out

    @property
    def tracking_budget(self) -> Budget:
        """The per-frame ``Budget`` every tracker spends."""
        return Budget(self.budget, self.layers, self.refine_steps, self.gradient_cost)

    @property
    def needs_manifold(self) -> bool:
        return any(get_tracker(m).needs_manifold for m in self.methods)

    def manifold_of(self, method: str) -> str | None:
        """The manifold kind tracker ``method`` runs on (None if it needs none)."""
        recipe = get_tracker(method)
        return recipe.manifold_for(self.manifold) if recipe.needs_manifold else None

    def velocity_of(self, method: str) -> bool:
        """Whether tracker ``method`` carries a Kalman-tracked velocity."""
        return get_tracker(method).velocity_for(self.velocity)

    def residual_of(self, method: str) -> float:
        """The scale of tracker ``method``'s off-manifold pose residual (0: none)."""
        return get_tracker(method).residual_for(self.residual)

    def latent_dim_of(self, method: str) -> int | None:
        """The latent dimension of tracker ``method``'s manifold (None if it needs none)."""
        kind = self.manifold_of(method)
        return None if kind is None else get_tracker(method).latent_dim_for(kind, self.latent_dim)

    def manifold_spec_of(self, method: str) -> tuple[str, int] | None:
        """``(kind, latent_dim)`` of tracker ``method``'s manifold (None if it needs none)."""
        kind = self.manifold_of(method)
        return None if kind is None else (kind, self.latent_dim_of(method))

    @property
    def manifold_specs(self) -> tuple[tuple[str, int], ...]:
        """The ``(kind, latent_dim)`` manifolds the experiment fits, in the order of the methods."""
        return tuple(dict.fromkeys(s for s in map(self.manifold_spec_of, self.methods) if s is not None))

    @property
    def manifold_kinds(self) -> tuple[str, ...]:
        """The manifold kinds the experiment fits, in the order of the methods."""
        return tuple(dict.fromkeys(kind for kind, _ in self.manifold_specs))
