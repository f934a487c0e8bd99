"""The tracking pipeline, sequence -> poses -> manifold -> dynamics -> likelihood -> tracker ->
estimates, as a friendly layer over the pure core.

Precision is decided here, once: manifolds and dynamics are fitted in float64, then cast to
float32 (``TRACKING_DTYPE``) at ``build_tracker``; the likelihood and the filters run in
float32; estimates come back as float64 NumPy arrays for the metrics.
"""

from __future__ import annotations

import dataclasses
import itertools
import sys
import time
import zlib
from collections.abc import Mapping
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Key, PRNGKeyArray
from .._tree import cast_floating
from .._validation import check_key
from ..body import (
    GLOBAL_DOFS,
    HUMANEVA_JOINTS,
    check_height,
    forward_kinematics,
    humaneva_body,
    inverse_kinematics,
    joint_angles,
    limb_lengths_for_height,
)
from ..camera import check_in_view
from ..dynamics import AbstractDynamics, GaitRate, VelocityFit, fit_pose_residual, fit_state_velocity
from ..errors import ConfigurationError
from ..filters import AbstractComposedFilter, LangevinRefinement, continue_filter, run_filter
from ..io import Sequence, check_keypoints
from ..likelihood import (
    DEFAULT_LIKELIHOOD,
    BodyCalibration,
    ObservationPart,
    SampledSilhouetteLikelihood,
    SceneInputs,
    SilhouetteLikelihood,
    SumLikelihood,
    body_of,
    calibrate_body,
    calibrate_body_from_keypoints,
    calibrate_shape,
    check_silhouettes,
    default_pixel_samples,
    get_likelihood,
    ground_clearance,
    has_evidence,
    keypoint_terms,
    make_ground_prior,
    maps_from_images,
    maps_from_silhouettes,
    sample_frames,
    set_references,
    with_body,
)
from ..likelihood import (
    fit_radii as fit_capsule_radii,
)
from ..manifold import DEFAULT_OPTIMISER, SpectralEmbedding, get_manifold_kind, to_prior
from ._dynamics_motion import dynamics_motion
from ._limb_measurement import LimbMeasurement, measure_limb_lengths
from ._off_manifold import OFF_MANIFOLD_START_MM, start_off_manifold_mm
from ._refine_body import refine_frame_count, spread_frames, track_and_refine_body
from ._registry import FADING_START, Budget, MotionData, TrackerRecipe
from ._spec import TrackingSpec
from ._start import START_CHOICES, PoseSamples, StartSearch, automatic_start
from ._subject import (
    CALIBRATION_PRIORS,
    OWN_BODY_SOURCES,
    SubjectBody,
    leg_length,
    limb_lengths_of,
    motion_subjects_prior,
    subject_body,
)

TRACKING_DTYPE = jnp.float32
FIT_KEY_TAG = 2**31 - 1  # fold_in tag of a tracker's dynamics-fit key (its runs use tags 0, 1, ...)
PIXEL_SAMPLE_TAG = 2**31 - 2  # fold_in tag of a test scene's pixel-sample key
START_TAG = 2**31 - 3  # fold_in tag of the automatic start's search key
RADII_SAMPLE_TAG = 2**31 - 4  # fold_in tag of the pixels the capsule radii are fitted on
CALIBRATION_SAMPLE_TAG = 2**31 - 5  # fold_in tag of the pixels the body is calibrated on
START_SAMPLE_TAG = 2**31 - 6  # fold_in tag of the pixels the automatic start searches on



def sequence_poses(sequence: Sequence, name: str, *, key: PRNGKeyArray) -> np.ndarray:
    """The (T, D) pose vectors of a sequence (float64) on its own body (``subject_body``): its
    ``pose`` key with its skeleton, else inverse kinematics on ``joints3d`` (``key`` seeds the IK's
    restarts), fitting the skeleton when the file has none."""
    resolved = subject_body(sequence, name, key=key)
    if resolved.poses is None:
        raise ValueError(f"{name}: needs 'pose' or 'joints3d' (ground truth) for the experiment")
    return resolved.poses


def ground_truth_joints(sequence: Sequence, poses: np.ndarray, skeleton) -> np.ndarray:
    """The (T, J, 3) ground-truth joints: the file's ``joints3d``, else forward kinematics."""
    if sequence.joints3d is not None:
        return np.asarray(sequence.joints3d, np.float64)
    return np.asarray(forward_kinematics(skeleton, jnp.asarray(poses, skeleton.offsets.dtype)), np.float64)


def check_test_sequence(sequence: Sequence, name: str, observes: tuple[str, ...] = ("silhouettes",), *,
                        truth: bool = True, likelihood: str | None = None) -> None:
    """A test sequence needs the observations its likelihood reads (``observes``: silhouettes,
    keypoints, and edge and foreground maps, which are made from the silhouettes and images),
    cameras and (with ``truth``) ground truth; raise ``ValueError`` if not, naming the
    ``likelihood`` that reads them where given."""
    present = {"silhouettes": sequence.silhouettes is not None, "keypoints": sequence.keypoints2d is not None,
               "cameras": sequence.has_cameras, "images": sequence.images is not None}
    keys = {"silhouettes": "silhouettes", "keypoints": "keypoints2d", "cameras": "camera_K, camera_R, camera_t, image_size",
            "images": "images"}
    needed = ["silhouettes" if kind in ("edges", "foreground") else kind for kind in observes]
    needed = list(dict.fromkeys([*needed, "cameras"]))
    missing = [what for what in needed if not present[what]]
    if missing:
        who = "a test sequence" if likelihood is None else f"a test sequence tracked with the {likelihood} likelihood"
        raise ValueError(f"{name}: {who} needs {' and '.join(missing)}, which the file lacks (key"
                         f"{'s' if len(missing) > 1 else ''} {'; '.join(keys[m] for m in missing)})")
    if truth and sequence.joints3d is None and sequence.pose is None:
        raise ValueError(f"{name}: a test sequence needs ground truth ('joints3d' or 'pose') to be scored")


def keypoint_height_pixels(keypoints) -> float:
    """The median over views of the confident (> 0.5) keypoints' vertical extent in pixels,
    keypoints (C, 15, 3); about 0.9 of the person's height (the head joint is not the crown)."""
    heights = []
    for view in np.asarray(keypoints):
        v = view[view[:, 2] > 0.5, 1]
        heights.append(float(np.ptp(v)) if v.size >= 2 else 0.0)
    return float(np.median(heights))


def check_frame_rates(sequences, names, *, tolerance: float = 0.01) -> None:
    """Raise ``ValueError`` unless every sequence has the same frame rate (within ``tolerance``,
    relative): dynamics fitted at one rate do not describe motion sampled at another."""
    rates = [float(s.fps) for s in sequences]
    for rate, name in zip(rates[1:], names[1:]):
        if abs(rate - rates[0]) > tolerance * rates[0]:
            raise ValueError(f"{name} is at {rate:g} Hz but {names[0]} at {rates[0]:g} Hz: the dynamics are fitted at one frame "
                             "rate and track at it; resample with 'jaxtrack convert --fps'")


