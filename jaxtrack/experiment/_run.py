"""The HumanEva-style experiment of paper 000 sec. 6 (docs/papers.md).

Inputs are sequences: training sequences (poses for the manifold), validation sequences (the
trackers' dynamics, 000 sec. 5.2), and test sequences with silhouettes and cameras. Every
tracker's dynamics are fitted once; then each tracker runs ``runs`` times on every test
sequence with different keys from the first test frame's ground truth. The error is
000 eq. 31 in mm, with per-frame curves (000 Fig. 6) and per-part errors (000 Table 2).
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import equinox as eqx
import jax
import numpy as np

from ..body import part_group_indices
from ..evaluation import mean_joint_error_mm, per_frame_error_mm, per_group_error_mm
from ..image import downsample_silhouettes
from ..io import fit_floor
from ..likelihood import get_likelihood, suggest_window
from ..manifold import ManifoldPrior
from ..tracking import (
    OFF_MANIFOLD_START_MM,
    add_ground_prior,
    build_for_start,
    check_frame_rates,
    check_test_sequence,
    fit_manifold,
    fit_tracker,
    get_tracker,
    leg_length,
    method_problems,
    motion_clearance,
    motion_data,
    prepare_test,
    subject_body,
    track,
    track_and_refine_body,
    track_runs,
    tracker_keys,
)
from ._config import ExperimentConfig
from ._report import method_label, write_outputs, write_progress


def dynamics_parameters(fitted) -> dict:
    """The fitted parameters of a tracker's dynamics, for results.json: every small array field
    of its modules (the manifold they share is described once, elsewhere)."""
    out = {}

    def visit(node, prefix):
        if isinstance(node, ManifoldPrior):
            return
        if isinstance(node, (tuple, list)):
            for i, child in enumerate(node):
                visit(child, f"{prefix}{i}.")
            return
        if isinstance(node, eqx.Module):
            out[f"{prefix}class"] = type(node).__name__
            for field in dataclasses.fields(node):
                value = getattr(node, field.name)
                if eqx.is_array(value) and value.ndim <= 1:
                    out[prefix + field.name] = np.asarray(value, np.float64).round(6).tolist()
                elif isinstance(value, str):
                    out[prefix + field.name] = value
                else:
                    visit(value, f"{prefix}{field.name}.")

    visit(fitted, "")
    return out


def _warn_unreachable(resolved, name: str, results: dict) -> None:
    """Print (and record) a warning where a file's skeleton cannot reach its joints, and where its
    inverse-kinematics residual is above the floor (on every frame, or at some frames)."""
    messages = []
    bad = [] if resolved is None else resolved.unreachable()
    if bad:
        messages.append(f"{name}: the skeleton cannot reach the file's joints ({', '.join(bad)}): a score against this ground "
                        "truth measures the file as much as the tracker")
    report = None if resolved is None else resolved.residual_report()
    if report is not None and report.pattern != "floor":
        messages.append(f"{name}: {report.describe()}")
    for message in messages:
        results.setdefault("warnings", []).append(message)
        print(f"warning: {message}")


def manifold_label(kind: str, latent_dim: int) -> str:
    """The key of a fitted manifold in the results: ``"gpdm-2d"``, ``"gle-3d"``."""
    return f"{kind}-{latent_dim}d"


def shared_window(test, frames, resolution=None):
    """One likelihood window for all test sequences when their images agree in size, so each
    tracker compiles once (the window is a static shape); "auto" (per sequence) otherwise."""
    if any(s.silhouettes is None for s in test):
        return "auto"
    sizes = {tuple(np.asarray(s.silhouettes.shape[-2:])) for s in test}
    if len(sizes) != 1:
        return "auto"
    masks = [s.silhouettes[:, :frames] for s in test]
    if resolution is not None:
        masks = [downsample_silhouettes(m, *resolution) for m in masks]
    windows = [suggest_window((m > 0).astype(np.uint8)) for m in masks]
    return max(w[0] for w in windows), max(w[1] for w in windows)


def _runs(tracker, run_root, scene, config: ExperimentConfig):
    """Each run's ``(poses, joints, infos, seconds)``: run r with key ``fold_in(run_root, r)``,
    one call each, or all in one vmapped call (``config.batch_runs``; its time then counted once,
    shared by the runs)."""
    keys = [jax.random.fold_in(run_root, run) for run in range(config.runs)]
    if not config.batch_runs:
        for key in keys:
            start = time.perf_counter()
            poses, joints, info = track(tracker, key, scene)
            yield poses, joints, info, time.perf_counter() - start
        return
    start = time.perf_counter()
    poses, joints, infos = track_runs(tracker, jax.numpy.stack(keys), scene)
    seconds = (time.perf_counter() - start) / config.runs
    for run in range(config.runs):
        yield poses[run], joints[run], jax.tree.map(lambda x, r=run: x[r], infos), seconds


@dataclasses.dataclass
class ExperimentInputs:
    """What the fit and track stages read, built and checked before any fitting
    (``prepare_inputs``).

    Attributes:
        train_poses, validation_poses: (T_i, D) float64 poses of the training and validation
            takes, each on its own body.
        motion_subjects: per training and validation take's name, its ``SubjectBody``.
        scenes: the prepared test scenes (``tracking.TestScene``), in the order of ``test_names``
            (``prepare_scenes``; empty until the manifolds are fitted when the start is found
            automatically).
        test_names: the test sequences' display names.
        clearance: the ankle's clearance above the floor in the validation motion (metres).
        tests: the test ``Sequence``s.
        window: the likelihood's window, shared by the test scenes (``shared_window``).
        donors: the training and validation takes' bodies (``prepare_test``'s ``donors``).
        root_height, root_height_legs: the validation motion's mean root height and its
            bodies' mean leg length (metres): the automatic start holds the root at the first
            scaled by the test body's legs over the second (``tracking.prepare_test``).
        manifolds: per ``(kind, latent_dim)``, the manifold ``fit_methods`` fitted.
    """

    train_poses: list
    validation_poses: list
    motion_subjects: dict
    scenes: list
    test_names: list
    clearance: float = 0.06
    tests: list = dataclasses.field(default_factory=list)
    window: object = "auto"
    donors: list = dataclasses.field(default_factory=list)
    root_height: float | None = None
    root_height_legs: float | None = None
    manifolds: dict = dataclasses.field(default_factory=dict)


def _warn_tilted_floor(seq, name: str, results: dict) -> None:
    """Print (and record) a warning where a file's joints walk on a tilted floor: the ground
    prior's floor is level (``io.fit_floor``; docs/floor.md, "A tilted capture")."""
    names = None if seq.joint_names is None else [str(n) for n in seq.joint_names]
    if seq.joints3d is None or names is None or not {"lankle", "rankle"} <= set(names):
        return
    floor = fit_floor(seq.joints3d, names)
    if floor.worth_levelling:
        message = (f"{name}: {floor.describe()}; the trackers' floor is level, so the ground prior holds the feet "
                   "at the wrong height there (convert it with --level-floor)")
        results.setdefault("warnings", []).append(message)
        print(f"warning: {message}")


