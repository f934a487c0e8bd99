"""The HumanEva-style experiment of paper 000 sec. 6 (../shared/METHODS.md section 4).

Inputs are sequence files: training sequences (poses for the manifold), a validation sequence
(the dynamics' noise scales, 000 sec. 5.2), and test sequences with silhouettes and cameras.
Each method runs ``runs`` times with different keys from the first test frame's ground truth;
the error is 000 eq. 31 in mm, with per-frame curves (000 Fig. 6) and per-part errors
(000 Table 2).
"""

from __future__ import annotations

import dataclasses
import json
import os
import time

import jax
import jax.numpy as jnp
import numpy as np

from .body import HUMANEVA_JOINTS, check_joint_names, forward_kinematics, inverse_kinematics, part_group_indices
from .evaluation import mean_joint_error_mm, per_frame_error_mm, per_group_error_mm
from .filters import (
    MRPF_PROPOSALS,
    fit_noise_scales,
    make_apf,
    make_gpapf,
    make_latent_pf,
    make_manifold_prior,
    make_mrpf,
    make_sir,
    run_filter,
)
from .io import Sequence, load_sequence
from .likelihood import check_silhouettes, make_silhouette_likelihood

METHODS = ("sir", "apf", "mrpf", "gpapf", "latentpf")
METHOD_LABELS = {"sir": "SIR", "apf": "APF", "mrpf": "MRPF", "gpapf": "GPAPF", "latentpf": "LatentPF"}


@dataclasses.dataclass(frozen=True)
class ExperimentConfig:
    """Settings of the experiment (defaults: paper 000 sec. 6.1).

    Attributes:
        methods: trackers to compare, from ``METHODS``.
        budget: likelihood evaluations per frame (SIR, MRPF, LatentPF: that many particles;
            APF and GPAPF: ``layers`` layers of ``budget / layers``).
        layers: annealing layers of APF and GPAPF (GPAPF's last one is its full-pose layer).
        runs: runs per method, each with its own key.
        latent_dim: dimension of the BC-GPLVM latent space.
        fit_steps: L-BFGS iterations for the manifold.
        likelihood_scale: temperature of the silhouette likelihood, ``ln p = -scale * cost``.
        frames: track only the first ``frames`` frames of each test sequence (None: all).
        seed: base PRNG seed.
        mrpf_proposal: how MRPF draws poses: ``"product"`` (eq. 28 sampled exactly) or
            ``"prior"`` (000 Alg. 1 as printed); see ``jaxtrack.filters.MRPF``.
    """

    methods: tuple[str, ...] = METHODS
    budget: int = 500
    layers: int = 5
    runs: int = 5
    latent_dim: int = 2
    fit_steps: int = 300
    likelihood_scale: float = 100.0
    frames: int | None = None
    seed: int = 0
    mrpf_proposal: str = "product"

    def __post_init__(self):
        unknown = [m for m in self.methods if m not in METHODS]
        if unknown or not self.methods:
            raise ValueError(f"unknown methods {unknown}; choose from {list(METHODS)}")
        if self.mrpf_proposal not in MRPF_PROPOSALS:
            raise ValueError(f"mrpf_proposal must be one of {MRPF_PROPOSALS}, got {self.mrpf_proposal!r}")
        if self.budget < 1 or self.runs < 1 or self.layers < 1:
            raise ValueError("budget, runs and layers must be positive")
        annealed = [m for m in self.methods if m in ("apf", "gpapf")]
        if annealed and self.budget % self.layers:
            raise ValueError(
                f"a budget of {self.budget} likelihood evaluations cannot be split into {self.layers} equal "
                f"annealing layers for {', '.join(annealed).upper()}; use a multiple of {self.layers}"
            )
        if "gpapf" in self.methods and self.layers < 2:
            raise ValueError("GPAPF needs at least 2 layers (annealing layers plus its final full-pose layer)")


def sequence_poses(sequence: Sequence, name: str, *, seed: int = 0) -> np.ndarray:
    """The (T, 32) pose vectors of a sequence: its ``pose`` key, or inverse kinematics on
    ``joints3d`` with the sequence's own skeleton when it has no poses."""
    if sequence.joint_names is not None:
        check_joint_names([str(n) for n in sequence.joint_names], HUMANEVA_JOINTS, f"{name} joint_names")
    if sequence.pose is not None:
        return np.asarray(sequence.pose, np.float64)
    if sequence.joints3d is None:
        raise ValueError(f"{name}: needs 'pose' or 'joints3d' (ground truth) for the experiment")
    return np.asarray(inverse_kinematics(sequence.joints3d, key=jax.random.key(seed)).pose, np.float64)