def fit_manifold(train_poses: list[np.ndarray], latent_dim: int | None, steps: int, *, kind: str = "bc-gplvm",
                 progress: bool = False, optimiser: str = DEFAULT_OPTIMISER, key: PRNGKeyArray | None = None, **options):
    """A manifold of the joint angles of the training pose sequences (the global DOFs dropped),
    in float64: the registered manifold ``kind`` (``manifold.get_manifold_kind``: a BC-GPLVM,
    000 eqs. 21-22; a GPDM, 001 eqs. 5-11; an LE, temporal LE or GLE embedding with its RBF
    networks, 002, fitted in closed form; or a kind of your own) made with ``options`` and
    ``key`` (for kinds with random initialisation), then fitted by ``model.fit`` (``steps``
    L-BFGS iterations with ``optimiser``, ``manifold.fit_model``). ``jaxtrack fit`` and
    ``jaxtrack experiment`` both fit through this function. ``latent_dim`` None: the kind's own.

    Returns:
        ``(model, FitInfo, training_starts)``.
    """
    recipe = get_manifold_kind(kind)
    if not isinstance(train_poses, (list, tuple)) or not train_poses:
        shape = f" of shape {np.shape(train_poses)}" if hasattr(train_poses, "shape") else ""
        raise TypeError(f"train_poses must be a non-empty list of (frames, dofs) pose arrays, one per sequence; got "
                        f"{type(train_poses).__name__}{shape} (one sequence: pass [poses])")
    angles = [joint_angles(np.asarray(p, np.float64)) for p in train_poses]
    starts = tuple(int(v) for v in np.cumsum([0] + [len(p) for p in train_poses]))
    with jax.enable_x64(True):
        model = recipe.build(angles, latent_dim, key=key, **options)
        fitted, info = model.fit(max_steps=steps, progress=progress, optimiser=optimiser)
    return fitted, info, starts


def motion_data(train_poses, validation_poses, model=None, training_starts=None, stored=None) -> MotionData:
    """The ``MotionData`` the trackers' dynamics are fitted on (float64), with the manifold
    ``model`` precomputed for tracking when one is given, and what its file ``stored`` beside it
    (the header's ``extra``)."""
    manifold = None
    if model is not None:
        with jax.enable_x64(True):
            manifold = to_prior(model, validation_poses[0].shape[1] - model.data_dim)
    return MotionData(
        training=tuple(np.asarray(p, np.float64) for p in train_poses),
        validation=tuple(np.asarray(p, np.float64) for p in validation_poses),
        manifold=manifold,
        training_starts=training_starts,
        model=model,
        stored=dict(stored or {}),
    )


def fit_tracker(recipe: TrackerRecipe, key: PRNGKeyArray, motion: MotionData):
    """The tracker's fitted dynamics (float64)."""
    if recipe.needs_manifold and motion.manifold is None:
        raise ValueError(f"{recipe.label} needs a fitted manifold; none was given")
    with jax.enable_x64(True):
        return recipe.fit(key, motion)


def build_tracker(recipe: TrackerRecipe, fitted, likelihood, budget: Budget, refinement: LangevinRefinement | None = None,
                  velocity_from: list[np.ndarray] | tuple[np.ndarray, ...] | None = None,
                  residual_from: list[np.ndarray] | tuple[np.ndarray, ...] | None = None, residual_scale: float = 0.0,
                  residual_decay: float = 1.0, residual_target=None, gait_rate: float = 0.0):
    """The tracker's filter on the fitted dynamics cast to ``TRACKING_DTYPE`` (the one cast).

    With ``velocity_from`` (validation pose arrays, (T >= 3, D) each) the filter's dynamics
    carry a Kalman-tracked velocity (``jaxtrack.dynamics.StateVelocity``) of the state
    entries they support (``velocity_states``: the root for every dynamics, the pose for MRPF,
    the latent point for a latent random walk), fitted on those poses by ``fit_velocity``:
    any tracker whose filter is an ``AbstractComposedFilter`` (``SIR``, ``APF``: it takes new
    dynamics by ``with_dynamics``) moves with the body instead of diffusing behind it.

    With ``residual_scale`` > 0 the dynamics (inside the velocity) carry an off-manifold pose
    residual (``jaxtrack.dynamics.PoseResidual``) whose steps are ``residual_scale`` times the
    RMS joint-angle steps of the ``residual_from`` poses, and which fades by ``residual_decay`` a
    frame (1: a random walk) to ``residual_target`` ((A,) joint-angle offset, radians; None: 0).

    With ``gait_rate`` > 0 the fitted dynamics (inside the residual and the velocity) are
    stepped at a per-particle cadence whose log has that spread (``jaxtrack.dynamics.GaitRate``).

    With ``budget.refine_steps`` > 0 the filter gets gradient-refined moves,
    ``refinement`` (default ``LangevinRefinement(budget.refine_steps)``), given by the filter's
    ``with_refinement``: any ``AbstractComposedFilter`` on refinable dynamics
    (``dynamics.is_refinable``) can be refined."""
    recipe.check_budget(budget)
    tracker = recipe.build(cast_floating(fitted, TRACKING_DTYPE), likelihood, budget)
    if residual_target is not None and not residual_scale:
        raise ValueError("a residual target needs a pose residual (residual_scale > 0)")
    wants = [what for what, wanted in (("a pose residual", residual_scale), ("a velocity", velocity_from is not None),
                                       ("a gait rate", gait_rate), ("refined moves", budget.refine_steps)) if wanted]
    if wants and not isinstance(tracker, AbstractComposedFilter):
        raise ValueError(f"{recipe.label}'s filter ({type(tracker).__name__}) is not an AbstractComposedFilter (a dynamics and a "
                         f"likelihood it can take new ones of), so it cannot be given {' or '.join(wants)}")
    if gait_rate:
        tracker = tracker.with_dynamics(GaitRate(tracker.dynamics, spread=float(gait_rate)))
    if residual_scale:
        if residual_from is None:
            raise ValueError(f"a pose residual for {recipe.label} needs validation poses to fit it on")
        with jax.enable_x64(True):
            residual = fit_pose_residual(tracker.dynamics, [np.asarray(p, np.float64) for p in residual_from], residual_scale,
                                         decay=residual_decay, target=residual_target)
        tracker = tracker.with_dynamics(cast_floating(residual, TRACKING_DTYPE))
    if velocity_from is not None:
        velocity = fit_velocity(tracker.dynamics, velocity_from)
        tracker = tracker.with_dynamics(cast_floating(velocity, TRACKING_DTYPE).wrap(tracker.dynamics))
    if not budget.refine_steps:
        return tracker
    refinement = LangevinRefinement(budget.refine_steps) if refinement is None else refinement
    if refinement.num_steps != budget.refine_steps:
        raise ValueError(f"the refinement makes {refinement.num_steps} moves, the budget pays for {budget.refine_steps}")
    return tracker.with_refinement(refinement)


def build_for_start(recipe: TrackerRecipe, fitted, likelihood, budget: Budget, *, start_pose, skeleton, key,
                    residual_scale: float = 0.0, residual_decay: float = 1.0, say=None, name: str = "", **options):
    """``build_tracker``, and where the tracker decodes its pose from a latent point, carries no
    pose residual and would start more than ``OFF_MANIFOLD_START_MM`` from ``start_pose`` (its
    projection onto the manifold), the same tracker with the fading start (``FADING_START``), said
    to ``say``.

    Returns:
        ``(tracker, distance)``: ``distance`` the start's projection's distance from ``start_pose``
        (mm, mean over ``skeleton``'s joints), or None where it was not measured (a tracker that
        takes no residual, or one that carries one).
    """
    tracker = build_tracker(recipe, fitted, likelihood, budget, residual_scale=residual_scale, residual_decay=residual_decay,
                            **options)
    if residual_scale or recipe.residual is None:
        return tracker, None
    distance = start_off_manifold_mm(tracker.dynamics, start_pose, skeleton, key)
    if distance <= OFF_MANIFOLD_START_MM:
        return tracker, distance
    if say is not None:
        say(f"{name + ': ' if name else ''}{recipe.label} would start {distance:.0f} mm from frame 0's pose (its projection onto "
            f"the manifold; over {OFF_MANIFOLD_START_MM:.0f} mm): it starts from the pose itself, with the latent point that "
            "decodes nearest to it, and fades onto its manifold (a fading pose residual)")
    return build_tracker(recipe, fitted, likelihood, budget, residual_scale=FADING_START[0], residual_decay=FADING_START[1],
                         **options), distance