def new_results(config: ExperimentConfig) -> dict:
    """The empty results of an experiment with ``config``: what ``prepare_inputs``,
    ``prepare_scenes``, ``fit_methods`` and ``track_methods`` fill, for a caller that runs the
    stages itself (e.g. to keep the prepared scenes, ``ExperimentInputs.scenes``)."""
    return {"config": config.as_dict(), "complete": False, "manifold": None, "manifolds": {}, "dynamics": {}, "velocity": {},
            "residual": {}, "sequences": {}, "refused": {}, "bodies": {}, "ik_residual_mm": {}, "estimates": {},
            "shape_calibration": {}, "ground_prior": {}, "likelihoods": {}, "start": None}


def prepare_inputs(train, validation, test, config: ExperimentConfig, results: dict, *, names=None, say=print) -> ExperimentInputs:
    """Stage 1 of ``run_experiment``: every file's body and poses, and every test scene (its
    silhouettes, cameras, body, likelihood and ground prior) built and checked, so a bad last
    file fails in seconds, not after the fits and the first tracks; records the bodies, the
    inverse kinematics' residuals, the likelihoods and the ground priors in ``results``. With
    ``config.start == "auto"`` the test files are checked here and their scenes built after the
    fits (``prepare_scenes``): the automatic start searches a fitted manifold."""
    names = names or {}
    train_names = names.get("train") or [f"train{i}" for i in range(len(train))]
    validation_names = names.get("validation") or [f"validation{i}" for i in range(len(validation))]
    test_names = names.get("test") or [f"test{i}" for i in range(len(test))]
    if not train or not validation or not test:
        raise ValueError("the experiment needs at least one training, one validation and one test sequence")
    ik_key = jax.random.key(config.seed)
    observes = get_likelihood(config.likelihood).observes
    for seq, name in zip(test, test_names):
        check_test_sequence(seq, name, observes, likelihood=config.likelihood)
    check_frame_rates([*train, *validation, *test], [*train_names, *validation_names, *test_names])
    # The training and validation takes' bodies and poses: each its own skeleton (the file's, or
    # the one inverse kinematics fits to its joints).
    motion_subjects = {}
    for seq, name in [*zip(train, train_names), *zip(validation, validation_names)]:
        resolved = subject_body(seq, name, key=ik_key)
        if resolved.poses is None:
            raise ValueError(f"{name}: needs 'pose' or 'joints3d' (ground truth) for the experiment")
        motion_subjects[name] = resolved
    train_poses = [motion_subjects[n].poses for n in train_names]
    validation_poses = [motion_subjects[n].poses for n in validation_names]
    donors = [(name, motion_subjects[name], seq.subject) for seq, name in [*zip(train, train_names), *zip(validation, validation_names)]]
    # The ankle's clearance above the floor in the validation motion: the floor's prior while a body is
    # calibrated from the images, and the tracker's ground prior.
    clearance = motion_clearance(validation, validation_poses, skeletons=[motion_subjects[n].body.skeleton for n in validation_names])
    inputs = ExperimentInputs(train_poses, validation_poses, motion_subjects, [], test_names, clearance, tests=list(test),
                              window=shared_window(test, config.frames, config.resolution), donors=donors,
                              **validation_root_height([motion_subjects[n] for n in validation_names]))
    for name, resolved in motion_subjects.items():
        results["ik_residual_mm"][name] = resolved.summary().get("ik_residual_mm")
        _warn_unreachable(resolved, name, results)
    for seq, name in [*zip(train, train_names), *zip(validation, validation_names), *zip(test, test_names)]:
        _warn_tilted_floor(seq, name, results)
    if config.start == "truth":
        prepare_scenes(inputs, config, results, say=say)
    return inputs


