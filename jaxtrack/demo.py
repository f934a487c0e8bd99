"""``jaxtrack demo``: the pipeline end to end on the embedded synthetic default.

``run_demo`` (the default) is a small version of the experiment of 000 sec. 6: synthetic walks
and jogs of two subjects train a BC-GPLVM, another pair of sequences fits the trackers' dynamics, and
SIR, APF, MRPF, GPAPF and LatentPF track two rendered test scenes; it prints the table of
000 Table 1 and writes the results, error curves and an overlay animation.

``run_likelihood_demo`` (``jaxtrack demo --show-likelihood``) shows the likelihood itself:

1. generate a walk for synthetic subject S1 and render it into 4 noisy silhouette views;
2. save the scene as a sequence file and read it back (validated);
3. score the true pose against perturbed poses with the windowed silhouette likelihood;
4. refine perturbed poses by gradient descent on the soft likelihood (autodiff through the
   rasteriser) and report the joint error in mm (000 eq. 31) before and after;
5. write a contact sheet (PNG) and an animation (GIF).
"""

from __future__ import annotations

import dataclasses
import os
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from .body import forward_kinematics
from .camera import default_rig
from .data import SilhouetteNoise, build_scene, generate_motion
from .evaluation import mean_joint_error_mm
from .io import load_sequence, save_sequence
from .likelihood import check_silhouettes, make_silhouette_likelihood
from .viz import animation, contact_sheet


@dataclasses.dataclass
class DemoReport:
    """What the demo measured."""

    scene_path: str
    contact_sheet_path: str
    animation_path: str
    num_frames: int
    window: tuple[int, int] | None
    truth_wins_fraction: float
    likelihood_compile_s: float
    likelihood_ms_per_frame: float
    particles: int
    refine_error_before_mm: float
    refine_error_after_mm: float


def perturb_poses(key, pose, count: int, angle_sigma: float = 0.15, position_sigma: float = 0.05):
    """``count`` Gaussian perturbations of one pose: radians on angles, metres on the root."""
    sigma = jnp.full(pose.shape, angle_sigma, pose.dtype).at[:3].set(position_sigma)
    return pose + sigma * jax.random.normal(key, (count,) + pose.shape, pose.dtype)


def refine_pose(likelihood, pose0, observed, *, steps: int = 80, learning_rate: float = 0.02):
    """Gradient ascent (Adam) on the soft silhouette log-likelihood from an initial pose."""
    optimiser = optax.adam(learning_rate)
    skeleton = likelihood.body.skeleton

    def loss(pose):
        return -likelihood.log_likelihood(pose[None], observed)[0]

    def step(carry, _):
        pose, state = carry
        value, grad = jax.value_and_grad(loss)(pose)
        updates, state = optimiser.update(grad, state)
        pose = skeleton.clip_to_limits(optax.apply_updates(pose, updates))
        return (pose, state), value

    (pose, _), trace = jax.lax.scan(step, (pose0, optimiser.init(pose0)), None, length=steps)
    return pose, trace