def fit_velocity(dynamics: AbstractDynamics, validation_poses: list[np.ndarray] | tuple[np.ndarray, ...]) -> VelocityFit:
    """The velocity ``dynamics`` supports (``fit_state_velocity``), fitted in float64 on the
    validation poses."""
    with jax.enable_x64(True):
        return fit_state_velocity(cast_floating(dynamics, jnp.float64), [np.asarray(p, np.float64) for p in validation_poses])


@dataclasses.dataclass(frozen=True)
class TestScene:
    """A test sequence ready to track: float32 likelihood and observations, the initial pose,
    and the float64 ground truth.

    ``subject`` says where the body came from (``SubjectBody``: file, fitted to joints, training
    take, default) and ``body_calibration`` what the calibration from the images did (then the
    body's source is "calibrated"); ``start_error_mm`` is the initial pose's mean joint error
    against the ground truth of frame 0 (000 eq. 31): a body or start fault shows there before
    any tracking."""

    likelihood: object
    observations: object  # (T, C, H, W) float32 silhouettes, or a PixelSample with a leading T axis
    initial_pose: jax.Array  # (D,) float32
    truth_poses: np.ndarray | None  # (T, D); None: a file without ground truth (started automatically)
    truth_joints: np.ndarray | None  # (T, J, 3)
    body: object
    shape_calibration: object = None  # a ShapeCalibration when the body was calibrated
    ground_prior: object = None  # the GroundPlanePrior the likelihood includes, if any (``add_ground_prior``)
    subject: SubjectBody | None = None
    body_calibration: BodyCalibration | None = None
    start_error_mm: float = float("nan")
    pixel_samples: int | None = None
    limb_measurement: LimbMeasurement | None = None  # the limbs measured on the keypoints, which narrowed the calibration's prior

    @property
    def num_frames(self) -> int:
        return int(jax.tree.leaves(self.observations)[0].shape[0])

    @property
    def body_source(self) -> str:
        """Where the body came from: one of ``BODY_SOURCES``."""
        if self.body_calibration is not None:
            return "calibrated"
        return "default" if self.subject is None else self.subject.source

    def body_summary(self) -> dict:
        """For results.json: the body's source, limb lengths (mm), radii, IK residual, calibration."""
        out = {} if self.subject is None else self.subject.summary()
        out["source"] = self.body_source
        out["limb_lengths_mm"] = {k: round(1000 * v, 1) for k, v in limb_lengths_of(self.body).items()}
        out["capsule_radii_mm"] = dict(zip(self.body.capsule_names, np.round(1000 * np.asarray(self.body.radii, np.float64), 1).tolist()))
        if self.body_calibration is not None:
            out["calibration"] = self.body_calibration.summary()
        if self.limb_measurement is not None:
            out["limbs_measured_on_keypoints_mm"] = {
                limb: {"length": round(1000 * value, 1), "standard_error": round(1000 * self.limb_measurement.standard_errors[limb], 1)}
                for limb, value in self.limb_measurement.lengths.items()}
        out["start_error_mm"] = self.start_error_mm
        return out


CALIBRATION_FRAMES = 4  # frames the body calibration fits (the first ones, their poses free)
# The ankle's clearance above the floor during the calibration when none is measured (metres): an
# adult's ankle joint stands 6-8 cm above the sole. Without the floor, foot shadows stretch the
# shins (docs/body.md, "The floor band").
CALIBRATION_CLEARANCE = 0.06
# How the report of a calibrated body names what it was fitted to (``BodyCalibration.cues``).
CUES_SAID = {"all": "", "keypoint lengths": " (the lengths from the keypoints, the radii from every cue)",
             "keypoints": " (from the keypoints alone)"}


# The person's height in pixels (median over the views, frame 0) under which ``body="auto"`` does
# not calibrate limb lengths: in the default rig at 80x60 (a person 29 pixels tall) the calibrated
# start was worse than the default body's (docs/body.md); at 160x120 (55 pixels) it was better on
# clean views.
MIN_CALIBRATION_PIXELS = 45
# Frames spread over a scene that ``prepare_test(fit_radii=...)`` fits the capsule radii on, at the poses
# the file's joints give (docs/body.md, "The radii of a body fitted to joints").
RADII_FRAMES = 12


def person_height_pixels(masks) -> float:
    """The median over views of the silhouettes' bounding-box height in pixels, masks (C, H, W)."""
    rows = np.any(np.asarray(masks) > 0, axis=-1)  # (C, H)
    heights = [np.ptp(np.flatnonzero(r)) + 1 if r.any() else 0 for r in rows]
    return float(np.median(heights))


def _start_pose(sequence: Sequence, body_model, pose, key, start: str = "truth") -> np.ndarray:
    """The start pose on a new body: with ``start="truth"``, frame 0's joints solved on its
    skeleton when the file has them (the given start is joint positions), else ``pose``."""
    if sequence.joints3d is None or start != "truth":
        return np.asarray(pose, np.float64)
    return np.asarray(inverse_kinematics(sequence.joints3d[:1], skeleton=body_model.skeleton, key=key, dtype=jnp.float64).pose[0])


def _is_silhouette_part(term) -> bool:
    return isinstance(term, ObservationPart) and term.key == "silhouettes" and isinstance(term.term, SilhouetteLikelihood)


def _samples_pixels(likelihood) -> bool:
    """Whether the likelihood's silhouettes can be scored on sampled pixels: a
    ``SilhouetteLikelihood``, one on the ``"silhouettes"`` entry of the frame, or a sum with one."""
    return isinstance(likelihood, SilhouetteLikelihood) or _is_silhouette_part(likelihood) or (
        isinstance(likelihood, SumLikelihood) and any(_is_silhouette_part(t) for t in likelihood.terms))


def _on_sampled_pixels(likelihood, observations, key, samples: int):
    """The likelihood and observations with the silhouettes scored on ``samples`` stratified
    pixels per view and frame (``_samples_pixels`` must hold)."""
    sampled = _sampled(observations, key, samples)
    if isinstance(likelihood, SilhouetteLikelihood):
        return SampledSilhouetteLikelihood.from_dense(likelihood), sampled
    if _is_silhouette_part(likelihood):
        return ObservationPart(SampledSilhouetteLikelihood.from_dense(likelihood.term), likelihood.key), sampled
    terms = tuple(ObservationPart(SampledSilhouetteLikelihood.from_dense(t.term), t.key) if _is_silhouette_part(t) else t
                  for t in likelihood.terms)
    return SumLikelihood(terms), sampled


def _pixel_samples(requested, likelihood, likelihood_name, width, height, name, say) -> int | None:
    """The pixels per view and frame the scene's silhouette likelihood scores (None: all)."""
    sampled = _samples_pixels(likelihood)
    if requested == "auto":
        requested = default_pixel_samples(width, height) if sampled else None
        say(f"{name}: {width}x{height} images: the {likelihood_name} likelihood scores "
            + ("every pixel of its window" if requested is None else f"{requested} sampled pixels per view and frame")
            + ("" if sampled else " (pixel sampling applies to the silhouette likelihood only)")
            + " (--pixel-samples to choose)")
    if requested and not sampled:
        raise ValueError(f"--pixel-samples {requested}: the {likelihood_name} likelihood ({type(likelihood).__name__}) "
                         "does not score sampled pixels; pixel sampling applies to the silhouette likelihood")
    return requested or None