def validation_root_height(subjects) -> dict:
    """The validation takes' mean root height over their frames and their bodies' leg length
    (``tracking.leg_length``) averaged the same way, metres (``SubjectBody`` each, its own pose
    layout): ``{"root_height": ..., "root_height_legs": ...}``, where the automatic start holds
    the root (``tracking.prepare_test``)."""
    heights = [s.poses[:, list(s.body.skeleton.pose_layout).index("root_z")] for s in subjects]
    legs = [np.full(len(h), leg_length(s.body)) for s, h in zip(subjects, heights)]
    return {"root_height": float(np.mean(np.concatenate(heights))), "root_height_legs": float(np.mean(np.concatenate(legs)))}


def prepare_scenes(inputs: ExperimentInputs, config: ExperimentConfig, results: dict, *, start_model=None,
                   say=print) -> None:
    """The test scenes (``tracking.prepare_test``) into ``inputs.scenes``, with the ground prior
    where ``config.ground_prior``; records their likelihoods, bodies and ground priors in
    ``results``. ``config.start == "auto"``: each scene's start is found from its first frame
    on ``start_model``'s latent space (``tracking.automatic_start``), the root at
    ``inputs.root_height`` (scaled to the test person's legs where the body is their own);
    every tracker then starts from it."""
    key = jax.random.key(config.seed)
    scenes = [prepare_test(seq, name, key=key, frames=config.frames, window=inputs.window, donors=inputs.donors, say=say,
                           ground_clearance=inputs.clearance, start=config.start, start_model=start_model,
                           root_height=inputs.root_height, root_height_legs=inputs.root_height_legs, **config.scene_options())
              for seq, name in zip(inputs.tests, inputs.test_names)]
    for scene, name in zip(scenes, inputs.test_names):
        results["likelihoods"][name] = {"name": config.likelihood, "options": dict(config.likelihood_options),
                                        "class": type(scene.likelihood).__name__, "pixel_samples": scene.pixel_samples}
        results["bodies"][name] = scene.body_summary()
        results["ik_residual_mm"][name] = results["bodies"][name].get("ik_residual_mm")
        _warn_unreachable(scene.subject, name, results)
        say(f"{name}: body {scene.body_source}{f' ({scene.subject.detail})' if scene.subject.detail else ''}; the start pose is "
            f"{scene.start_error_mm:.1f} mm from frame 0's ground truth")
    if config.ground_prior:
        scenes = [add_ground_prior(scene, inputs.clearance) for scene in scenes]
        for scene, name in zip(scenes, inputs.test_names):
            prior = scene.ground_prior
            results["ground_prior"][name] = {"clearance_m": float(prior.clearance), "validation_clearance_m": inputs.clearance,
                                             "tolerance_m": float(prior.tolerance), "floor_height_m": float(prior.floor_height)}
    inputs.scenes = scenes