def run_likelihood_demo(
    out_dir: str = "jaxtrack_demo",
    *,
    seed: int = 0,
    num_frames: int = 60,
    particles: int = 500,
    refine_frames: int = 4,
    width: int = 80,
    height: int = 60,
    verbose: bool = True,
) -> DemoReport:
    """Run the demo and write its files under ``out_dir``; returns the measured figures."""
    say = print if verbose else (lambda *a, **k: None)
    key = jax.random.key(seed)
    k_motion, k_scene, k_perturb, k_refine = jax.random.split(key, 4)

    say(f"[1/5] synthetic walk (subject S1, {num_frames} frames at 60 Hz) seen by 4 cameras at {width}x{height}")
    motion = generate_motion("walk", "S1", num_frames=num_frames, fps=60.0, key=k_motion)
    rig = default_rig(width, height)
    scene = build_scene(k_scene, motion, rig, SilhouetteNoise(), progress=verbose)

    os.makedirs(out_dir, exist_ok=True)
    scene_path = os.path.join(out_dir, "scene.npz")
    save_sequence(scene_path, scene)
    scene = load_sequence(scene_path)
    say(f"[2/5] wrote and re-read {scene_path}: silhouettes {scene.silhouettes.shape}, walking speed {motion.speed:.2f} m/s")

    observed = jnp.asarray(check_silhouettes(scene.silhouettes, rig))  # (C, T, H, W)
    body = scene.body()
    likelihood = make_silhouette_likelihood(body, rig, edge_width=1.0, silhouettes=observed)
    truth = jnp.asarray(scene.pose, jnp.float32)

    score = eqx.filter_jit(lambda lik, poses, obs: lik.log_likelihood(poses, obs))
    keys = jax.random.split(k_perturb, num_frames)
    wins, times, compile_s = 0, [], 0.0
    for t in range(num_frames):
        candidates = perturb_poses(keys[t], truth[t], particles).at[0].set(truth[t])
        start = time.perf_counter()
        loglik = jax.block_until_ready(score(likelihood, candidates, observed[:, t]))
        elapsed = time.perf_counter() - start
        if t == 0:
            compile_s = elapsed
        else:
            times.append(elapsed)
        wins += int(jnp.argmax(loglik) == 0)
    ms = 1000 * float(np.median(times)) if times else float("nan")
    say(
        f"[3/5] likelihood of {particles} poses x 4 views, window {likelihood.window}: first call "
        f"{compile_s:.2f} s (compile), then median {ms:.1f} ms/frame; the true pose scores best "
        f"in {wins}/{num_frames} frames"
    )

    frames = np.linspace(0, num_frames - 1, refine_frames).round().astype(int)
    refine = eqx.filter_jit(refine_pose)
    before, after = [], []
    for i, t in enumerate(frames):
        start_pose = perturb_poses(jax.random.fold_in(k_refine, i), truth[t], 1, 0.12, 0.04)[0]
        refined, _ = refine(likelihood, start_pose, observed[:, t])
        true_joints = forward_kinematics(body.skeleton, truth[t])[None]
        before.append(float(mean_joint_error_mm(forward_kinematics(body.skeleton, start_pose)[None], true_joints)))
        after.append(float(mean_joint_error_mm(forward_kinematics(body.skeleton, refined)[None], true_joints)))
    say(
        f"[4/5] gradient refinement through the soft rasteriser on {refine_frames} frames: "
        f"joint error {np.mean(before):.0f} mm -> {np.mean(after):.0f} mm (000 eq. 31)"
    )

    sheet = contact_sheet(scene, os.path.join(out_dir, "contact_sheet.png"))
    gif = animation(scene, os.path.join(out_dir, "scene.gif"), every=2)
    say(f"[5/5] wrote {sheet} and {gif}")
    return DemoReport(
        scene_path=scene_path,
        contact_sheet_path=sheet,
        animation_path=gif,
        num_frames=num_frames,
        window=likelihood.window,
        truth_wins_fraction=wins / num_frames,
        likelihood_compile_s=compile_s,
        likelihood_ms_per_frame=ms,
        particles=particles,
        refine_error_before_mm=float(np.mean(before)),
        refine_error_after_mm=float(np.mean(after)),
    )


DEMO_TRAINING = (("walk", "S1"), ("jog", "S1"), ("walk", "S2"), ("jog", "S2"))
DEMO_VALIDATION = (("walk", "S1"), ("jog", "S2"))
DEMO_TEST = (("walk", "S1"), ("jog", "S2"))