def _checked_cues(sequence: Sequence, rig, frames: int, name: str, silhouette_dtype=np.float32):
    """The first ``frames`` frames' silhouettes and keypoints (C, T, ...), checked (None where absent)."""
    observed = (None if sequence.silhouettes is None
                else check_silhouettes(sequence.silhouettes, rig, name=f"{name} silhouettes", dtype=silhouette_dtype)[:, :frames])
    keypoints = None if sequence.keypoints2d is None else check_keypoints(sequence.keypoints2d, rig.num_views,
                                                                            where=f"{name} keypoints2d")[:, :frames]
    return observed, keypoints


def _cues(recipe, sequence: Sequence, observed, keypoints, frames: int, likelihood_options) -> dict:
    """Every cue a likelihood may read, (C, T, ...) each (None where it reads none): the
    silhouettes, the keypoints, 001's edge and foreground maps (from the images' edges where the
    sequence has images), the images in [0, 1]."""
    edges = foreground = None
    if {"edges", "foreground"} & set(recipe.observes):
        images = None if sequence.images is None else sequence.images[:, :frames]
        chosen = {**recipe.options, **dict(likelihood_options or {})}
        edges, foreground = (maps_from_silhouettes(observed) if images is None else maps_from_images(
            images, observed, colour=bool(chosen.get("edge_colour", False)), near=int(chosen.get("edges_near", 0))))
        edges, foreground = np.asarray(edges), np.asarray(foreground)
    images = np.asarray(sequence.images[:, :frames], np.float32) / 255.0 if "images" in recipe.observes else None
    return {"silhouettes": observed, "keypoints": keypoints, "edges": edges, "foreground": foreground, "images": images}


def _per_frame(recipe, cues: dict):
    """The observations the likelihood reads, frame axis first: (T, C, ...) of its one cue, or a
    dict of them."""
    per_frame = {kind: np.moveaxis(cues[kind], 1, 0) for kind in recipe.observes}
    return per_frame[recipe.observes[0]] if len(recipe.observes) == 1 else per_frame


def _sampled(observations, key, samples: int):
    """The observations with their silhouettes on ``samples`` stratified pixels per view and frame."""
    if isinstance(observations, dict):
        return {**observations, "silhouettes": sample_frames(key, observations["silhouettes"], samples=samples)}
    return sample_frames(key, observations, samples=samples)


def segment_observations(scene: TestScene, sequence: Sequence, likelihood: str, likelihood_options=None, *, key: PRNGKeyArray,
                         name: str = "test"):
    """The observations of another segment of a stream whose first segment made ``scene``
    (``prepare_test`` with the likelihood named ``likelihood``): the same cues, on pixels sampled
    with ``key`` where the scene's are (``scene.pixel_samples``), ready for
    ``filters.continue_filter``."""
    recipe = get_likelihood(likelihood)
    rig = sequence.rig(dtype=TRACKING_DTYPE)
    # sampled from bytes (the same samples: sample_pixels reads observed > 0.5), not a float32 copy 4 times their size
    sampled_only = scene.pixel_samples is not None and not {"edges", "foreground"} & set(recipe.observes)
    observed, keypoints = _checked_cues(sequence, rig, sequence.num_frames, name, np.uint8 if sampled_only else np.float32)
    observations = jax.tree.map(jnp.asarray, _per_frame(recipe, _cues(recipe, sequence, observed, keypoints, sequence.num_frames,
                                                                       likelihood_options)))
    return observations if scene.pixel_samples is None else _sampled(observations, key, scene.pixel_samples)