def start_manifold(inputs: ExperimentInputs, config: ExperimentConfig, results: dict, *, progress=True, say=print):
    """The manifold the automatic start searches: the first one the experiment's trackers run
    on (in the order of ``config.methods``), or, where none does, a BC-GPLVM of the training
    poses (``tracking.fit_manifold``'s default) fitted for the start alone. Records its label
    in ``results["start"]``."""
    fitted = [spec for spec in config.manifold_specs if spec in inputs.manifolds]
    if fitted:
        kind, latent_dim = fitted[0]
        model = inputs.manifolds[fitted[0]]
    else:
        kind = "bc-gplvm"
        model, info, _ = fit_manifold(inputs.train_poses, None, config.fit_steps, kind=kind, progress=progress,
                                      optimiser=config.fit_optimiser, key=jax.random.key(config.seed))
        latent_dim = model.latent_dim
        say(f"start manifold: {type(model).__name__} on {int(model.data.shape[0])} training frames, latent dim {latent_dim}, "
            f"objective {info.objective:.6g} after {info.steps} steps (no tracker runs on a manifold)")
    results["start"] = {"kind": "auto", "manifold": manifold_label(kind, latent_dim), "root_height_m": inputs.root_height,
                        "root_height_legs_m": inputs.root_height_legs}
    return model


def _refuse(results: dict, method: str, why: str) -> None:
    if method not in results["refused"]:
        results["refused"][method] = why
        print(f"warning: {method_label(method)} refused: {why}")


