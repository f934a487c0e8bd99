"""Body calibration from the images: a subject's limb lengths and capsule radii fitted jointly
with the poses of the first few frames, by gradient through the likelihood (the soft
rasteriser for silhouettes), for a user who has no motion capture of the person.

The maximum a posteriori estimate of

    theta = (log scale, log limb proportions (8, left and right tied), log radii (left and
             right tied), poses of F frames)

under ``data_weight * sum_f ln p(I_f | x_f, body(theta))`` (000 eq. 12 at the likelihood's
temperature, or any likelihood of the library whose pytree holds the ``BodyModel`` it renders),
with Gaussian priors on

- the common log scale of every limb around a reference: a stated height's (the default
  proportions scaled to it, ``body.limb_lengths_for_height``; sd ``scale_sd_height`` 0.02), or
  the starting body's (sd ``scale_sd`` 0.1: adults' statures spread by about 7 %);
- each limb's own log length around the scaled reference (sd ``proportion_sd`` 0.06: segment
  lengths as fractions of stature vary by 4-6 % between adults);
- each log radius around its start (sd ``radius_sd`` 0.15, as ``calibrate_shape``);
- each pose around its start (``pose_sd_m`` on the root, ``pose_sd_rad`` on the angles): weak,
  so the poses move where the body's new proportions need them.

``data_weight`` (30) undoes the tracker's tempering for this one MAP problem: at the tracking
temperature (000 eq. 12 times 100) a 4-frame clean 160x120 scene holds about one nat for a limb
5 cm off, less than the proportions' prior, and the lengths stayed where they started; at 30 the
arms and legs came within 1-2 cm (the notes in ``docs/body.md``). The 2-D keypoints' term
(``KeypointLikelihood``) is not tempered, so it enters once, alone or beside the silhouettes: its
weight is divided by ``data_weight`` for the fit (at 30 times its weight the fit followed one
pixel of detection noise: docs/keypoints.md).

Two things a start pose and the tracker's soft edge would otherwise bias (docs/body.md, "The
thorax's height and the soft edge"):

- the clavicles (every ``*clavicle*`` dof, ``neutral_dofs``) start at the rest posture and are held
  near it (sd ``neutral_sd`` 0.1 rad), not near the start: a start pose solved on the default
  skeleton raises them (by 0.35 rad for a spine 12 % longer) to reach the person's shoulders, and
  a prior around that start kept the thorax low (the spine 35-39 mm short, the neck as long);
- the silhouettes are fitted with a soft edge half as wide as the tracker's (``edge_factor``): at
  the tracker's width a clean scene's cost is lower away from the true body than at it.

and one thing a capsule body cannot explain (docs/body.md, "The floor band"): the feet, and the
shadows background subtraction segments with them. With a floor prior in the likelihood the
silhouettes are fitted without the floor around the ankles (``floor_band``,
``FloorBandSilhouette``); the floor's prior then holds the ankles' height, where whole
silhouettes stretched the shins 4-8 cm down into the shadows.

Adam on the whitened parameters (each divided by its prior's sd), from the prior's centre. (A
coarse-to-fine schedule, the soft edges 4, 2 and then 1 times the likelihood's width, changed
nothing at 160x120 and made 80x60 worse: its blurred first stage moved the legs away.) Bone lengths and poses
trade against each other in one view; in several calibrated views the scale is fixed by the
cameras.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from ..body import LIMB_SEGMENTS, BodyModel, Skeleton, check_height, limb_lengths_for_height, stature
from ..errors import ConfigurationError
from ._base import AbstractLikelihood, SumLikelihood
from ._calibration import ShapeCalibration, symmetric_groups
from ._floor_band import FloorBandSilhouette
from ._ground import GroundPlanePrior
from ._keypoints import KeypointLikelihood, keypoint_terms
from ._sampled import SampledSilhouetteLikelihood
from ._silhouette import SilhouetteLikelihood

PLAUSIBLE_FACTOR = (0.75, 1.33)  # a fitted limb length outside this range of its reference: not converged
# The floor band's reach around each ankle's ground point (metres): a foot reaches 20-25 cm ahead of
# the ankle and its shadow further (chosen in docs/body.md, "The floor band").
FLOOR_BAND_RADIUS = 0.45
MAX_COST = 0.5  # 000 eq. 12's cost (mean over frames) a converged calibration ends below (docs/body.md)
# ``fit_radii``: the prior sds that hold the limb lengths (log) and the poses (metres, radians) where they are.
HELD_LENGTH_SD, HELD_POSE_SD_M, HELD_POSE_SD_RAD = 1e-4, 0.005, 0.01


class BodyCalibration(NamedTuple):
    """What ``calibrate_body`` did.

    Attributes:
        limb_names: the 8 limbs (keys of ``body.DEFAULT_LIMB_LENGTHS``).
        lengths_before, lengths_after: (8,) limb lengths, metres.
        reference_lengths: (8,) the prior's centre, metres (with ``measured_lengths``, the centre they narrowed it to).
        capsule_names: the capsules.
        radii_before, radii_after: (K,) radii, metres.
        poses_before, poses_after: (F, D) the frames' poses.
        cost_before, cost_after: ``-mean_f ln p(I_f | x_f) / scale`` at the start and the end.
        trace: (steps taken,) the MAP objective per step.
        height: the stated height (metres), or None.
        cues: what the body was fitted to: "all" (the whole likelihood); "keypoint lengths" (the limb
            lengths to its 2-D keypoints alone, the radii and poses then to the whole likelihood:
            ``calibrate_body_from_keypoints``); or "keypoints" (the keypoints alone: where that
            function's second step was refused).
        neutral_pose: (D,) the pose whose neutral dofs centred their prior (``calibrate_body``'s
            ``neutral_pose``), or None (0, the rest posture); a second pass keeps it.
    """

    limb_names: tuple[str, ...]
    lengths_before: np.ndarray
    lengths_after: np.ndarray
    reference_lengths: np.ndarray
    capsule_names: tuple[str, ...]
    radii_before: np.ndarray
    radii_after: np.ndarray
    poses_before: np.ndarray
    poses_after: np.ndarray
    cost_before: float
    cost_after: float
    trace: np.ndarray
    height: float | None
    cues: str = "all"
    neutral_pose: np.ndarray | None = None

    def summary(self) -> dict:
        """For results.json: lengths and radii (mm) before and after, costs, height."""
        return {"limb_lengths_before_mm": dict(zip(self.limb_names, np.round(1000 * self.lengths_before, 1).tolist())),
                "limb_lengths_after_mm": dict(zip(self.limb_names, np.round(1000 * self.lengths_after, 1).tolist())),
                "radii_before_mm": dict(zip(self.capsule_names, np.round(1000 * self.radii_before, 1).tolist())),
                "radii_after_mm": dict(zip(self.capsule_names, np.round(1000 * self.radii_after, 1).tolist())),
                "cost_before": self.cost_before, "cost_after": self.cost_after, "frames": int(self.poses_after.shape[0]),
                "height_m": self.height, "cues": self.cues}


def body_of(likelihood) -> BodyModel:
    """The ``BodyModel`` a likelihood renders (the first one in its pytree)."""
    found = [leaf for leaf in jax.tree.leaves(likelihood, is_leaf=lambda x: isinstance(x, BodyModel)) if isinstance(leaf, BodyModel)]
    if not found:
        raise ConfigurationError(f"{type(likelihood).__name__} holds no BodyModel: there is no body to calibrate")
    return found[0]


def with_body(likelihood, body: BodyModel):
    """The likelihood with every ``BodyModel`` in its pytree replaced by ``body``, and every
    skeleton outside one (a ``GroundPlanePrior``'s) by ``body.skeleton``."""
    def swap(leaf):
        if isinstance(leaf, BodyModel):
            return body
        return body.skeleton if isinstance(leaf, Skeleton) else leaf

    return jax.tree.map(swap, likelihood, is_leaf=lambda x: isinstance(x, (BodyModel, Skeleton)))


def _limb_structure(body: BodyModel):
    """Per joint: its limb's index (-1 for the root) and the unit direction of its rest offset."""
    names = tuple(LIMB_SEGMENTS)
    limb_of = np.full(body.skeleton.num_joints, -1)
    for i, limb in enumerate(names):
        for _, joint in LIMB_SEGMENTS[limb]:
            limb_of[body.skeleton.joint_index(joint)] = i
    offsets = np.asarray(body.skeleton.offsets, np.float64)
    norms = np.linalg.norm(offsets, axis=1)
    directions = np.where(norms[:, None] > 0, offsets / np.maximum(norms, 1e-12)[:, None], 0.0)
    lengths = np.array([np.mean([norms[body.skeleton.joint_index(j)] for _, j in LIMB_SEGMENTS[limb]]) for limb in names])
    return names, limb_of, directions, lengths


def calibrate_body(
    likelihood: AbstractLikelihood,
    poses,
    observations,
    *,
    height: float | None = None,
    prior_lengths: dict[str, float] | None = None,
    steps: int = 300,
    learning_rate: float = 0.05,
    scale_sd: float = 0.1,
    scale_sd_height: float = 0.02,
    proportion_sd: float | dict[str, float] = 0.06,
    radius_sd: float = 0.15,
    pose_sd_m: float = 0.1,
    pose_sd_rad: float = 0.3,
    data_weight: float = 30.0,
    max_cost: float | None = MAX_COST,
    neutral_dofs: tuple[str, ...] | None = None,
    neutral_sd: float = 0.1,
    neutral_pose=None,
    edge_factor: float = 0.5,
    floor_band: float | None = FLOOR_BAND_RADIUS,
    measured_lengths: dict[str, tuple[float, float]] | None = None,
    stop_tolerance: float | None = None,
):
    """Fit the body's limb lengths and radii, and the frames' poses, to the first frames' images.

    Args:
        likelihood: any likelihood whose pytree holds the ``BodyModel`` it renders (e.g.
            ``SilhouetteLikelihood``); its body is the start.
        poses: (F, D) starting poses of the F frames (e.g. the given start pose repeated, or
            inverse kinematics on the default skeleton).
        observations: the F frames' observations, a leading F axis on every leaf (e.g. (F, C,
            H, W) silhouettes, or a ``PixelSample``).
        height: the subject's standing height in metres: the limb lengths' prior is then the
            default proportions (or ``prior_lengths``') at that height (tighter); None: the starting
            body's lengths.
        prior_lengths: the limbs' prior centre (metres, by ``body.LIMB_SEGMENTS``' names, every
            limb) instead of the starting body's lengths, with the sd ``scale_sd`` on their common
            scale: a second pass started at a first pass's body keeps the first pass's prior
            (``tracking.refine_body``), and a first pass takes the proportions of the motion model's
            subject (``tracking.prepare_test``). With ``height``: these proportions scaled to the
            height (``body.stature``), with the sd ``scale_sd_height``.
        steps, learning_rate: Adam on the whitened parameters (``steps`` at most).
        stop_tolerance: stop before ``steps`` once the MAP objective fell by less than this
            fraction of itself over the last ``STALL_WINDOW`` steps (None: every step is taken).
        scale_sd, scale_sd_height: prior sd of the common log scale of every limb, without and
            with a stated height.
        proportion_sd: prior sd of each limb's own log length around the scaled reference; a dict
            sets it per limb (``body.LIMB_SEGMENTS``' names), the others keeping 0.06.
        radius_sd: prior sd of each log radius around its start.
        pose_sd_m, pose_sd_rad: prior sds of the poses around their start.
        data_weight: the log-likelihood's weight against the priors (module docstring).
        neutral_dofs: rotational dofs (``Skeleton.dof_names``) started at 0, the rest posture, with
            the prior sd ``neutral_sd`` around it instead of around the start: the dofs a start pose
            solved on another skeleton bends to reach the person's joints. None: every dof whose
            name holds ``clavicle`` (module docstring).
        neutral_sd: their prior sd, radians.
        neutral_pose: (D,) a pose whose values of the neutral dofs start them and centre their prior
            instead of 0: the posture the tracker's motion model holds them in (e.g. the mean of its
            training poses: a motion-capture convention puts the thorax below the shoulders, the
            clavicles then raised 0.15-0.35 rad; docs/body.md, "The motion model's subject").
        edge_factor: every term with a soft edge (an ``edge_width``: the silhouettes) is fitted with
            its edge this many times as wide (module docstring); the returned likelihood keeps its own.
        floor_band: with a ``GroundPlanePrior`` in the likelihood (the floor then holds the ankles),
            every silhouette term is fitted without the pixels whose ray meets the floor within this
            many metres of an ankle's ground point (``FloorBandSilhouette``: the feet and their
            shadows, which a capsule body can only explain with longer shins); None, or no floor
            prior: whole silhouettes. The returned likelihood scores whole silhouettes.
        measured_lengths: limb name -> (length, standard error), metres: a measurement of some
            limbs over more frames than those fitted (``tracking.measure_limb_lengths``: the
            keypoints of every frame, triangulated), combined with the lengths' prior as a Gaussian
            observation of their logs (``combine_length_prior``) before the fit.
        max_cost: the highest final cost (``-mean_f ln p / scale``) of a converged calibration,
            on 000 eq. 12's scale (``MAX_COST``); applied only to a likelihood with a tempered term
            (the silhouettes'); None, or a likelihood on another scale (the keypoints' alone): only
            a rising cost and implausible lengths are refused.

    Returns:
        ``(likelihood with the fitted body, fitted poses (F, D), BodyCalibration)``.

    Raises:
        ValueError: bad shapes, non-finite poses, a height that is not a person's, or non-positive
            settings.
        ConfigurationError: a calibration that does not converge (a non-finite objective, a cost
            that rose or stayed above 0.5, or a limb length outside 0.75-1.33 times its
            reference, named).
    """
    body = body_of(likelihood)
    poses = np.asarray(poses, np.float64)
    D = body.skeleton.num_dofs
    if poses.ndim != 2 or poses.shape[1] != D or poses.shape[0] < 1:
        raise ValueError(f"poses must be (frames >= 1, {D}), got {poses.shape}")
    if not np.all(np.isfinite(poses)):
        raise ValueError("poses contain NaN or infinite values")
    frames = poses.shape[0]
    leaves = jax.tree.leaves(observations)
    if not leaves or any(np.shape(leaf)[:1] != (frames,) for leaf in leaves):
        raise ValueError(f"observations must have a leading axis of {frames} frames (one per pose)")
    names, limb_of, directions, start_lengths = _limb_structure(body)
    proportion_sds = _per_limb(proportion_sd, names)
    if steps < 1 or not learning_rate > 0 or min(scale_sd, scale_sd_height, *proportion_sds, radius_sd, pose_sd_m, pose_sd_rad,
                                                  neutral_sd) <= 0:
        raise ValueError("steps, learning_rate and every prior sd must be positive")
    if not (np.isfinite(data_weight) and data_weight > 0):
        raise ValueError(f"data_weight must be a positive number, got {data_weight!r}")
    if not 0 < edge_factor <= 1:
        raise ValueError(f"edge_factor must be in (0, 1], got {edge_factor}")
    if floor_band is not None and not (np.isfinite(floor_band) and 0 < floor_band <= 2):
        raise ValueError(f"floor_band must be a reach on the floor in metres, in (0, 2], or None; got {floor_band}")
    if height is not None:
        height = check_height(height)
    reference = limb_prior_centre(names, start_lengths, height, prior_lengths)
    sd_scale = scale_sd if height is None else scale_sd_height
    if measured_lengths is not None:
        reference, sd_scale, proportion_sds = combine_length_prior(names, reference, sd_scale, proportion_sds, measured_lengths)
    groups = symmetric_groups(body.capsule_names)
    log_radii = np.log(np.asarray(body.radii, np.float64))
    radius0 = np.array([log_radii[groups == g].mean() for g in range(groups.max() + 1)])
    pose_sd = np.full(D, pose_sd_rad)
    pose_sd[:3] = pose_sd_m
    neutral = _neutral_columns(body.skeleton, neutral_dofs)
    if neutral_pose is not None:
        neutral_pose = np.asarray(neutral_pose, np.float64)
        if neutral_pose.shape != (D,) or not np.all(np.isfinite(neutral_pose)):
            raise ValueError(f"neutral_pose must be a finite pose of shape ({D},), got shape {neutral_pose.shape}")
    if neutral.size:
        poses = poses.copy()
        poses[:, neutral] = 0.0 if neutral_pose is None else neutral_pose[neutral]
        pose_sd[neutral] = neutral_sd
    dtype = body.radii.dtype
    cast = lambda a: jnp.asarray(a, dtype)  # noqa: E731
    # Prior centres (the start too) and sds of the whitened parameters.
    prior = {"scale": cast(np.zeros(1)), "proportion": cast(np.zeros(len(names))), "radius": cast(radius0), "pose": cast(poses)}
    sds = {"scale": cast(np.full(1, sd_scale)), "proportion": cast(proportion_sds),
           "radius": cast(np.full(len(radius0), radius_sd)), "pose": cast(pose_sd)}
    structure = (cast(directions), jnp.asarray(limb_of), jnp.asarray(groups), cast(np.log(reference)))
    u0 = jax.tree.map(jnp.zeros_like, prior)
    fitted_to = _untempered_keypoints(_sharpened(likelihood, edge_factor), data_weight)
    if not _tempered(likelihood):
        max_cost = None  # the cost is not on 000 eq. 12's scale
    if floor_band is not None:
        fitted_to = _without_floor_band(fitted_to, floor_band)
    tolerance = -np.inf if stop_tolerance is None else float(stop_tolerance)
    u, trace, costs, taken = _fit(fitted_to, body, structure, observations, prior, sds, jnp.asarray(data_weight, dtype), u0,
                                  steps, learning_rate, jnp.asarray(tolerance, dtype))
    fitted = _unwhiten(body, prior, sds, u)
    trace, costs = np.asarray(trace)[:int(taken)], np.asarray(costs)[:int(taken)]
    before, after = float(costs[0]), float(costs[-1])
    log_lengths = np.log(reference) + np.asarray(fitted["scale"], np.float64) + np.asarray(fitted["proportion"], np.float64)
    lengths_after = np.exp(log_lengths)
    if not (np.all(np.isfinite(trace)) and np.isfinite(after)):
        raise ConfigurationError("the body calibration did not converge: its objective became non-finite (are the first frames' "
                                 "silhouettes empty, or the start pose far from the person?)")
    ratio = lengths_after / reference
    bad = [f"{n} {1000 * v:.0f} mm ({r:.2f} x the reference)" for n, v, r in zip(names, lengths_after, ratio)
           if not PLAUSIBLE_FACTOR[0] <= r <= PLAUSIBLE_FACTOR[1]]
    too_high = max_cost is not None and after > max_cost
    if bad or after > before or too_high:
        why = (f"limb lengths {', '.join(bad)}" if bad else f"its cost rose from {before:.3f} to {after:.3f}" if after > before
               else f"its cost ended at {after:.3f}: the body explains too little of the images (a fit reaches 0.1-0.3)")
        raise ConfigurationError(f"the body calibration did not converge ({why}): check the start pose, the cameras and the "
                                 "silhouettes of the first frames, or state the subject's height (--height)")
    new_body = _body(body, structure, fitted)
    report = BodyCalibration(
        limb_names=names, lengths_before=start_lengths, lengths_after=lengths_after, reference_lengths=reference,
        capsule_names=body.capsule_names, radii_before=np.exp(log_radii), radii_after=np.asarray(new_body.radii, np.float64),
        poses_before=poses, poses_after=np.asarray(fitted["pose"], np.float64), cost_before=float(before), cost_after=float(after),
        trace=np.asarray(trace), height=height, neutral_pose=neutral_pose,
    )
    return with_body(likelihood, new_body), np.asarray(fitted["pose"], np.float64), report


COMBINED_SCALE_SD = 1e-3  # the common scale's sd once a measurement is in the prior: its spread is in the limbs' own sds


def combine_length_prior(names, reference, scale_sd: float, proportion_sds, measured: dict[str, tuple[float, float]]):
    """The limb lengths' prior with a measurement of some of them folded in: ``(reference (8,),
    scale_sd, proportion_sds (8,))`` of the Gaussian posterior over the log lengths.

    The prior is ``log L = log reference + s + p`` with ``s ~ N(0, scale_sd^2)`` common to every limb
    and ``p_k ~ N(0, proportion_sds_k^2)``; the measurement, ``log L_k ~ N(log m_k, (se_k / m_k)^2)``
    for each measured limb k (``measured``: name -> (m_k, se_k), metres). The posterior's mean is the
    new reference, so an unmeasured limb moves with the common scale the others show; its marginal
    sds the new proportion sds, and the common scale is then held (``COMBINED_SCALE_SD``).

    Raises:
        ValueError: a name that is not a limb, or a length or standard error that is not positive.
    """
    names = tuple(names)
    unknown = sorted(set(measured) - set(names))
    if unknown:
        raise ValueError(f"measured_lengths names {unknown}, which are not limbs (the limbs: {', '.join(names)})")
    bad = [n for n, (m, se) in measured.items() if not (np.isfinite(m) and m > 0 and np.isfinite(se) and se > 0)]
    if bad:
        raise ValueError(f"measured_lengths of {bad}: a length and a standard error must be positive metres")
    sds = np.asarray(proportion_sds, np.float64)
    prior_cov = scale_sd ** 2 * np.ones((len(names), len(names))) + np.diag(sds ** 2)
    prior_precision = np.linalg.inv(prior_cov)
    seen = np.array([n in measured for n in names])
    values = np.array([np.log(measured[n][0]) if n in measured else 0.0 for n in names])
    precisions = np.array([(measured[n][0] / measured[n][1]) ** 2 if n in measured else 0.0 for n in names])
    posterior_cov = np.linalg.inv(prior_precision + np.diag(precisions))
    mean = posterior_cov @ (prior_precision @ np.log(np.asarray(reference, np.float64)) + np.where(seen, precisions * values, 0.0))
    return np.exp(mean), COMBINED_SCALE_SD, np.sqrt(np.diag(posterior_cov))


def limb_prior_centre(names, start_lengths, height: float | None, prior_lengths) -> np.ndarray:
    """(8,) the limb lengths' prior centre (metres, in ``names``' order): ``prior_lengths`` or the
    start's lengths; with a ``height``, the default proportions at it
    (``body.limb_lengths_for_height``), or ``prior_lengths`` scaled the same way (by the height over
    their ``body.stature``)."""
    reference = np.asarray(start_lengths, np.float64)
    if prior_lengths is not None:
        missing = sorted(set(names) - set(prior_lengths))
        reference = np.array([float(prior_lengths.get(n, np.nan)) for n in names])
        if missing or sorted(set(prior_lengths) - set(names)) or not np.all(np.isfinite(reference) & (reference > 0)):
            raise ValueError(f"prior_lengths must give every limb ({', '.join(names)}) a positive length in metres, got "
                             f"{dict(prior_lengths)}")
    if height is None:
        return reference
    if prior_lengths is None:
        return np.array([limb_lengths_for_height(height)[n] for n in names])
    return reference * (height / stature(dict(zip(names, reference))))


def _sharpened(likelihood, factor: float):
    """The likelihood with every term's soft ``edge_width`` times ``factor``."""
    has_edge = lambda x: isinstance(x, AbstractLikelihood) and hasattr(x, "edge_width")  # noqa: E731

    def sharpen(term):
        return eqx.tree_at(lambda t: t.edge_width, term, term.edge_width * factor) if has_edge(term) else term

    return jax.tree.map(sharpen, likelihood, is_leaf=has_edge) if factor != 1 else likelihood


def _untempered_keypoints(likelihood, data_weight: float):
    """The likelihood with every keypoint term's weight divided by ``data_weight``: untempered
    terms enter the MAP objective once (module docstring)."""
    is_keypoints = lambda x: isinstance(x, KeypointLikelihood)  # noqa: E731

    def untempered(term):
        if not is_keypoints(term):
            return term
        return KeypointLikelihood(term.body, term.rig, term.sigmas, term.robust, term.weight / float(data_weight))

    return jax.tree.map(untempered, likelihood, is_leaf=is_keypoints)


def _tempered(likelihood) -> bool:
    """Whether some term of the likelihood has a temperature (a ``scale``: the silhouettes')."""
    has_scale = lambda x: isinstance(x, AbstractLikelihood) and hasattr(x, "scale")  # noqa: E731
    return any(has_scale(x) for x in jax.tree.leaves(likelihood, is_leaf=has_scale))


def _per_limb(sd, names: tuple[str, ...]) -> np.ndarray:
    """(8,) prior sds of the limbs' proportions from one number or a dict by limb name (0.06 for the others)."""
    if not isinstance(sd, dict):
        return np.full(len(names), float(sd))
    unknown = sorted(set(sd) - set(names))
    if unknown:
        raise ValueError(f"proportion_sd names {unknown}, which are not limbs (the limbs: {', '.join(names)})")
    return np.array([float(sd.get(n, 0.06)) for n in names])


def _without_floor_band(likelihood, radius: float):
    """The likelihood with every silhouette term scored without its floor band (``FloorBandSilhouette``)
    when it holds a ``GroundPlanePrior`` (whose floor it is), else as it is."""
    is_term = lambda x: isinstance(x, (SilhouetteLikelihood, SampledSilhouetteLikelihood, GroundPlanePrior))  # noqa: E731
    floors = [x for x in jax.tree.leaves(likelihood, is_leaf=is_term) if isinstance(x, GroundPlanePrior)]
    if not floors:
        return likelihood
    floor_height = floors[0].floor_height
    dtype = body_of(likelihood).radii.dtype

    def band(term):
        if isinstance(term, (SilhouetteLikelihood, SampledSilhouetteLikelihood)):
            return FloorBandSilhouette(silhouette=term, radius=jnp.asarray(radius, dtype), floor_height=jnp.asarray(floor_height, dtype))
        return term

    return jax.tree.map(band, likelihood, is_leaf=is_term)


def _neutral_columns(skeleton: Skeleton, names: tuple[str, ...] | None) -> np.ndarray:
    """Pose columns of the named rotational dofs (every ``*clavicle*`` dof for None)."""
    dofs = tuple(skeleton.dof_names)
    if names is None:
        names = tuple(n for n in dofs if "clavicle" in n)
    unknown = [n for n in names if n not in dofs]
    if unknown:
        raise ValueError(f"neutral_dofs {unknown} are not dofs of the skeleton (its dofs: {', '.join(dofs)})")
    offset = skeleton.num_dofs - len(dofs)  # the root's translation comes first
    return np.array([offset + dofs.index(n) for n in names], dtype=int)


def _body(body: BodyModel, structure, params) -> BodyModel:
    directions, limb_of, groups, log_reference = structure
    log_lengths = log_reference + params["scale"] + params["proportion"]
    lengths = jnp.where(limb_of >= 0, jnp.exp(log_lengths)[jnp.maximum(limb_of, 0)], 0.0)
    offsets = directions * lengths[:, None]
    body = eqx.tree_at(lambda b: b.skeleton.offsets, body, offsets.astype(body.radii.dtype))
    return eqx.tree_at(lambda b: b.radii, body, jnp.exp(params["radius"])[groups].astype(body.radii.dtype))


def _scale(likelihood):
    """The temperature of the likelihood's first term that has one (1 for none)."""
    for term in jax.tree.leaves(likelihood, is_leaf=lambda x: isinstance(x, AbstractLikelihood) and hasattr(x, "scale")):
        if isinstance(term, AbstractLikelihood) and hasattr(term, "scale"):
            return term.scale
    return 1.0


def _unwhiten(body, prior, sds, u):
    params = jax.tree.map(lambda c, s, v: c + s * v, prior, sds, u)
    return {**params, "pose": body.skeleton.clip_to_limits(params["pose"])}


def _loss(u, likelihood, body, structure, observations, prior, sds, data_weight):
    """The MAP objective at whitened parameters ``u``, and the cost ``-mean_f ln p / scale``."""
    params = _unwhiten(body, prior, sds, u)
    model = with_body(likelihood, _body(body, structure, params))
    per_frame = jax.vmap(lambda pose, obs: model.log_likelihood(pose[None], obs)[0])(params["pose"], observations)
    penalty = 0.5 * sum(jnp.sum(v ** 2) for v in jax.tree.leaves(u))
    return -data_weight * jnp.sum(per_frame) + penalty, -jnp.mean(per_frame) / _scale(likelihood)


RADII_STOP_TOLERANCE = 1e-4
"""``fit_radii``'s ``stop_tolerance``: the fit ends once its objective fell by under 0.01 % over
``STALL_WINDOW`` steps (docs/motion_files.md, "The radii's cost")."""
RADII_LEARNING_RATE = 0.1
"""``fit_radii``'s Adam step (``calibrate_body``'s is 0.05): with the skeleton and poses held, on a
320x240 walk it stopped after 140 steps instead of 256, every radius but the clavicles' (which the
silhouettes do not see) within 0.1 % of a 1000-step fit (docs/motion_files.md)."""
STALL_WINDOW = 25  # steps over which a fit's objective must still fall (``calibrate_body``'s ``stop_tolerance``)


@eqx.filter_jit
def _fit(likelihood, body, structure, observations, prior, sds, data_weight, u0, steps, learning_rate, stop_tolerance):
    """Up to ``steps`` Adam steps on the whitened parameters from ``u0``, stopping once the MAP
    objective fell by less than ``stop_tolerance`` (relative) over the last ``STALL_WINDOW``
    steps; returns the last ``u``, the objective and the cost per step (NaN after the last) and
    the steps taken."""
    optimiser = optax.adam(learning_rate)
    dtype = jax.tree.leaves(u0)[0].dtype

    def step(carry):
        u, state, i, trace, costs = carry
        (value, cost), grad = jax.value_and_grad(_loss, has_aux=True)(u, likelihood, body, structure, observations, prior, sds,
                                                                 data_weight)
        grad = jax.tree.map(lambda g: jnp.where(jnp.isfinite(g), g, 0.0), grad)
        updates, state = optimiser.update(grad, state)
        return optax.apply_updates(u, updates), state, i + 1, trace.at[i].set(value), costs.at[i].set(cost)

    def going(carry):
        _, _, i, trace, _ = carry
        last, earlier = trace[jnp.maximum(i - 1, 0)], trace[jnp.maximum(i - 1 - STALL_WINDOW, 0)]
        stalled = (i > STALL_WINDOW) & (earlier - last < stop_tolerance * jnp.abs(last))
        return (i < steps) & ~stalled

    empty = jnp.full(steps, jnp.nan, dtype)
    u, _, taken, trace, costs = jax.lax.while_loop(going, step, (u0, optimiser.init(u0), jnp.asarray(0), empty, empty))
    return u, trace, costs, taken


def calibrate_body_from_keypoints(likelihood: AbstractLikelihood, poses, observations, **options):
    """The body calibrated in two steps where the likelihood observes 2-D keypoints beside another
    cue (``silhouette+keypoints``): the limb lengths from the cue that marks the joints, the girth
    from the one that draws the body.

    1. ``calibrate_body`` on the keypoint terms alone (``keypoint_terms``) and the likelihood's priors
       (a floor's): the limb lengths and the frames' poses.
    2. ``calibrate_body`` on the whole likelihood from those poses, the limb lengths held at step 1's
       (prior sd ``HELD_LENGTH_SD`` on their logs): the capsule radii, and the poses again (their
       priors as in step 1; held at step 1's instead, the tracks were better on the motion model's
       own subject and worse on two others: docs/body.md).

    Fitted together, the silhouettes of a body whose shape is not the capsules' pull the joints where
    the capsules' outline fits best: on the solid-bodied films the neck came out 53-86 mm long and the
    spine 38-65 mm short, inside the plausible range, so nothing refused them (docs/body.md, "Limb
    lengths from the keypoints, radii from the silhouettes").

    Args:
        likelihood, poses, observations: as ``calibrate_body``.
        options: ``calibrate_body``'s settings for step 1 (``height``, ``prior_lengths``,
            ``neutral_pose``, ...); step 2 takes them too, except the lengths' prior.

    Returns:
        ``(likelihood with the fitted body, fitted poses (F, D), BodyCalibration)``, its ``cues``
        "keypoint lengths": the lengths, their prior centre and ``poses_before`` from step 1, the
        radii, fitted poses, costs and trace from step 2 (its ``cost_before``: the whole
        likelihood's at step 1's body and poses). Where step 2 is
        refused, step 1's body with the starting radii, ``cues`` "keypoints". A likelihood
        without keypoints, or with nothing else: ``calibrate_body``.

    Raises:
        ValueError: as ``calibrate_body``.
        ConfigurationError: step 1 does not converge (``calibrate_body``'s checks).
    """
    alone = keypoint_terms(likelihood)
    if alone is None:
        return calibrate_body(likelihood, poses, observations, **options)
    priors = tuple(term for term in _terms(likelihood) if not term.reads_observation)
    fitted, fitted_poses, lengths = calibrate_body(SumLikelihood((alone, *priors)) if priors else alone, poses, observations,
                                                   **options)
    body = body_of(fitted)
    kept = {key: value for key, value in options.items()
            if key not in ("height", "prior_lengths", "scale_sd", "proportion_sd", "measured_lengths")}
    try:  # the lengths held where the keypoints put them; the poses as free as in step 1
        whole, whole_poses, girth = calibrate_body(with_body(likelihood, body), fitted_poses, observations,
                                                   prior_lengths=dict(zip(lengths.limb_names, lengths.lengths_after)),
                                                   scale_sd=HELD_LENGTH_SD, proportion_sd=HELD_LENGTH_SD, **kept)
    except ConfigurationError:
        return with_body(likelihood, body), fitted_poses, lengths._replace(cues="keypoints")
    return whole, whole_poses, lengths._replace(cues="keypoint lengths", radii_after=girth.radii_after, poses_after=whole_poses,
                                                cost_before=girth.cost_before, cost_after=girth.cost_after, trace=girth.trace)


def _terms(likelihood: AbstractLikelihood) -> tuple[AbstractLikelihood, ...]:
    """The terms of a (nested) sum, in order; a likelihood that is no sum: itself."""
    if isinstance(likelihood, SumLikelihood):
        return tuple(t for term in likelihood.terms for t in _terms(term))
    return (likelihood,)


def fit_radii(likelihood: AbstractLikelihood, poses, observations, **options) -> tuple[AbstractLikelihood, ShapeCalibration]:
    """The body's capsule radii fitted to frames whose poses are known, its skeleton kept.

    ``calibrate_body`` with the limb lengths held at the body's (prior sd ``HELD_LENGTH_SD`` on
    their logs) and the poses at the given ones (``HELD_POSE_SD_M``, ``HELD_POSE_SD_RAD``), every
    dof free of the clavicles' rest prior: its data weight, sharpened edge and floor band (with a
    ``GroundPlanePrior`` in the likelihood), which ``calibrate_shape`` does not have. It stops once
    its objective stops falling (``RADII_STOP_TOLERANCE``), with Adam's step ``RADII_LEARNING_RATE``. For a file
    whose joints give the skeleton and the poses but not the person's girth, on frames spread over
    the scene (``tracking.prepare_test``'s ``fit_radii``; measured in docs/body.md, "The radii of a
    body fitted to joints"). No ceiling on the final cost (``max_cost`` None unless given): with the
    skeleton and poses held a high cost says the images hold more than the capsules draw (a
    body of another shape, 80x60 noise), not that the fit went astray; a cost that rose is
    still refused.

    Args:
        likelihood: any likelihood that renders a body (the silhouettes' carry the radii).
        poses: (F, D) the frames' poses on the body's skeleton.
        observations: the F frames' observations, a leading F axis on every leaf.
        options: further ``calibrate_body`` settings (``radius_sd``, ``steps``, ...).

    Returns:
        ``(likelihood with the fitted radii and its own skeleton, ShapeCalibration)``.

    Raises:
        ConfigurationError: a fit that does not converge (``calibrate_body``'s checks).
    """
    body = body_of(likelihood)
    names, _, _, lengths = _limb_structure(body)
    fitted, _, report = calibrate_body(likelihood, poses, observations, prior_lengths=dict(zip(names, lengths)),
                                       scale_sd=HELD_LENGTH_SD, proportion_sd=HELD_LENGTH_SD, pose_sd_m=HELD_POSE_SD_M,
                                       pose_sd_rad=HELD_POSE_SD_RAD, neutral_dofs=(),
                                       **{"max_cost": None, "stop_tolerance": RADII_STOP_TOLERANCE,
                                          "learning_rate": RADII_LEARNING_RATE, **options})
    radii = body_of(fitted).radii
    new_body = eqx.tree_at(lambda b: b.radii, body, radii)  # the skeleton exactly as it was (left and right untied)
    return with_body(likelihood, new_body), ShapeCalibration(
        capsule_names=body.capsule_names, radii_before=report.radii_before, radii_after=np.asarray(radii, np.float64),
        cost_before=report.cost_before, cost_after=report.cost_after, trace=report.trace)