def prepare_test(sequence: Sequence, name: str, *, key: PRNGKeyArray, frames: int | None = None, likelihood_scale: float = 100.0,
                 window="auto", calibrate: bool = False, resolution: tuple[int, int] | None = None,
                 pixel_samples: int | str | None = None, body: str = "auto", height: float | None = None, donors=(),
                 calibration_frames: int = CALIBRATION_FRAMES, ground_clearance: float | None = None, say=None,
                 likelihood: str = DEFAULT_LIKELIHOOD, likelihood_options: Mapping[str, Any] | None = None,
                 start: str = "truth", start_model=None, root_height: float | None = None, root_height_legs: float | None = None,
                 start_search: StartSearch | None = None, fit_radii: bool | None = None,
                 calibration_prior: str = "default") -> TestScene:
    """Validate a test sequence and build its likelihood and observations (the first
    ``frames`` frames (at most the sequence's), all when None).

    The body (``subject_body``): ``body="auto"`` takes the file's skeleton, else the one fitted
    to its ``joints3d``, else that of a ``donors`` take of the same ``subject``, else calibrates
    the default from the first ``calibration_frames`` frames' silhouettes
    (``likelihood.calibrate_body``: limb lengths, radii and those frames' poses, from the given
    start pose, the feet kept out of the floor by the ground plane's prior at
    ``ground_clearance``, default ``CALIBRATION_CLEARANCE``; with 2-D keypoints beside the
    silhouettes, ``likelihood.calibrate_body_from_keypoints``: the limb lengths from the keypoints,
    the radii from every cue; where the keypoints' fit is refused, every cue at once), the limb lengths' prior centred on
    the default proportions (``calibration_prior="default"``), or on the ``donors``' (the motion
    model's subjects, ``motion_subjects_prior``: ``"proportions"``), the clavicles then at rest,
    or held at the donors' mean posture as well (``"motion"``; docs/body.md, "The motion model's
    subject"), scaled to ``height`` when it is given, and narrowed by the limb lengths measured on
    every tracked frame's keypoints where two views or more see them (``measure_limb_lengths``:
    triangulated, the noise's bias removed; docs/body.md, "Limb lengths measured over every
    frame"); ``"calibrate"`` always calibrates, ``"default"`` never (the
    default body, poses solved on it), ``"joints"`` fits to the joints even over a file's
    skeleton. ``fit_radii``: the capsule radii fitted to the silhouettes of ``RADII_FRAMES`` frames
    spread over the scene at their ground-truth poses, the skeleton kept (``likelihood.fit_radii``);
    None: where the body is the one fitted to the file's joints, the file gives no
    ``capsule_radii`` (HumanEva's case: joints, not the person's girth), the start is given
    (``start="truth"``: an automatic start uses no ground-truth pose) and the person is at least
    ``MIN_CALIBRATION_PIXELS`` tall (at 80x60 the fit changed nothing: docs/body.md). With ``calibrate``, the
    capsule radii alone are fitted to the first frame at the initial pose
    (``likelihood.calibrate_shape``). With ``resolution`` = (width, height), the
    silhouettes are block-averaged down to it and the cameras rescaled (``Sequence.resized``). With
    ``pixel_samples`` = n, the likelihood (or its silhouette term) is the ``SampledSilhouetteLikelihood`` on n stratified
    pixels per view and frame (``sample_frames`` with ``fold_in(key, PIXEL_SAMPLE_TAG)``, drawn
    once for the scene, after any calibration) and the observations are the ``PixelSample``;
    ``"auto"``: by the image size (``likelihood.default_pixel_samples``); None or 0: every pixel
    (pixel sampling applies to the silhouette likelihood only). ``likelihood`` names the
    registered likelihood (``likelihood.get_likelihood``; default the silhouettes' of 000 eq.
    12) built with ``likelihood_options``. ``say`` (e.g. ``print``) is told what was chosen.

    ``start="truth"`` starts from frame 0's ground truth; ``"auto"`` finds the start from the
    first frame's images (``automatic_start`` on ``start_model``'s latent space with the root
    at ``root_height``, scaled by the person's legs over ``root_height_legs`` (the leg length,
    ``leg_length``, of the body it was measured on) where the body is the person's own
    (``OWN_BODY_SOURCES``); before any body calibration, which then starts from it), and a file
    without ground truth is accepted (the scene's ``truth_poses`` and ``truth_joints`` are then
    None)."""
    check_key(key)
    say = say or (lambda *a, **k: None)
    recipe = get_likelihood(likelihood)
    check_test_sequence(sequence, name, recipe.observes, truth=start == "truth", likelihood=recipe.name)
    if calibrate and "silhouettes" not in recipe.observes:
        raise ConfigurationError(f"{name}: --calibrate fits the capsule radii to silhouettes; the {recipe.name} likelihood "
                                 "reads none")
    if height is not None:
        check_height(height)
    total = sequence.num_frames
    if frames is not None and (isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or frames < 1):
        raise ValueError(f"{name}: frames must be a whole number of frames, 1 or more (None: all {total}), got {frames!r}")
    frames = total if frames is None else min(int(frames), total)
    if resolution is not None:
        sequence = sequence.resized(*resolution)
    rig = sequence.rig(dtype=TRACKING_DTYPE)
    width, image_height = (int(v) for v in sequence.image_size[0])
    if isinstance(pixel_samples, str) and pixel_samples != "auto":
        raise ValueError(f"pixel_samples must be a whole number, 'auto' or None, got {pixel_samples!r}")
    if start not in START_CHOICES:
        raise ValueError(f"start must be one of {START_CHOICES}, got {start!r}")
    if calibration_prior not in CALIBRATION_PRIORS:
        raise ValueError(f"calibration_prior must be one of {CALIBRATION_PRIORS}, got {calibration_prior!r}")
    if start == "auto" and (start_model is None or root_height is None):
        raise ValueError("start='auto' searches a manifold's latent space: give start_model and root_height")
    resolved = subject_body(sequence, name, key=key, choice=body, donors=donors, dtype=TRACKING_DTYPE)
    if resolved.poses is None and start == "truth":
        raise ValueError(f"{name}: a test sequence needs ground truth ('joints3d' or 'pose') to start from and be scored; "
                         "without it, start automatically (start='auto', 'jaxtrack track --start auto')")
    body_model = resolved.body
    observed, keypoints = _checked_cues(sequence, rig, frames, name)
    truth_poses = truth = None
    if resolved.poses is not None:
        truth_poses = resolved.poses[:frames]
        truth = ground_truth_joints(sequence, truth_poses, body_model.skeleton)[:frames]
    if start == "truth":
        check_in_view(rig, forward_kinematics(body_model.skeleton, jnp.asarray(truth_poses[0], TRACKING_DTYPE)),
                      f"{name}'s initial pose (frame 0)")
    cues = _cues(recipe, sequence, observed, keypoints, frames, likelihood_options)
    likelihood = recipe.make(SceneInputs(body=body_model, rig=rig, silhouettes=observed, scale=likelihood_scale, window=window,
                                         keypoints=keypoints, edges=cues["edges"], foreground=cues["foreground"],
                                         images=cues["images"]),
                             **dict(likelihood_options or {}))
    pixel_samples = _pixel_samples(pixel_samples, likelihood, recipe.name, width, image_height, name, say)
    observations = _per_frame(recipe, cues)
    if start == "auto":
        searched = likelihood
        if has_evidence(likelihood) and observed is not None:
            # evidence fitted from the mean of a search's poses, scattered over every heading, explains nothing (004's
            # blobs: the start 18-19 cm off on a filmed walk, docs/vlmm.md): the search reads the silhouettes' likelihood
            searched = get_likelihood(DEFAULT_LIKELIHOOD).make(SceneInputs(body=body_model, rig=rig, silhouettes=observed,
                                                                           scale=likelihood_scale, window=window))
            searched = ObservationPart(searched, "silhouettes") if isinstance(observations, dict) else searched
            say(f"{name}: the automatic start searched with the silhouette likelihood (the {recipe.name} likelihood's "
                "evidence needs a start)")
        if root_height_legs is not None and resolved.source in OWN_BODY_SOURCES:
            # another person's stance on this person's legs (a root held 8 cm low was never recovered: docs/subjects.md)
            root_height = root_height * leg_length(body_model) / root_height_legs
            say(f"{name}: the automatic start holds the root at {root_height:.3f} m (the motion's height on this body's legs)")
        start_search = start_search or StartSearch()
        searched_frames = jax.tree.map(lambda x: jnp.asarray(x[: start_search.frames]), observations)
        if pixel_samples is not None and _samples_pixels(searched):
            # on sampled pixels, as the tracker scores them: every pixel of 4 views of 272x480 held 3.8 GB for the search
            searched, searched_frames = _on_sampled_pixels(searched, searched_frames, jax.random.fold_in(key, START_SAMPLE_TAG),
                                                           pixel_samples)
        initial_pose, found = automatic_start(
            jax.random.fold_in(key, START_TAG), searched, searched_frames, start_model, rig,
            body_model.skeleton, root_height=root_height, search=start_search,
            silhouettes=None if observed is None else observed[:, 0], keypoints=None if keypoints is None else keypoints[:, 0])
        say(f"{name}: automatic start: the root placed by the {found['placed_by']}, heading {np.degrees(found['heading']):.0f} deg")
    else:
        initial_pose = truth_poses[0]
    if "images" in recipe.observes:  # the appearance references (001's histograms, 003's templates), at the start
        likelihood = set_references(likelihood, initial_pose, jax.tree.map(lambda x: x[0], observations))
    calibration = measured = None
    tall = person_height_pixels(observed[:, 0]) if observed is not None else keypoint_height_pixels(keypoints[:, 0]) / 0.9
    wanted = body == "calibrate" or (body == "auto" and resolved.source == "default")
    if wanted and body == "auto" and tall < MIN_CALIBRATION_PIXELS:
        print(f"warning: {name}: the file has no skeleton, and the person is {tall:.0f} pixels tall: too small to calibrate limb "
              f"lengths from (under {MIN_CALIBRATION_PIXELS}: docs/body.md); tracking with the default proportions"
              + ("" if height is None else f" scaled to {height:g} m") + " (--calibrate-body to calibrate all the same)",
              file=sys.stderr)
        wanted = False
        if height is not None:
            body_model = eqx.tree_at(lambda b: b.skeleton, body_model,
                                     humaneva_body(limb_lengths_for_height(height), dtype=TRACKING_DTYPE).skeleton)
            likelihood = with_body(likelihood, body_model)
            initial_pose = _start_pose(sequence, body_model, initial_pose, key, start)
    if wanted:
        count = max(1, min(calibration_frames, frames))
        say(f"{name}: calibrating the body's limb lengths and radii from the first {count} frames' {' and '.join(recipe.observes)}"
            f"{'' if height is None else f' (height {height:g} m)'}")
        floor = make_ground_prior(body_model.skeleton, CALIBRATION_CLEARANCE if ground_clearance is None else ground_clearance)
        calibration_inputs = (np.repeat(initial_pose[None], count, axis=0), jax.tree.map(lambda x: jnp.asarray(x[:count]), observations))
        calibrated_on = likelihood
        if pixel_samples is not None:  # on sampled pixels, as the tracker scores them (every pixel of 4 views of 272x480: minutes)
            calibrated_on, sampled = _on_sampled_pixels(likelihood, calibration_inputs[1],
                                                        jax.random.fold_in(key, CALIBRATION_SAMPLE_TAG), pixel_samples)
            calibration_inputs = (calibration_inputs[0], sampled)
        prior_lengths, posture = motion_subjects_prior(donors) if calibration_prior != "default" else (None, None)
        posture = posture if calibration_prior == "motion" else None
        if prior_lengths is not None:
            say(f"{name}: the limb lengths' prior has the proportions of the motion model's subject"
                f"{'s' if len(donors) > 1 else ''}" + (", their clavicles' posture held" if posture is not None else "")
                + " (docs/body.md)")
        calibration_options = {"height": height, "prior_lengths": prior_lengths, "neutral_pose": posture}
        measured = None if keypoints is None else measure_limb_lengths(rig, keypoints)
        if measured is not None:  # every frame's keypoints, triangulated: the limbs' prior narrowed (docs/body.md)
            calibration_options["measured_lengths"] = measured.as_observation()
            say(f"{name}: limb lengths measured on {keypoints.shape[1]} frames' keypoints (noise {measured.pixel_noise:.1f} px; mm): "
                + ", ".join(f"{n} {1000 * v:.0f} +- {1000 * measured.standard_errors[n]:.0f}" for n, v in measured.lengths.items()))
        alone = keypoint_terms(likelihood)
        try:  # with keypoints: the limb lengths from them, the radii from every cue (docs/body.md)
            calibrated, fitted_poses, calibration = calibrate_body_from_keypoints(calibrated_on + floor, *calibration_inputs,
                                                                                  **calibration_options)
            if alone is not None and calibration.cues == "keypoints":
                print(f"warning: {name}: fitting the capsule radii to the {' and '.join(recipe.observes)} did not converge; the "
                      "limb lengths from the keypoints, the default radii", file=sys.stderr)
        except ConfigurationError as err:
            failure = err
            if alone is not None:  # the keypoints refused (too few detections): every cue together
                print(f"warning: {name}: {err} (from the 2-D keypoints); calibrating from the {' and '.join(recipe.observes)} "
                      "together", file=sys.stderr)
                try:
                    calibrated, fitted_poses, calibration = calibrate_body(calibrated_on + floor, *calibration_inputs,
                                                                           **calibration_options)
                    failure = None
                except ConfigurationError as second:
                    failure = second
            if failure is not None and body == "calibrate":  # asked for: the failure is the answer
                raise ConfigurationError(f"{name}: {failure}") from None
            if failure is not None:
                print(f"warning: {name}: {failure}; tracking with the default body", file=sys.stderr)
                wanted = False
    if wanted:
        body_model = body_of(calibrated)
        likelihood = with_body(likelihood, body_model)
        initial_pose = _start_pose(sequence, body_model, fitted_poses[0], key, start)
        say(f"{name}: calibrated limb lengths (mm): "
            + ", ".join(f"{n} {1000 * v:.0f}" for n, v in zip(calibration.limb_names, calibration.lengths_after))
            + CUES_SAID[calibration.cues]
            + f"; cost {calibration.cost_before:.3f} -> {calibration.cost_after:.3f}")
    if "images" in recipe.observes and wanted:  # again, on the calibrated body
        likelihood = set_references(likelihood, initial_pose, jax.tree.map(lambda x: x[0], observations))
    report = None
    radii_wanted = fit_radii
    if fit_radii is None:  # a body fitted to joints, no radii in the file, the start given, a person tall enough to measure
        radii_wanted = resolved.source == "fitted to joints" and sequence.capsule_radii is None and start == "truth"
        if radii_wanted and tall < MIN_CALIBRATION_PIXELS:
            say(f"{name}: the person is {tall:.0f} pixels tall, too small to fit the capsule radii to (under "
                f"{MIN_CALIBRATION_PIXELS}: docs/body.md): the default radii (--fit-radii to fit them all the same)")
            radii_wanted = False
    if radii_wanted and not wanted:
        if "silhouettes" not in recipe.observes or truth_poses is None:
            if fit_radii:  # asked for, and impossible
                raise ConfigurationError(f"{name}: fitting the capsule radii needs silhouettes and the ground-truth poses of the "
                                         f"frames (the {recipe.name} likelihood, {'with' if truth_poses is not None else 'no'} "
                                         "ground truth)")
        else:
            picks = spread_frames(frames, RADII_FRAMES)
            floor = make_ground_prior(body_model.skeleton, CALIBRATION_CLEARANCE if ground_clearance is None else ground_clearance)
            fit_to, fit_observations = likelihood, jax.tree.map(lambda x: jnp.asarray(x[picks]), observations)
            if pixel_samples is not None:  # on the pixels the tracker scores, not every pixel of the images
                fit_to, fit_observations = _on_sampled_pixels(likelihood, fit_observations,
                                                              jax.random.fold_in(key, RADII_SAMPLE_TAG), pixel_samples)
            started = time.perf_counter()
            try:
                fitted, report = fit_capsule_radii(fit_to + floor, np.asarray(truth_poses, np.float64)[picks], fit_observations)
            except ConfigurationError as err:
                if fit_radii:  # asked for: the failure is the answer
                    raise ConfigurationError(f"{name}: fitting the capsule radii: {err}") from None
                print(f"warning: {name}: fitting the capsule radii: {err}; tracking with the default radii", file=sys.stderr)
            else:
                body_model = body_of(fitted)
                likelihood = with_body(likelihood, body_model)
                say(f"{name}: capsule radii fitted to {len(picks)} frames' silhouettes at the poses its joints give, on "
                    + ("every pixel" if pixel_samples is None else f"{pixel_samples} sampled pixels per view and frame")
                    + f": {len(report.trace)} steps, {time.perf_counter() - started:.1f} s")
    if calibrate:
        likelihood, report = calibrate_shape(likelihood, initial_pose[None], observations[:1])
        body_model = likelihood.body
    start_error = float("nan") if truth is None else float(np.mean(np.linalg.norm(
        np.asarray(forward_kinematics(body_model.skeleton, jnp.asarray(initial_pose, TRACKING_DTYPE)), np.float64) - truth[0], axis=-1)))
    observations = jax.tree.map(jnp.asarray, observations)
    if pixel_samples is not None:
        likelihood, observations = _on_sampled_pixels(likelihood, observations, jax.random.fold_in(key, PIXEL_SAMPLE_TAG),
                                                      pixel_samples)
    return TestScene(
        likelihood=likelihood, observations=observations, initial_pose=jnp.asarray(initial_pose, TRACKING_DTYPE),
        truth_poses=truth_poses, truth_joints=truth, body=body_model, shape_calibration=report, subject=resolved,
        body_calibration=calibration, start_error_mm=1000.0 * start_error, pixel_samples=pixel_samples,
        limb_measurement=measured if calibration is not None else None,
    )