def fit_methods(inputs: ExperimentInputs, config: ExperimentConfig, results: dict, *, progress=True, say=print) -> dict:
    """Stage 2 of ``run_experiment``: every method's preconditions checked before any fitting
    (a method that cannot run on these data is refused alone, and the others run), the manifolds
    the methods need fitted once per (kind, latent dimension), then each method's dynamics.
    Returns ``{method: fitted dynamics}`` of the methods that can run; records the manifolds,
    the dynamics' parameters and the refusals in ``results``."""
    train_poses, validation_poses = inputs.train_poses, inputs.validation_poses
    for method, why in method_problems(config, train_poses, validation_poses).items():
        _refuse(results, method, why)
    motions = {None: motion_data(train_poses, validation_poses)}
    for kind, latent_dim in config.manifold_specs:
        users = [m for m in config.methods if config.manifold_spec_of(m) == (kind, latent_dim) and m not in results["refused"]]
        if not users:
            continue
        start = time.perf_counter()
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                model, fit_info, starts = fit_manifold(train_poses, latent_dim, config.fit_steps, kind=kind, progress=progress,
                                                       optimiser=config.fit_optimiser, key=jax.random.key(config.seed))
        except (ValueError, np.linalg.LinAlgError) as err:
            for method in users:
                _refuse(results, method, f"its {kind} manifold ({latent_dim}-D) could not be fitted: {err}")
            continue
        notes = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
        for note in notes:
            print(f"warning: {manifold_label(kind, latent_dim)}: {note}")
        fit_s = time.perf_counter() - start
        say(f"manifold: {type(model).__name__} on {int(model.data.shape[0])} training frames, latent dim {model.latent_dim}, "
            f"objective {fit_info.objective:.6g} after {fit_info.steps} steps ({fit_s:.1f} s)")
        results["manifolds"][manifold_label(kind, latent_dim)] = {
            "kind": kind, "class": type(model).__name__, "frames": int(model.data.shape[0]), "latent_dim": model.latent_dim,
            "objective": fit_info.objective, "steps": fit_info.steps, "fit_s": fit_s, "warnings": notes}
        motions[kind, latent_dim] = motion_data(train_poses, validation_poses, model, starts)
        inputs.manifolds[kind, latent_dim] = model
    if results["manifolds"]:
        results["manifold"] = next(iter(results["manifolds"].values()))
    fitted = {}
    for method in config.methods:
        if method in results["refused"]:
            continue
        fit_key, _ = tracker_keys(config.seed, method)
        try:
            fitted[method] = fit_tracker(get_tracker(method), fit_key, motions[config.manifold_spec_of(method)])
        except (ValueError, np.linalg.LinAlgError) as err:
            _refuse(results, method, f"its dynamics could not be fitted: {err}")
            continue
        results["dynamics"][method] = dynamics_parameters(fitted[method])
    return fitted


def _record_dynamics(tracker, method: str, config: ExperimentConfig, results: dict, with_velocity: bool) -> None:
    """The fitted residual and velocity of a built tracker, in results (once per method)."""
    if config.residual_of(method) and method not in results["residual"]:
        carrier = tracker.dynamics.inner if with_velocity else tracker.dynamics
        results["residual"][method] = {"scale": config.residual_of(method), "decay": config.residual_decay_of(method),
                                       "step_rad": np.asarray(carrier.scales, np.float64).round(6).tolist()}
    if with_velocity and method not in results["velocity"]:
        moving = tracker.dynamics
        spreads = {name: np.asarray(getattr(moving, name), np.float64).round(6).tolist()
                   for name in ("acceleration", "initial_speed", "displacement_noise")}
        results["velocity"][method] = {"entries": moving.size, "rest_probability": moving.rest_probability, **spreads}


def _build(method: str, fitted: dict, scene, config: ExperimentConfig, validation_poses, say=None, name: str = ""):
    """Tracker ``method`` for ``scene`` (``tracking.build_for_start``: the fading start where a latent
    tracker without a residual would start off its manifold) and its start's distance from its
    manifold (mm, or None)."""
    _, run_root = tracker_keys(config.seed, method)
    return build_for_start(get_tracker(method), fitted[method], scene.likelihood, config.tracking_budget,
                           start_pose=scene.initial_pose, skeleton=scene.body.skeleton, key=run_root, say=say, name=name,
                           velocity_from=validation_poses if config.velocity_of(method) else None,
                           residual_from=validation_poses, residual_scale=config.residual_of(method),
                           residual_decay=config.residual_decay_of(method), residual_target=config.residual_target_of(method),
                           gait_rate=config.gait_rate_of(method))


def _refined(scene, name: str, method: str, fitted: dict, config: ExperimentConfig, inputs: ExperimentInputs, results: dict, say):
    """``config.refines_body(scene)``: the calibrated body refined on one run of ``method``
    (``tracking.track_and_refine_body``), recorded in ``results["bodies"][name]``."""
    _, run_root = tracker_keys(config.seed, method)
    tracker, _ = _build(method, fitted, scene, config, inputs.validation_poses)
    first = scene.body_summary()
    scene = track_and_refine_body(scene, tracker, run_root, start_from_truth=config.start == "truth",
                                  ground_clearance=inputs.clearance, name=name)
    results["bodies"][name] = {**scene.body_summary(), "refined_with": method, "first_pass": first}
    say(f"{name}: body refined on a {method_label(method)} run's frames spread over the sequence; the start pose is "
        f"{scene.start_error_mm:.1f} mm from frame 0's ground truth")
    return scene


