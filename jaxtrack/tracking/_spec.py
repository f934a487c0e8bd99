"""``TrackingSpec``: how to track, in one validated object. Everything between the motion data
and the estimates that a user chooses (the manifold and its fit, the likelihood and the images
it scores, the body, the ground prior, the dynamics' velocity and residual, the budget) is a
field here, checked once when the spec is made. ``jaxtrack.experiment.run_experiment``,
``track_sequence``, the demo and the ``experiment`` and ``track`` commands all build one from
their arguments and read it; ``ExperimentConfig`` is a spec plus the experiment's own settings
(the trackers, runs, frames and seed)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..body import check_height
from ..errors import ConfigurationError
from ..likelihood import DEFAULT_LIKELIHOOD, get_likelihood
from ..manifold import DEFAULT_OPTIMISER, OPTIMISERS, manifold_kinds
from ._registry import GRADIENT_COST, Budget, TrackerRecipe, get_tracker
from ._start import START_CHOICES
from ._subject import BODY_CHOICES, CALIBRATION_PRIORS


def _positive_int(value) -> bool:
    return not isinstance(value, bool) and isinstance(value, int) and value >= 1


@dataclasses.dataclass(frozen=True)
class TrackingSpec:
    """Attributes:
        budget: likelihood evaluations per frame (one-layer trackers: that many particles;
            annealed ones: ``layers`` layers of ``budget / layers``).
        layers: annealing layers of the annealed trackers (GPAPF's last one is its full-pose
            layer).
        refine_steps: gradient-refined (MALA) moves per particle per frame after the weighting
            (``jaxtrack.filters.LangevinRefinement``), paid for out of ``budget`` at
            ``gradient_cost`` evaluations a gradient (fewer particles); 0 for none.
        gradient_cost: what a likelihood gradient counts as, in evaluations (measured by
            ``benchmarks/bench_gradient.py``).
        manifold: the manifold every manifold tracker of its family runs on (a registered kind,
            ``manifold.manifold_kinds(trackable=True)``), or None for each tracker's own
            (``TrackerRecipe.manifold``: the one its paper uses).
        latent_dim: dimension of every manifold's latent space (None: each tracker's own,
            ``TrackerRecipe.latent_dim``: MRPF 2, GPAPF and LatentPF 3; else the kind's,
            ``ManifoldKind.latent_dim``: 2 for the GP models, 3 for the spectral ones).
        fit_steps: L-BFGS iterations for the manifold.
        fit_optimiser: the manifold fit's L-BFGS (``jaxtrack.manifold.fit_model``): "lbfgs"
            (``manifold.DEFAULT_OPTIMISER``: one evaluation per loop iteration, compiles in
            about half the time) or "optax" (optax's, zoom line search: the tracking tables of
            docs/trackers.md measured before 2026-11-26).
        likelihood: the registered likelihood every test scene is tracked with
            (``likelihood.available_likelihoods()``; default the silhouettes' of 000 eq. 12).
        likelihood_options: that likelihood's options (``LikelihoodRecipe.options``).
        likelihood_scale: temperature of the likelihood, ``ln p = -scale * cost``.
        resolution: (width, height) to track at: the test silhouettes are block-averaged down
            to it and the cameras rescaled (None: as recorded).
        pixel_samples: score 000 eq. 12 on this many stratified sample pixels per view and
            frame (``jaxtrack.likelihood.SampledSilhouetteLikelihood``) instead of every pixel
            of the window (None or 0: every pixel; "auto": by the image size tracked at,
            ``likelihood.default_pixel_samples``: every pixel up to 160x120, 2048 up to 320x240,
            4096 above).
        body: the test subjects' bodies (``tracking.BODY_CHOICES``): "auto" (the file's
            skeleton, else the one fitted to its joints, else a training or validation take's
            of the same ``subject``, else calibrated from the first frames' silhouettes),
            "joints" (fitted to the joints even over a file's skeleton), "default" (the default
            body, never calibrated) or "calibrate" (limb lengths and radii always fitted to the
            first frames' silhouettes, ``likelihood.calibrate_body``).
        height: the test subjects' standing height in metres, the calibration's prior (None: the
            default proportions, loosely).
        body_prior: what centres a calibration's prior (``tracking.CALIBRATION_PRIORS``):
            "default" (the default body's proportions, the clavicles at rest; the default),
            "proportions" (the motion model's subjects' proportions, the clavicles at rest) or
            "motion" (their proportions and clavicle posture: best where the person is the motion
            model's subject, worse for others); docs/body.md, "The motion model's subject".
        refine_body: where the body was calibrated from the images, calibrate it a second time on
            one tracker run's estimates at frames spread over the sequence (``tracking.refine_body``:
            the knees and elbows bend there, where the first frames hold them straight), then track
            with the refined body; one more tracking run per calibrated test sequence
            (``track_sequence``: the tracker's own; ``run_experiment``: the first method's). None
            (the default): where the start is given (``start="truth"``: the trackers came within
            3-15 % of the true body's error, from 13-23 %, docs/body.md), not where it is found
            automatically (``start="auto"``: the first run is then off for its first 20-40 frames,
            and the second pass made the filmed scenes' tracks worse, docs/video.md); True or
            False: always or never (``refines_body``).
        calibrate_shape: fit the body's capsule radii to each test sequence's first frame at
            its initial pose before tracking (``jaxtrack.likelihood.calibrate_shape``).
        fit_radii: fit the capsule radii to the silhouettes of 12 frames spread over each test
            sequence at their ground-truth poses, the skeleton kept (``tracking.prepare_test``,
            ``likelihood.fit_radii``). None (the default): where the body is fitted to the file's
            joints, the file has no radii, the start is given (``start="truth"``) and the person is
            45 pixels tall or more
            (the limb calibration's size rule; HumanEva's files: for a subject 20 % thicker than the
            default, MRPF 15.2 -> 12.3 mm and LatentPF 13.0 -> 11.1 at 4 views of 160x120; even on
            a body of another shape: docs/body.md, "The radii of a body fitted to joints"); True
            or False: always (a file with ground truth) or never.
        ground_prior: multiply every tracker's likelihood by the ground plane's prior, the feet
            kept out of the floor (``jaxtrack.likelihood.GroundPlanePrior``; the floor at world
            z = 0, the ankle's clearance above it fitted on the validation motion).
        velocity: True: every tracker's dynamics carry a Kalman-tracked velocity of the root (in
            its heading frame) and, where the dynamics support it, of the pose or the latent
            point, fitted on the validation motion (``jaxtrack.dynamics.StateVelocity``); False:
            none does; None: each tracker's own (``TrackerRecipe.velocity``).
        residual: the scale of the off-manifold pose residual of every tracker whose pose is
            decoded from a latent point (``jaxtrack.dynamics.PoseResidual``; 0: none), relative
            to the pose random walk's steps; None: each tracker's own (``TrackerRecipe.residual``).
        residual_decay: that residual's factor per frame (``dynamics.PoseResidual.decay``): 1, a
            random walk; below 1 it fades back to the manifold, so the filter starts at the given
            pose and ends on its manifold. None: with each tracker's own residual its own decay
            (``TrackerRecipe.residual_decay``), with a ``residual`` named 1.
        residual_target: the joint-angle offset (A,) that residual fades to instead of to the
            manifold (radians; ``dynamics.PoseResidual.target``): the tracked person's mean
            posture less the training motion's (docs/subjects.md, "A person's own posture");
            None: 0.
        gait_rate: the spread (standard deviation of the log) of a per-particle gait rate for
            every tracker on a manifold (``jaxtrack.dynamics.GaitRate``: each particle steps its
            dynamics 0, 1 or 2 times a frame at its own cadence); 0 (the default): none.
            Tried across people and not kept: docs/subjects.md, "Tried: a gait rate per particle".
        start: where ``track_sequence`` and the experiment start (``tracking.START_CHOICES``):
            "truth" (frame 0's ground truth) or "auto" (``tracking.automatic_start``: found from
            the first frame's images on the model's latent space, in the experiment on the
            first manifold its trackers run on, ``experiment.start_manifold``; no ground truth
            needed).

    Raises:
        ConfigurationError: on any setting out of its range, an unknown manifold kind or
            likelihood, or an option the likelihood does not take.
    """

    budget: int = 500
    layers: int = 5
    refine_steps: int = 0
    gradient_cost: float = GRADIENT_COST
    manifold: str | None = None
    latent_dim: int | None = None
    fit_steps: int = 300
    fit_optimiser: str = DEFAULT_OPTIMISER
    likelihood: str = DEFAULT_LIKELIHOOD
    likelihood_options: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    likelihood_scale: float = 100.0
    resolution: tuple[int, int] | None = None
    pixel_samples: int | str | None = "auto"
    body: str = "auto"
    height: float | None = None
    body_prior: str = "default"
    refine_body: bool | None = None
    calibrate_shape: bool = False
    fit_radii: bool | None = None
    ground_prior: bool = True
    velocity: bool | None = None
    residual: float | None = None
    residual_decay: float | None = None
    residual_target: Any = None  # (A,) floats or None; kept as a tuple
    gait_rate: float = 0.0
    start: str = "truth"

    def __post_init__(self):
        if not _positive_int(self.fit_steps) or (self.latent_dim is not None and not _positive_int(self.latent_dim)):
            raise ConfigurationError(f"latent_dim and fit_steps must be positive integers, got {self.latent_dim!r} and {self.fit_steps!r}")
        if self.fit_optimiser not in OPTIMISERS:
            raise ConfigurationError(f"fit_optimiser must be one of {OPTIMISERS}, got {self.fit_optimiser!r}")
        if not (isinstance(self.likelihood_scale, (int, float)) and self.likelihood_scale > 0 and math.isfinite(self.likelihood_scale)):
            raise ConfigurationError(f"likelihood_scale must be a positive number, got {self.likelihood_scale!r}")
        if self.resolution is not None and (len(self.resolution) != 2 or not all(_positive_int(v) for v in self.resolution)):
            raise ConfigurationError(f"resolution must be (width, height) in pixels, got {self.resolution}")
        if self.pixel_samples not in (None, 0, "auto") and (isinstance(self.pixel_samples, bool)
                                                             or not isinstance(self.pixel_samples, int) or self.pixel_samples < 4):
            raise ConfigurationError(f"pixel_samples must be a whole number >= 4 (per view and frame; one per stratum), 0 or None "
                                     f"(every pixel) or 'auto', got {self.pixel_samples!r}")
        if self.refine_body is not None and not isinstance(self.refine_body, bool):
            raise ConfigurationError(f"refine_body must be True, False or None (by the start), got {self.refine_body!r}")
        if self.fit_radii is not None and not isinstance(self.fit_radii, bool):
            raise ConfigurationError(f"fit_radii must be True, False or None (by the file), got {self.fit_radii!r}")
        if self.body not in BODY_CHOICES:
            raise ConfigurationError(f"body must be one of {BODY_CHOICES}, got {self.body!r}")
        if self.body_prior not in CALIBRATION_PRIORS:
            raise ConfigurationError(f"body_prior must be one of {CALIBRATION_PRIORS}, got {self.body_prior!r}")
        if self.start not in START_CHOICES:
            raise ConfigurationError(f"start must be one of {START_CHOICES}, got {self.start!r}")
        if self.height is not None:
            try:
                check_height(self.height)
            except ValueError as err:
                raise ConfigurationError(str(err)) from None
        if self.residual is not None and (isinstance(self.residual, bool) or not isinstance(self.residual, (int, float))
                                          or not (math.isfinite(self.residual) and self.residual >= 0)):
            raise ConfigurationError(f"residual must be a scale >= 0 or None (each tracker's own), got {self.residual!r}")
        if self.residual_decay is not None and (isinstance(self.residual_decay, bool)
                                                or not isinstance(self.residual_decay, (int, float)) or not 0 < self.residual_decay <= 1):
            raise ConfigurationError(f"residual_decay must be a number in (0, 1], got {self.residual_decay!r}")
        if isinstance(self.gait_rate, bool) or not isinstance(self.gait_rate, (int, float)) or not (
                math.isfinite(self.gait_rate) and 0 <= self.gait_rate <= 1):
            raise ConfigurationError(f"gait_rate must be a spread in [0, 1] (0: none), got {self.gait_rate!r}")
        if self.residual_target is not None:
            target = np.asarray(self.residual_target)
            if target.ndim != 1 or not target.size or target.dtype.kind not in "fiu" or not np.all(np.isfinite(target)):
                raise ConfigurationError("residual_target must be one finite offset per joint angle (radians), "
                                         f"got {self.residual_target!r}")
            object.__setattr__(self, "residual_target", tuple(float(v) for v in target))
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
        try:
            self.tracking_budget  # noqa: B018 (validates the budget's numbers)
        except ValueError as err:
            raise ConfigurationError(str(err)) from None

    @property
    def tracking_budget(self) -> Budget:
        """The per-frame ``Budget`` every tracker spends."""
        return Budget(self.budget, self.layers, self.refine_steps, self.gradient_cost)

    def refines_body(self, scene) -> bool:
        """Whether ``scene`` (``prepare_test``'s) gets the second body pass: only a body calibrated
        from the images, and by ``refine_body`` (None: where the start is given)."""
        if scene.body_calibration is None:
            return False
        return self.start == "truth" if self.refine_body is None else self.refine_body

    def tracking_fields(self) -> dict:
        """This spec's own fields (a subclass's extra settings left out)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(TrackingSpec)}

    @property
    def spec(self) -> TrackingSpec:
        """The tracking spec alone (for an ``ExperimentConfig``: without the experiment's own settings)."""
        return TrackingSpec(**self.tracking_fields())

    def as_dict(self) -> dict:
        """The settings as plain JSON values (results.json's "config")."""
        out = dataclasses.asdict(self)
        out["likelihood_options"] = dict(self.likelihood_options)
        return out

    def check_method(self, method: str) -> TrackerRecipe:
        """The recipe of tracker ``method`` if it can run under this spec (its budget, its
        manifold); raises ``ValueError`` otherwise (an unknown name lists the registered ones)."""
        recipe = get_tracker(method)
        recipe.check_budget(self.tracking_budget)
        if recipe.needs_manifold:
            recipe.manifold_for(self.manifold)
        return recipe

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

    def residual_decay_of(self, method: str) -> float:
        """The factor per frame of tracker ``method``'s pose residual (1: a random walk)."""
        return get_tracker(method).residual_decay_for(self.residual, self.residual_decay)

    def residual_target_of(self, method: str):
        """(A,) the offset tracker ``method``'s pose residual fades to, or None (0; also for a
        tracker without a residual)."""
        return np.asarray(self.residual_target, np.float64) if self.residual_target is not None and self.residual_of(method) else None

    def gait_rate_of(self, method: str) -> float:
        """The spread of tracker ``method``'s per-particle gait rate (0: none; only trackers on a
        manifold carry one)."""
        return float(self.gait_rate) if get_tracker(method).needs_manifold else 0.0

    def latent_dim_of(self, method: str) -> int | None:
        """The latent dimension of tracker ``method``'s manifold (None if it needs none)."""
        kind = self.manifold_of(method)
        return None if kind is None else get_tracker(method).latent_dim_for(kind, self.latent_dim)

    def manifold_spec_of(self, method: str) -> tuple[str, int] | None:
        """``(kind, latent_dim)`` of tracker ``method``'s manifold (None if it needs none)."""
        kind = self.manifold_of(method)
        return None if kind is None else (kind, self.latent_dim_of(method))

    def scene_options(self) -> dict:
        """The keyword arguments of ``prepare_test`` this spec decides (the likelihood, its
        images and the body)."""
        return {"likelihood_scale": self.likelihood_scale, "calibrate": self.calibrate_shape, "fit_radii": self.fit_radii,
                "resolution": self.resolution,
                "pixel_samples": self.pixel_samples, "body": self.body, "height": self.height,
                "calibration_prior": self.body_prior, "likelihood": self.likelihood,
                "likelihood_options": dict(self.likelihood_options)}