def ground_truth_joints(sequence: Sequence, poses: np.ndarray, skeleton) -> np.ndarray:
    if sequence.joints3d is not None:
        return np.asarray(sequence.joints3d, np.float64)
    return np.asarray(forward_kinematics(skeleton, jnp.asarray(poses, skeleton.offsets.dtype)), np.float64)


def check_test_sequence(sequence: Sequence, name: str):
    """A test sequence needs silhouettes, cameras and ground truth; raise ``ValueError`` if not."""
    missing = [what for what, ok in (("silhouettes", sequence.silhouettes is not None), ("cameras", sequence.has_cameras)) if not ok]
    if missing:
        raise ValueError(f"{name}: a test sequence needs {' and '.join(missing)} (found neither key)" if len(missing) == 2
                         else f"{name}: a test sequence needs {missing[0]}, which the file lacks")
    if sequence.joints3d is None and sequence.pose is None:
        raise ValueError(f"{name}: a test sequence needs ground truth ('joints3d' or 'pose') to be scored")


def make_tracker(method: str, config: ExperimentConfig, likelihood, prior, scales, dtype=jnp.float32):
    """The tracker of ``method`` with the experiment's budget and fitted noise scales."""
    budget, layers = config.budget, config.layers
    log_lik = likelihood.log_likelihood
    if method == "sir":
        return make_sir(log_lik, scales.s_xx, budget, dtype=dtype)
    if method == "apf":
        return make_apf(log_lik, scales.s_xx, budget // layers, layers, dtype=dtype)
    if method == "mrpf":
        if config.mrpf_proposal == "prior":  # 000 Alg. 1 as printed, with eqs. 29 and 30 fitted separately
            return make_mrpf(log_lik, prior, scales.s_xx, scales.s_xz, scales.s_zx_residual, budget, dtype=dtype, proposal="prior")
        return make_mrpf(log_lik, prior, scales.mrpf_s_xx, scales.s_xz, scales.s_zx, budget, dtype=dtype)
    if method == "gpapf":
        return make_gpapf(log_lik, prior, scales.s_global, scales.nu, budget // layers, layers - 1, s_final=0.5 * scales.s_xx, dtype=dtype)
    if method == "latentpf":
        return make_latent_pf(log_lik, prior, scales.s_global, scales.nu, budget, dtype=dtype)
    raise ValueError(f"unknown method {method!r}")


def fit_manifold(train_poses: list[np.ndarray], latent_dim: int, steps: int, *, global_dims: int = 6, progress=False):
    """BC-GPLVM (000 eqs. 21-22) on the joint angles of the training sequences (float64)."""
    from .manifold import fit_model, make_bc_gplvm

    angles = np.concatenate([p[:, global_dims:] for p in train_poses])
    starts = tuple(int(v) for v in np.cumsum([0] + [len(p) for p in train_poses]))
    with jax.enable_x64(True):
        model = make_bc_gplvm(angles, latent_dim)
        fitted, info = fit_model(model, max_steps=steps, progress=progress)
    return fitted, info, starts


def run_experiment(train, validation, test, config: ExperimentConfig = ExperimentConfig(), *, out_dir=None,
                   names=None, progress=True, animations=True) -> dict:
    """Run the experiment; returns the results (and writes them under ``out_dir`` if given).

    Args:
        train, validation, test: lists of ``Sequence`` (validation: one or more).
        names: dict with lists "train", "validation", "test" of display names (file names).
    """
    say = print if progress else (lambda *a, **k: None)
    names = names or {}
    train_names = names.get("train") or [f"train{i}" for i in range(len(train))]
    validation_names = names.get("validation") or [f"validation{i}" for i in range(len(validation))]
    test_names = names.get("test") or [f"test{i}" for i in range(len(test))]
    if not train or not validation or not test:
        raise ValueError("the experiment needs at least one training, one validation and one test sequence")
    for seq, name in zip(test, test_names):
        check_test_sequence(seq, name)
    train_poses = [sequence_poses(s, n, seed=config.seed) for s, n in zip(train, train_names)]
    validation_poses = [sequence_poses(s, n, seed=config.seed) for s, n in zip(validation, validation_names)]

    start = time.perf_counter()
    model, fit_info, starts = fit_manifold(train_poses, config.latent_dim, config.fit_steps, progress=progress)
    fit_s = time.perf_counter() - start
    say(f"manifold: BC-GPLVM on {sum(map(len, train_poses))} training frames, latent dim {config.latent_dim}, "
        f"objective {fit_info.objective:.6g} after {fit_info.steps} steps ({fit_s:.1f} s)")
    with jax.enable_x64(True):
        prior64 = make_manifold_prior(model, train_poses[0].shape[1])
        scales = fit_noise_scales(prior64, validation_poses, starts)
    prior = prior64.astype(jnp.float32)

    results = {
        "config": dataclasses.asdict(config),
        "manifold": {"class": type(model).__name__, "frames": int(model.data.shape[0]), "objective": fit_info.objective,
                     "steps": fit_info.steps, "fit_s": fit_s},
        "noise_scales": {k: np.asarray(v).round(6).tolist() for k, v in scales._asdict().items()},
        "sequences": {},
        "estimates": {},
    }
    window = shared_window(test, config.frames)
    for seq, name in zip(test, test_names):
        frames = seq.silhouettes.shape[1] if config.frames is None else min(config.frames, seq.silhouettes.shape[1])
        rig = seq.rig(dtype=jnp.float32)
        body = seq.body(dtype=jnp.float32)
        observed = check_silhouettes(seq.silhouettes, rig, name=f"{name} silhouettes")[:, :frames]
        truth_poses = sequence_poses(seq, name, seed=config.seed)[:frames]
        truth = ground_truth_joints(seq, truth_poses, body.skeleton)[:frames]
        seq_window = window if window is not None else "auto"
        likelihood = make_silhouette_likelihood(body, rig, scale=config.likelihood_scale, window=seq_window, silhouettes=observed)
        observations = jnp.asarray(np.moveaxis(observed, 1, 0))  # (T, C, H, W)
        initial = jnp.asarray(truth_poses[0], jnp.float32)
        groups = part_group_indices(body.skeleton)
        per_method = {}
        for m_index, method in enumerate(config.methods):
            tracker = make_tracker(method, config, likelihood, prior, scales)
            errors, curves, group_errors, times, ess, estimates = [], [], [], [], [], None
            for run in range(config.runs):
                key = jax.random.fold_in(jax.random.fold_in(jax.random.key(config.seed), m_index), run)
                start = time.perf_counter()
                _, info = run_filter(tracker, key, initial, observations)
                poses = np.asarray(jax.block_until_ready(info.estimate), np.float64)
                times.append(time.perf_counter() - start)
                joints = np.asarray(forward_kinematics(body.skeleton, jnp.asarray(poses, jnp.float32)), np.float64)
                errors.append(float(mean_joint_error_mm(joints, truth)))
                curves.append(np.asarray(per_frame_error_mm(joints, truth)))
                group_errors.append({g: float(v) for g, v in per_group_error_mm(joints, truth, groups).items()})
                ess.append(float(np.mean(np.asarray(info.ess))))
                if run == 0:
                    estimates = (poses, joints)
            steady = times[1:] or times
            per_method[method] = {
                "error_mm_mean": float(np.mean(errors)),
                "error_mm_std": float(np.std(errors)),
                "error_mm_per_run": errors,
                "per_frame_error_mm": np.mean(curves, axis=0).round(2).tolist(),
                "per_group_error_mm": {g: float(np.mean([e[g] for e in group_errors])) for g in groups},
                "frames_per_second": float(frames / np.median(steady)),
                "first_run_s (includes compile)": float(times[0]),
                "mean_ess": float(np.mean(ess)),
                "likelihood_evaluations_per_frame": config.budget,
            }
            results["estimates"].setdefault(name, {})[method] = estimates
            say(f"{name} {METHOD_LABELS[method]:>8}: {np.mean(errors):6.1f} ({np.std(errors):4.1f}) mm over {config.runs} runs, "
                f"{per_method[method]['frames_per_second']:.1f} frames/s")
        results["sequences"][name] = per_method
    if out_dir is not None:
        write_outputs(results, test, test_names, out_dir, animations=animations)
    return results


def shared_window(test, frames):
    """One likelihood window for all test sequences when their images agree in size, so each
    tracker compiles once (the window is a static shape); None otherwise."""
    from .likelihood import suggest_window

    sizes = {tuple(np.asarray(s.silhouettes.shape[-2:])) for s in test}
    if len(sizes) != 1:
        return None
    windows = [suggest_window((s.silhouettes[:, :frames] > 0).astype(np.uint8)) for s in test]
    return max(w[0] for w in windows), max(w[1] for w in windows)


def results_table(results: dict) -> str:
    """Markdown table in the layout of 000 Table 1: one row per test sequence, one column per
    method, ``mean (std)`` of the eq. 31 error in mm over the runs."""
    methods = list(results["config"]["methods"])
    lines = ["| Sequence | " + " | ".join(METHOD_LABELS[m] for m in methods) + " |",
             "|---|" + "---:|" * len(methods)]
    for name, per_method in results["sequences"].items():
        cells = [f"{per_method[m]['error_mm_mean']:.0f} ({per_method[m]['error_mm_std']:.0f})" for m in methods]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def plot_error_curves(results: dict, path: str) -> str:
    """Per-frame error of each method (mean over runs), one panel per test sequence (000 Fig. 6)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sequences = list(results["sequences"])
    fig, axes = plt.subplots(len(sequences), 1, figsize=(7, 2.8 * len(sequences)), squeeze=False)
    for ax, name in zip(axes[:, 0], sequences):
        for method, values in results["sequences"][name].items():
            ax.plot(values["per_frame_error_mm"], label=METHOD_LABELS[method], lw=1.2)
        ax.set_title(name, fontsize=10)
        ax.set_xlabel("frame")
        ax.set_ylabel("error (mm)")
        ax.legend(fontsize=7, ncol=len(results["sequences"][name]))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_outputs(results: dict, test, test_names, out_dir: str, *, animations: bool = True) -> dict:
    """``results.json``, ``table.md``, ``error_curves.png`` and one overlay GIF per test sequence
    (the estimate of the method with the lowest error, first run) under ``out_dir``."""
    from .viz import animation

    os.makedirs(out_dir, exist_ok=True)
    paths = {"results": os.path.join(out_dir, "results.json"), "table": os.path.join(out_dir, "table.md"),
             "curves": os.path.join(out_dir, "error_curves.png")}
    serialisable = {k: v for k, v in results.items() if k != "estimates"}
    with open(paths["results"], "w") as handle:
        json.dump(serialisable, handle, indent=1)
    with open(paths["table"], "w") as handle:
        handle.write(results_table(results))
    plot_error_curves(results, paths["curves"])
    if animations:
        for seq, name in zip(test, test_names):
            per_method = results["sequences"][name]
            best = min(per_method, key=lambda m: per_method[m]["error_mm_mean"])
            joints = results["estimates"][name][best][1]
            frames = joints.shape[0]
            clipped = seq.replace(silhouettes=seq.silhouettes[:, :frames], images=None,
                                  joints3d=None if seq.joints3d is None else seq.joints3d[:frames], pose=None, pose_layout=None)
            stem = os.path.splitext(os.path.basename(name))[0].replace(" ", "_")
            paths[f"animation {name}"] = animation(clipped, os.path.join(out_dir, f"{stem}_{best}.gif"), estimate=joints, every=2)
    return paths


def load_sequences(paths) -> tuple[list[Sequence], list[str]]:
    return [load_sequence(p) for p in paths], [os.path.basename(p) for p in paths]


def track_sequence(sequence: Sequence, model, header: dict, method: str, validation: Sequence, *, budget: int = 500,
                   layers: int = 5, likelihood_scale: float = 100.0, seed: int = 0, name: str = "test"):
    """``jaxtrack track``: one tracker with a saved manifold model on one test sequence.

    Returns ``(estimated_poses (T, D), estimated_joints (T, J, 3), info)``.
    """
    check_test_sequence(sequence, name)
    poses = sequence_poses(sequence, name, seed=seed)
    layout = header.get("extra", {}).get("pose_layout")
    expected = [str(n) for n in sequence.pose_layout[6:]] if sequence.pose_layout is not None else None
    if expected is None:
        from .body import humaneva_skeleton

        expected = list(humaneva_skeleton().pose_layout[6:])
    if layout is not None and list(layout) != expected:
        raise ValueError(f"the model was fitted on another skeleton: its pose layout {layout[:4]}... "
                         f"({len(layout)} entries) differs from {name}'s {expected[:4]}... ({len(expected)} entries)")
    if model.data.shape[1] != poses.shape[1] - 6:
        raise ValueError(f"the model has {model.data.shape[1]} pose entries, {name} has {poses.shape[1] - 6} joint angles")
    config = ExperimentConfig(methods=(method,), budget=budget, layers=layers, runs=1, likelihood_scale=likelihood_scale, seed=seed)
    with jax.enable_x64(True):
        prior64 = make_manifold_prior(model, poses.shape[1])
        scales = fit_noise_scales(prior64, [sequence_poses(validation, "validation", seed=seed)], header.get("sequence_starts"))
    rig, body = sequence.rig(dtype=jnp.float32), sequence.body(dtype=jnp.float32)
    observed = check_silhouettes(sequence.silhouettes, rig, name=f"{name} silhouettes")
    likelihood = make_silhouette_likelihood(body, rig, scale=likelihood_scale, silhouettes=observed)
    tracker = make_tracker(method, config, likelihood, prior64.astype(jnp.float32), scales)
    _, info = run_filter(tracker, jax.random.key(seed), jnp.asarray(poses[0], jnp.float32), jnp.asarray(np.moveaxis(observed, 1, 0)))
    estimate = np.asarray(info.estimate, np.float64)
    joints = np.asarray(forward_kinematics(body.skeleton, jnp.asarray(estimate, jnp.float32)), np.float64)
    return estimate, joints, info