def track_methods(inputs: ExperimentInputs, fitted: dict, config: ExperimentConfig, results: dict, *, out_dir=None,
                  say=print) -> None:
    """Stage 3 of ``run_experiment``: each fitted method built for each test scene and run
    ``config.runs`` times with its own keys; the errors (000 eq. 31), curves, per-part errors,
    frames/s, ESS and degenerate fractions recorded in ``results`` (written to ``out_dir`` after
    each method, so an interruption loses the one in progress at most)."""
    validation_poses = inputs.validation_poses
    methods = [m for m in config.methods if m in fitted]
    for index, (scene, name) in enumerate(zip(inputs.scenes, inputs.test_names)):
        if config.refines_body(scene) and methods:
            scene = inputs.scenes[index] = _refined(scene, name, methods[0], fitted, config, inputs, results, say)
        if scene.shape_calibration is not None:
            report = scene.shape_calibration
            results["shape_calibration"][name] = {
                "capsules": list(report.capsule_names), "radii_before_m": report.radii_before.round(4).tolist(),
                "radii_after_m": report.radii_after.round(4).tolist(), "cost_before": report.cost_before, "cost_after": report.cost_after,
                "steps": len(report.trace),
            }
            say(f"{name}: body calibrated on frame 0, silhouette cost {report.cost_before:.3f} -> {report.cost_after:.3f}")
        groups = part_group_indices(scene.body.skeleton)
        per_method = results["sequences"][name] = {}
        for method in methods:
            velocity_from = validation_poses if config.velocity_of(method) else None
            tracker, off_manifold = _build(method, fitted, scene, config, validation_poses, say=say, name=name)
            _record_dynamics(tracker, method, config, results, velocity_from is not None)
            _, run_root = tracker_keys(config.seed, method)
            errors, curves, group_errors, times, ess, degenerate, restarts, estimates = [], [], [], [], [], [], [], None
            for run, (poses, joints, info, seconds) in enumerate(_runs(tracker, run_root, scene, config)):
                times.append(seconds)
                errors.append(float(mean_joint_error_mm(joints, scene.truth_joints)))
                curves.append(np.asarray(per_frame_error_mm(joints, scene.truth_joints)))
                group_errors.append({g: float(v) for g, v in per_group_error_mm(joints, scene.truth_joints, groups).items()})
                ess.append(float(np.mean(np.asarray(info.ess))))
                degenerate.append(float(np.mean(np.asarray(info.degenerate))))
                if info.restarted is not None:  # a filter that restarts when lost (RecoveringSIR)
                    restarts.append(int(np.sum(np.asarray(info.restarted))))
                if run == 0:
                    estimates = (poses, joints)
            steady = times[1:] or times
            per_method[method] = {
                "error_mm_mean": float(np.mean(errors)),
                "error_mm_std": float(np.std(errors)),
                "error_mm_per_run": errors,
                "per_frame_error_mm": np.mean(curves, axis=0).round(2).tolist(),
                "per_frame_error_mm_per_run": [c.round(2).tolist() for c in curves],
                "per_group_error_mm": {g: float(np.mean([e[g] for e in group_errors])) for g in groups},
                "frames_per_second": float(scene.num_frames / np.median(steady)),
                "first_run_s (includes compile)": float(times[0]),
                # compile time: the first run less a steady one (None with one run, or batched runs)
                "compile_s": float(times[0] - np.median(steady)) if len(times) > 1 and not config.batch_runs else None,
                "frame0_error_mm": float(np.mean([c[0] for c in curves])),
                "start_error_mm": scene.start_error_mm,
                # the start's projection onto the tracker's manifold (mm; None: not measured) and whether
                # the tracker was given the fading start for it (tracking.build_for_start)
                "start_off_manifold_mm": off_manifold,
                "fading_start_added": bool(off_manifold is not None and off_manifold > OFF_MANIFOLD_START_MM),
                "mean_ess": float(np.mean(ess)),
                "degenerate_fraction": float(np.mean(degenerate)),
                "restarts_per_run": restarts or None,
                "likelihood_evaluations_per_frame": config.budget,
            }
            results["estimates"].setdefault(name, {})[method] = estimates
            say(f"{name} {method_label(method):>8}: {np.mean(errors):6.1f} ({np.std(errors):4.1f}) mm over {config.runs} runs, "
                f"frame 0 {per_method[method]['frame0_error_mm']:.1f} mm, {per_method[method]['frames_per_second']:.1f} frames/s")
            if np.mean(degenerate) > 0:  # printed whatever ``progress`` says: these numbers are not to be trusted
                print(f"warning: {name} {method_label(method)}: on {100 * np.mean(degenerate):.0f} % of the frames every particle's "
                      "likelihood was -inf or NaN (the filter tracked blind on uniform weights)")
            if out_dir is not None:  # saved as it goes: an interruption loses the tracker in progress at most
                write_progress(results, out_dir)