def motion_clearance(sequences, poses, *, floor_height: float = 0.0, skeletons=None) -> float:
    """The ankle's clearance above the floor (``likelihood.ground_clearance``, metres) in
    motion sequences with their (T, D) ``poses`` (from ``sequence_poses``): the files' ``joints3d``,
    else forward kinematics with each sequence's own skeleton (``skeletons``, e.g. from
    ``subject_body``; default: the file's or the default one)."""
    skeletons = skeletons or [s.body(dtype=TRACKING_DTYPE).skeleton for s in sequences]
    joints = [ground_truth_joints(s, p, k) for s, p, k in zip(sequences, poses, skeletons)]
    return ground_clearance(joints, HUMANEVA_JOINTS, floor_height=floor_height)


def manifold_problem(kind: str, latent_dim: int, train_poses) -> str | None:
    """Why a ``kind`` manifold of ``latent_dim`` dimensions cannot be fitted on these training
    pose sequences, or None: the kind's own preconditions (``ManifoldKind.problem``), checked
    before any fitting."""
    return get_manifold_kind(kind).problem([len(p) for p in train_poses], latent_dim)


def method_problems(config, train_poses, validation_poses) -> dict[str, str]:
    """Each requested method that cannot run on these motion data, with the reason (its
    manifold's preconditions, ``manifold_problem``; a velocity fitted on validation sequences
    of fewer than three frames). ``config`` is an ``ExperimentConfig``."""
    problems = {}
    short = min(len(p) for p in validation_poses)
    for method in config.methods:
        spec = config.manifold_spec_of(method)
        why = None if spec is None else manifold_problem(*spec, train_poses)
        if why is None and config.velocity_of(method) and short < 3:
            why = f"its Kalman-tracked velocity needs validation sequences of three or more frames (one has {short})"
        if why is not None:
            problems[method] = why
    return problems