def demo_sequences(key, *, train_frames=80, validation_frames=80, test_frames=40, fps=60.0, width=80, height=60, progress=False,
                   noise: SilhouetteNoise | None = None):
    """Synthetic training, validation and test sequences (walk and jog of subjects S1 and S2);
    the test ones rendered with background-subtraction noise (``noise``, default
    ``SilhouetteNoise()``; ``data.NO_NOISE`` for none) in the default 4-camera rig."""
    from .data import motion_sequence

    def motion(gait, subject, frames, tag):
        return generate_motion(gait, subject, num_frames=frames, fps=fps, key=jax.random.fold_in(key, tag))

    train = [motion_sequence(motion(g, s, train_frames, i)) for i, (g, s) in enumerate(DEMO_TRAINING)]
    validation = [motion_sequence(motion(g, s, validation_frames, 100 + i)) for i, (g, s) in enumerate(DEMO_VALIDATION)]
    rig = default_rig(width, height)
    test = [
        build_scene(jax.random.fold_in(key, 300 + i), motion(g, s, test_frames, 200 + i), rig,
                    SilhouetteNoise() if noise is None else noise, progress=progress)
        for i, (g, s) in enumerate(DEMO_TEST)
    ]
    names = {
        "train": [f"{s} {g} (train)" for g, s in DEMO_TRAINING],
        "validation": [f"{s} {g} (validation)" for g, s in DEMO_VALIDATION],
        "test": [f"{s} {g}" for g, s in DEMO_TEST],
    }
    return train, validation, test, names


def run_demo(out_dir: str = "jaxtrack_demo", *, seed: int = 0, frames: int = 40, budget: int = 300, runs: int = 2,
             methods=None, velocity: bool | None = None, manifold: str | None = None, ground_prior: bool = True,
             verbose: bool = True):
    """The small experiment (module docstring); returns ``(results, paths)``.

    Args:
        methods: registered tracker names (default: the papers' five).
        velocity, manifold, ground_prior: as ``ExperimentConfig``'s (a Kalman-tracked velocity
            for every tracker or none, None for each one's own; the manifold of every manifold
            tracker, None for each one's own; the ground plane's prior on every tracker's
            likelihood or not).
    """
    from .experiment import ExperimentConfig, results_table, run_experiment, write_outputs
    from .tracking import PAPER_TRACKERS

    say = print if verbose else (lambda *a, **k: None)
    start = time.perf_counter()
    key = jax.random.key(seed)
    say(f"[1/4] synthetic walk and jog of subjects S1 and S2 at 60 Hz: 4 training and 2 validation sequences, "
        f"2 test scenes of {frames} frames in 4 noisy 80x60 silhouette views")
    train, validation, test, names = demo_sequences(key, test_frames=frames, progress=verbose)
    os.makedirs(out_dir, exist_ok=True)
    for seq, name in zip(test, names["test"]):
        path = os.path.join(out_dir, name.replace(" ", "_") + ".npz")
        save_sequence(path, seq)
    test = [load_sequence(os.path.join(out_dir, n.replace(" ", "_") + ".npz")) for n in names["test"]]
    config = ExperimentConfig(methods=tuple(methods or PAPER_TRACKERS), budget=budget, runs=runs, fit_steps=100, seed=seed,
                              velocity=velocity, manifold=manifold, ground_prior=ground_prior)
    fitted = " and ".join(f"{k.upper()} ({q}-D)" for k, q in config.manifold_specs) or "no manifold"
    say(f"[2/4] fitting {fitted} and each tracker's dynamics; then {', '.join(config.methods)} with "
        f"{budget} likelihood evaluations per frame{' (silhouettes times the ground plane prior)' if ground_prior else ''}, "
        f"{runs} runs each")
    results = run_experiment(train, validation, test, config, names=names, progress=verbose)
    say("[3/4] joint error (000 eq. 31), mm, mean (std) over runs:\n")
    say(results_table(results))
    paths = write_outputs(results, test, names["test"], out_dir)
    sheet = contact_sheet(test[0], os.path.join(out_dir, "contact_sheet.png"))
    paths["contact_sheet"] = sheet
    say(f"[4/4] wrote {paths['results']}, {paths['table']}, {paths['curves']}, {sheet} and the overlay animations "
        f"in {time.perf_counter() - start:.0f} s")
    return results, paths