def run_experiment(train, validation, test, config: ExperimentConfig | None = None, *, out_dir=None,
                   names=None, progress=True, animations=True) -> dict:
    """Run the experiment in three stages, ``prepare_inputs`` (every file checked and every test
    scene built), ``fit_methods`` (manifolds and dynamics) and ``track_methods`` (the runs), then
    the report (``write_outputs``); returns the results (and writes them under ``out_dir`` if
    given).

    Args:
        train, validation, test: lists of ``Sequence``.
        config: the settings (default ``ExperimentConfig()``, a ``tracking.TrackingSpec`` plus
            the trackers, runs, frames and seed); ``config.methods`` are registered tracker names.
        names: dict with lists "train", "validation", "test" of display names (file names).

    Returns:
        a dict with "config", "manifolds" (per manifold fitted, keyed ``manifold_label(kind,
        latent_dim)``, e.g. "gpdm-2d": kind, class, frames, latent dimension, objective, steps,
        fit time; "manifold" is the first of them), "dynamics" (each tracker's fitted parameters),
        "velocity" (per tracker that carries one, ``config.velocity_of``: how many leading state
        entries carry a velocity and its fitted spreads), "residual" (per tracker that carries an
        off-manifold pose residual, ``config.residual_of``: its scale and fitted step scales),
        "shape_calibration" (per test sequence, with ``config.calibrate_shape``), "ground_prior"
        (per test sequence, with ``config.ground_prior``: the ankle's clearance used, metres, that of
        the validation motion, the tolerance and the floor's height),
        "sequences" (per test sequence and tracker: mean and sd of the error over the runs, the
        per-frame curve (mean over the runs, and each run's), the error at frame 0 and the start
        pose's, per-part errors, frames/s, the mean ESS and the degenerate fraction),
        "bodies" (per test sequence, ``TestScene.body_summary``: where its body came from, its limb
        lengths and radii, the calibration, the inverse kinematics' residual per joint),
        "ik_residual_mm" (per file with joints, the residual's mean, max and per-joint figures),
        "likelihoods" (per test sequence, the registered likelihood's name, options, class and
        pixel samples), "refused" (per method that could not run on these data, the reason: every other method
        still runs), "warnings" (files whose skeleton cannot reach their joints), "start" (``{"kind":
        "truth"}``, or with ``config.start == "auto"`` the manifold searched and the root height
        held, ``start_manifold``) and "estimates" (first run's poses and joints).
    """
    config = ExperimentConfig() if config is None else config
    say = print if progress else (lambda *a, **k: None)
    results = new_results(config)
    inputs = prepare_inputs(train, validation, test, config, results, names=names, say=say)
    fitted = fit_methods(inputs, config, results, progress=progress, say=say)
    if config.start == "auto":  # the start searched on a fitted manifold, the same for every tracker
        prepare_scenes(inputs, config, results, start_model=start_manifold(inputs, config, results, progress=progress, say=say),
                       say=say)
    else:
        results["start"] = {"kind": "truth"}
    track_methods(inputs, fitted, config, results, out_dir=out_dir, say=say)
    results["complete"] = True
    if out_dir is not None:
        write_outputs(results, test, inputs.test_names, out_dir, animations=animations)
    return results