def add_ground_prior(scene: TestScene, clearance: float, *, floor_height: float = 0.0, tolerance: float | None = None) -> TestScene:
    """The scene with its likelihood times the ground plane's prior (``likelihood.GroundPlanePrior``)
    for its body: ``clearance`` (e.g. ``motion_clearance`` of the validation motion), lowered to
    the initial pose's lowest ankle where that is lower, so the known start is never penalised."""
    options = {} if tolerance is None else {"tolerance": tolerance}
    prior = make_ground_prior(scene.body.skeleton, clearance, floor_height=floor_height, **options).allowing(scene.initial_pose)
    return dataclasses.replace(scene, likelihood=scene.likelihood + prior, ground_prior=prior)


def track(tracker, key: PRNGKeyArray, scene: TestScene, *, chunk_frames: int | None = None, on_chunk=None):
    """Run a tracker on a prepared scene from its first frame's ground truth.

    With ``chunk_frames``, the frames are tracked that many at a time (the same result for the
    same key) and ``on_chunk(poses (t, D), joints (t, J, 3))`` is called with the estimates of
    the first t frames after each chunk, so a caller can save them as it goes.

    Returns:
        ``(poses (T, D), joints (T, J, 3), infos)``: float64 estimates and the per-frame
        ``StepInfo``.
    """
    def joints_of(poses):
        return np.asarray(forward_kinematics(scene.body.skeleton, jnp.asarray(poses, TRACKING_DTYPE)), np.float64)

    joints_so_far = []

    def report(frames_done, info):  # the joints of the new chunk only: one shape, compiled once
        poses = np.asarray(info.estimate, np.float64)
        joints_so_far.append(joints_of(poses[sum(len(j) for j in joints_so_far):]))
        on_chunk(poses, np.concatenate(joints_so_far))

    _, info = run_filter(tracker, key, scene.initial_pose, scene.observations, chunk_frames=chunk_frames,
                         on_chunk=None if on_chunk is None else report)
    poses = np.asarray(jax.block_until_ready(info.estimate), np.float64)
    return poses, joints_of(poses), info


def track_stream(prepared: PreparedTracking, further=(), *, on_chunk=None):
    """Run a prepared tracker over its scene's frames, then on over each further segment's
    observations (an iterable, e.g. ``segment_observations`` of a video read a segment at a
    time), the particles and their weights carried across (``filters.continue_filter``; the
    k-th further segment's frames use ``fold_in(prepared.key, k)``). Only one segment's
    observations are held at a time. With no further segment it is ``track`` in one pass.
    ``on_chunk(poses (t, D), joints (t, J, 3))`` is called with the estimates so far after each
    segment.

    Returns:
        ``(poses (T, D), joints (T, J, 3), infos)``: float64 estimates and the per-frame
        ``StepInfo`` of every segment.
    """
    scene = prepared.scene

    def joints_of(info):
        return np.asarray(forward_kinematics(scene.body.skeleton, jnp.asarray(info.estimate, TRACKING_DTYPE)), np.float64)

    state, info = run_filter(prepared.tracker, prepared.key, scene.initial_pose, scene.observations)
    infos, joints = [jax.tree.map(np.asarray, info)], [joints_of(info)]
    for k, observations in enumerate(itertools.chain([None], further)):
        if k:
            state, info = continue_filter(prepared.tracker, jax.random.fold_in(prepared.key, k), state, observations)
            infos.append(jax.tree.map(np.asarray, info))
            joints.append(joints_of(info))
        if on_chunk is not None:
            on_chunk(np.concatenate([np.asarray(i.estimate, np.float64) for i in infos]), np.concatenate(joints))
    info = infos[0] if len(infos) == 1 else jax.tree.map(lambda *xs: np.concatenate(xs), *infos)
    return np.asarray(info.estimate, np.float64), np.concatenate(joints), info


def track_runs(tracker, keys: Key[Array, " runs"], scene: TestScene):
    """Several runs of a tracker on a prepared scene in one compiled call: ``run_filter`` vmapped
    over ``keys`` (R,). Run r equals ``track(tracker, keys[r], scene)`` up to float rounding.

    Returns:
        ``(poses (R, T, D), joints (R, T, J, 3), infos)``: float64 estimates and the per-frame
        ``StepInfo`` with a leading run axis.
    """
    _, info = jax.vmap(run_filter, in_axes=(None, 0, None, None))(tracker, keys, scene.initial_pose, scene.observations)
    poses = np.asarray(jax.block_until_ready(info.estimate), np.float64)
    joints = jax.vmap(lambda p: forward_kinematics(scene.body.skeleton, p))(jnp.asarray(poses, TRACKING_DTYPE))
    return poses, np.asarray(joints, np.float64), info


def track_sequences(tracker, keys: Key[Array, " sequences"], scenes):
    """Several test sequences of equal length in one compiled call: ``run_filter`` vmapped over
    the sequences' keys (S,), initial poses and observations. Sequence s equals
    ``track(tracker, keys[s], scenes[s])`` up to float rounding. The tracker's likelihood scores
    them all, so the scenes must share its body and cameras: one subject filmed by one rig.

    Returns:
        ``(poses (S, T, D), joints (S, T, J, 3), infos)``: float64 estimates and the per-frame
        ``StepInfo`` with a leading sequence axis.

    Raises:
        ValueError: if ``keys`` and ``scenes`` differ in number, or the scenes differ in length,
            image size, pose size or body.
    """
    scenes = list(scenes)
    if not scenes or len(scenes) != len(keys):
        raise ValueError(f"track_sequences: {len(keys)} keys for {len(scenes)} scenes (one key per scene, at least one)")
    first = scenes[0]
    for index, scene in enumerate(scenes[1:], start=1):
        shapes = lambda tree: [x.shape for x in jax.tree.leaves(tree)]  # noqa: E731
        for what, a, b in (("observations (frames, views, height, width)", shapes(scene.observations), shapes(first.observations)),
                           ("initial pose", scene.initial_pose.shape, first.initial_pose.shape)):
            if a != b:
                raise ValueError(f"track_sequences: scene {index} has {what} {a}, scene 0 {b}: batched sequences must match")
        if not bool(eqx.tree_equal(scene.body, first.body)):
            raise ValueError(f"track_sequences: scene {index} has another body than scene 0; the tracker's likelihood scores all "
                             "the sequences with one body, so track it separately")
    initial = jnp.stack([scene.initial_pose for scene in scenes])
    observations = jax.tree.map(lambda *xs: jnp.stack(xs), *[scene.observations for scene in scenes])
    _, info = jax.vmap(run_filter, in_axes=(None, 0, 0, 0))(tracker, keys, initial, observations)
    poses = np.asarray(jax.block_until_ready(info.estimate), np.float64)
    joints = jax.vmap(lambda p: forward_kinematics(first.body.skeleton, p))(jnp.asarray(poses, TRACKING_DTYPE))
    return poses, np.asarray(joints, np.float64), info


def tracker_stream(name: str) -> int:
    """The key stream of the tracker named ``name``: a 31-bit hash of the name (CRC-32), so a
    tracker's keys depend on its name alone, not on its place in the registry or on which other
    trackers are registered or run."""
    return zlib.crc32(name.encode("utf-8")) & 0x7FFFFFFF


def tracker_keys(seed: int, name: str) -> tuple[PRNGKeyArray, PRNGKeyArray]:
    """``(fit key, run root)`` of the tracker named ``name`` (``tracker_stream``): run r uses
    ``fold_in(run_root, r)``."""
    if not isinstance(name, str):
        raise TypeError(f"tracker_keys takes the tracker's name, got {type(name).__name__} (keys follow the name, not the "
                        "registry position)")
    root = jax.random.fold_in(jax.random.key(seed), tracker_stream(name))
    return jax.random.fold_in(root, FIT_KEY_TAG), root


def check_model_layout(model, header: dict, sequence: Sequence, name: str) -> None:
    """Refuse a saved manifold fitted on another pose layout than ``sequence``'s joint angles."""
    from ..body import humaneva_skeleton

    layout = header.get("extra", {}).get("pose_layout")
    source = sequence.pose_layout if sequence.pose_layout is not None else humaneva_skeleton().pose_layout
    expected = [str(n) for n in source[GLOBAL_DOFS:]]
    if layout is not None and list(layout) != expected:
        raise ValueError(f"the model was fitted on another skeleton: its pose layout {layout[:4]}... "
                         f"({len(layout)} entries) differs from {name}'s {expected[:4]}... ({len(expected)} entries)")
    if model.data_dim != len(expected):
        raise ValueError(f"the model has {model.data_dim} pose entries, {name} has {len(expected)} joint angles")


def track_sequence(sequence: Sequence, model, header: dict | None, method: str, validation=None, spec: TrackingSpec | None = None, *,
                   seed: int = 0, name: str = "test", chunk_frames: int | None = None, on_chunk=None, say=print):
    """``jaxtrack track``: ``prepare_tracking``, then the tracker run over the sequence
    (``track``; ``chunk_frames`` and ``on_chunk`` as there).

    Returns ``(estimated_poses (T, D), estimated_joints (T, J, 3), infos)``.
    """
    prepared = prepare_tracking(sequence, model, header, method, validation, spec, seed=seed, name=name, say=say)
    return track(prepared.tracker, prepared.key, prepared.scene, chunk_frames=chunk_frames, on_chunk=on_chunk)


@dataclasses.dataclass(frozen=True)
class PreparedTracking:
    """A tracker ready to run on a prepared scene (``prepare_tracking``): ``key`` is its run's
    PRNG key (``run_filter``'s)."""

    tracker: Any
    scene: TestScene
    key: PRNGKeyArray


def prepare_tracking(sequence: Sequence, model, header: dict | None, method: str, validation=None,
                     spec: TrackingSpec | None = None, *, seed: int = 0, name: str = "test", say=print) -> PreparedTracking:
    """One registered tracker with a saved manifold model made ready for one test sequence,
    tracked as ``spec`` says (default ``TrackingSpec()``: its budget, likelihood, body, ground
    prior, velocity and residual; the manifold settings are the model file's). The validation
    motion (a ``Sequence`` or a list of them) fits the tracker's dynamics and the ground
    prior's clearance, and lends its body to a test file of the same ``subject`` that has
    neither skeleton nor joints; None: the model file's own training motion, else (SIR, APF with
    ``model`` None) the embedded walk (``dynamics_motion``). ``say`` is told what was chosen.

    Raises:
        ValueError: on a tracker that cannot run under ``spec`` or on this model, a residual for
            a tracker that takes none, or files that do not fit each other.
    """
    spec = TrackingSpec() if spec is None else spec
    if not isinstance(spec, TrackingSpec):
        raise TypeError(f"track_sequence takes a TrackingSpec, got {type(spec).__name__}")
    recipe = spec.check_method(method)
    if spec.residual and recipe.residual is None:
        raise ValueError(f"{recipe.label} takes no pose residual: its state holds the pose itself (or its estimate is "
                         f"projected onto the manifold); the trackers that take one decode their pose from a latent point")
    if model is None:
        if recipe.needs_manifold:
            raise ValueError(f"{recipe.label} tracks on a manifold: give a model file from 'jaxtrack fit' (--model); "
                             "sir and apf need none")
    else:
        spectral = isinstance(model, SpectralEmbedding)
        if recipe.needs_manifold and spectral != (recipe.family == "spectral"):
            raise ValueError(f"{recipe.label} runs on a {' or '.join(recipe.runs_on)} manifold, and the model file holds a "
                             f"{type(model).__name__}{f' ({model.graph})' if spectral else ''}")
        check_model_layout(model, header, sequence, name)
    header = {} if model is None else dict(header or {})
    key = jax.random.key(seed)
    motions, motion_source = dynamics_motion(validation, header if model is not None else None, fps=sequence.fps, key=key)
    motion_names = ["the validation sequence" if validation is not None else "the dynamics' motion"] * len(motions)
    check_frame_rates([sequence, *motions], [name, *motion_names])
    subjects = [subject_body(m, n, key=key) for m, n in zip(motions, motion_names)]
    if any(s.poses is None for s in subjects):
        raise ValueError("the validation sequence needs 'pose' or 'joints3d' to fit the tracker's dynamics on")
    say(f"{name}: dynamics fitted on {motion_source}")
    layout = [str(n) for n in subjects[0].body.skeleton.pose_layout]
    motion_poses = [s.poses for s in subjects]
    root_height = float(np.mean(np.concatenate([p[:, layout.index("root_z")] for p in motion_poses])))
    clearance = motion_clearance(motions, motion_poses, skeletons=[s.body.skeleton for s in subjects])
    donors = [(n, s, m.subject) for n, s, m in zip(motion_names, subjects, motions)]
    start_model = model if model is not None else PoseSamples(jnp.asarray(np.concatenate(motion_poses)[:, GLOBAL_DOFS:]))
    scene = prepare_test(sequence, name, key=key, donors=donors, say=say,
                         start=spec.start, start_model=start_model, root_height=root_height,
                         root_height_legs=leg_length(subjects[0].body), ground_clearance=clearance, **spec.scene_options())
    say(f"{name}: body {scene.body_source}"
        + ("" if np.isnan(scene.start_error_mm) else f"; the start pose is {scene.start_error_mm:.1f} mm from frame 0's ground truth"))
    starts = header.get("sequence_starts")
    if spec.ground_prior:
        scene = add_ground_prior(scene, clearance)
    motion = motion_data([], motion_poses, model, None if starts is None else tuple(starts), stored=header.get("extra"))
    fit_key, run_root = tracker_keys(seed, method)
    fitted = fit_tracker(recipe, fit_key, motion)

    def build(scene, tell=None):
        return build_for_start(recipe, fitted, scene.likelihood, spec.tracking_budget, start_pose=scene.initial_pose,
                               skeleton=scene.body.skeleton, key=run_root, say=tell, name=name,
                               velocity_from=motion.validation if spec.velocity_of(method) else None,
                               residual_from=motion.validation, residual_scale=spec.residual_of(method),
                               residual_decay=spec.residual_decay_of(method), residual_target=spec.residual_target_of(method),
                               gait_rate=spec.gait_rate_of(method))[0]

    tracker = build(scene, say)
    if scene.body_calibration is not None and not spec.refines_body(scene):
        say(f"{name}: no second body pass" + (" (the start was found automatically: docs/video.md; --refine-body for one)"
                                             if spec.refine_body is None else ""))
    if spec.refines_body(scene):
        say(f"{name}: refining the calibrated body on {refine_frame_count(scene)} frames of a first {recipe.label} run, "
            "spread over the sequence")
        scene = track_and_refine_body(scene, tracker, run_root, start_from_truth=spec.start == "truth", ground_clearance=clearance,
                                      name=name)
        say(f"{name}: refined limb lengths (mm): " + ", ".join(f"{n} {1000 * v:.0f}" for n, v in limb_lengths_of(scene.body).items()))
        tracker = build(scene)
    return PreparedTracking(tracker, scene, jax.random.fold_in(run_root, 0))
