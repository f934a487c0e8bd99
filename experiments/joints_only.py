"""Motion capture as joints-only files (15 HumanEva joints per frame, metres, 60 Hz, no pose and
no skeleton: what HumanEva hands out), converted back and tracked (docs/motion_files.md).

``convert``: every jog and run of the shared data (HDM05's five actors' jogs on a left circle,
CMU 09's run) written as joints-only files, whole and cut to 49 frames from several frames
(mid-stride starts), as captured and with marker-like noise; each converted by
``io.convert_motion`` and its residual read per frame (forward kinematics of the fitted pose on
the fitted skeleton against the file's joints, so any version of the library can be measured).

``track``: walks and jogs as joints-only training, validation and test files (each levelled onto
the floor under its stance foot where that tilts, as ``jaxtrack convert --level-floor``), the test take
rendered by a body that is not the tracker's (``data.SolidBody``) into 3 noisy 80x60 views of
the default rig; ``experiment.run_experiment`` with the library's defaults; per take and tracker
the joint error and frame 0's.

``floor``: the same rows' floors before any tracking: the nearest training pose
(``experiment.nearest_pose_floor_mm``) and the likelihood's own optimum near the truth (L-BFGS
from the true pose on the tracker's likelihood and body, every 10th frame).

    taskset -c 0,1 python experiments/joints_only.py convert --data ../shared/data --json convert.json
    taskset -c 0,1 python experiments/joints_only.py track --data ../shared/data --work /tmp/joints_only --json track.json
    taskset -c 0,1 python experiments/joints_only.py floor --data ../shared/data --json floor.json
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import time
import types

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.body import HUMANEVA_JOINTS, HUMANEVA_PARENTS, forward_kinematics, humaneva_skeleton, retarget_positions, with_offsets
from jaxtrack.io import Sequence, convert_motion, fit_floor, level_joints, load_motion, resample

FPS = 60.0
SHORT = 49  # frames of a short take (the training jog)


def joints_of(path: str, asf: str, source_fps: float = 120.0, *, level: bool = False) -> np.ndarray:
    """A take's 15 HumanEva joints at 60 Hz, straight from the motion capture (the presets'
    mapping), never through this library's skeleton; with ``level``, levelled onto the floor
    under the stance foot where it tilts (``io.fit_floor``: CMU 07's capture rises 1.1 degrees)."""
    motion = load_motion(path, asf=asf, source_fps=source_fps)
    joints = resample(retarget_positions(motion.positions, motion.joint_names), motion.fps, FPS)
    floor = fit_floor(joints)
    return level_joints(joints, floor) if level and floor.worth_levelling else joints


def marker_noise(joints: np.ndarray, sd_m: float, seed: int) -> np.ndarray:
    """Joints moved by smooth noise of ``sd_m`` per axis (a 10-frame moving sum of white noise,
    renormalised): a joint centre placed from markers on the skin, which slide by centimetres."""
    if sd_m <= 0:
        return joints
    rng = np.random.default_rng(seed)
    T = joints.shape[0]
    white = rng.normal(size=(T + 9,) + joints.shape[1:])
    smooth = np.stack([white[i:i + T] for i in range(10)]).sum(0) / np.sqrt(10.0)
    return joints + sd_m * smooth


def joints_only_sequence(joints: np.ndarray, subject: str) -> Sequence:
    """A sequence with only ``fps``, ``joints3d``, the joints' names and parents, and ``subject``."""
    return Sequence.create(fps=FPS, joints3d=np.asarray(joints, np.float64), joint_names=np.array(HUMANEVA_JOINTS),
                           parents=np.array(HUMANEVA_PARENTS), subject=subject)


def per_frame_residual_mm(sequence: Sequence, joints: np.ndarray) -> np.ndarray:
    """(T,) mean distance over the joints between the converted pose on its skeleton and the joints."""
    skeleton = with_offsets(humaneva_skeleton(dtype=jnp.float64), np.asarray(sequence.skeleton_offsets, np.float64))
    with jax.enable_x64(True):
        fitted = np.asarray(forward_kinematics(skeleton, jnp.asarray(sequence.pose, jnp.float64)))
    return 1000.0 * np.linalg.norm(fitted - joints, axis=-1).mean(axis=1)


def shared_runs(data: str) -> list[tuple[str, str, str]]:
    """(name, motion file, skeleton) of every jog and run in the shared data (the jogs run on a circle)."""
    takes = []
    for folder in sorted(glob.glob(os.path.join(data, "multi_subject", "hdm05_*"))):
        asf = glob.glob(os.path.join(folder, "*.asf"))[0]
        amcs = sorted(glob.glob(os.path.join(folder, "*jogLeftCircle*.amc")))
        takes.extend((f"HDM05 {os.path.basename(folder)[-2:]} jog {amc.split('Rstart_')[1][:3]}", amc, asf) for amc in amcs)
    takes.append(("CMU 09 run", os.path.join(data, "multi_subject", "cmu_09", "09_06-run.amc"),
                  os.path.join(data, "multi_subject", "cmu_09", "09-run.asf")))
    return takes


def off_the_floor(per_frame: np.ndarray, floor_mm: float) -> bool:
    """A cut some of whose frames (or all) sit far above the take's floor: its median frame over
    every cut (2.5 times it and 5 mm more)."""
    return bool(np.max(per_frame) > 2.5 * floor_mm + 5.0)


def convert_table(args) -> list[dict]:
    """Per take and noise level: the whole take and every cut of ``SHORT`` frames starting every
    ``args.every`` frames (the last ones shorter, down to 20 frames), each converted."""
    rows = []
    for name, path, asf in shared_runs(args.data):
        joints = joints_of(path, asf)
        for noise_mm in args.noise_mm:
            noisy = marker_noise(joints, noise_mm / 1000.0, seed=len(rows))
            cuts = [(0, noisy.shape[0])] + [(s, SHORT) for s in range(0, noisy.shape[0] - 20, args.every)]
            windows = []
            for start, frames in cuts:
                cut = noisy[start:start + frames]
                started = time.perf_counter()
                report = convert_motion(joints_only_sequence_motion(cut), None)
                seconds = time.perf_counter() - started
                per_frame = per_frame_residual_mm(report.sequence, cut)
                windows.append({"start": start, "frames": int(cut.shape[0]), "seconds": seconds,
                                "per_frame_mm": np.round(per_frame, 2).tolist(),
                                "pattern": getattr(getattr(report, "residual", None), "pattern", None)})
            whole, short = windows[0], windows[1:]
            floor = float(np.median(np.concatenate([w["per_frame_mm"] for w in short])))
            for window in windows:
                window["off_the_floor"] = off_the_floor(window["per_frame_mm"], floor)
            worst = max(max(w["per_frame_mm"]) for w in short)
            row = {"take": name, "frames": int(noisy.shape[0]), "noise_mm": noise_mm, "whole": whole, "cuts": short,
                   "cuts_off_the_floor": sum(w["off_the_floor"] for w in short), "worst_frame_mm": worst,
                   "median_frame_mm": floor}
            rows.append(row)
            print(f"{name:22s} noise {noise_mm:2.0f} mm: whole take ({whole['frames']} frames) {np.median(whole['per_frame_mm']):4.1f} / "
                  f"{max(whole['per_frame_mm']):5.1f} mm (median / worst frame); {len(short)} cuts of <= {SHORT} frames: "
                  f"median frame {row['median_frame_mm']:4.1f} mm, worst frame {worst:6.1f} mm, "
                  f"{row['cuts_off_the_floor']} off the floor", flush=True)
    return rows


def joints_only_sequence_motion(joints: np.ndarray):
    """The joints as the ``io.MotionCapture`` that ``load_joints3d`` makes of a joints-only file."""
    from jaxtrack.io import MotionCapture

    return MotionCapture(tuple(HUMANEVA_JOINTS), tuple(HUMANEVA_PARENTS), np.asarray(joints, np.float64), FPS, (),
                         np.zeros((joints.shape[0], 0)), "joints-only")


# --- tracking ------------------------------------------------------------------------------

def _hdm(data, actor, number):
    folder = os.path.join(data, "multi_subject", f"hdm05_{actor}")
    return glob.glob(os.path.join(folder, f"*jogLeftCircle*_{number:03d}_120.amc"))[0], os.path.join(folder, f"HDM_{actor}.asf")


def _cmu(data, folder, stem, asf):
    return os.path.join(data, "multi_subject", folder, f"{stem}.amc"), os.path.join(data, "multi_subject", folder, asf)


def tracking_rows(data: str) -> dict:
    """Per row: (subject, training takes, validation takes, test take, training frames kept: None
    for the first 240, or (first, count)): each take a (motion file, skeleton) pair. The bk row
    with 46 training frames trains on the cut that the inverse kinematics failed on before
    (``convert``: 25-176 mm on every frame)."""
    return {
        "CMU 07 walk": ("cmu07", [_cmu(data, "cmu_07", s, "07-walk.asf") for s in ("07_02-walk", "07_06-walk")],
                        [_cmu(data, "cmu_07", "07_07-walk", "07-walk.asf")], _cmu(data, "cmu_07", "07_01-walk", "07-walk.asf"), None),
        "CMU 16 walk": ("cmu16", [_cmu(data, "cmu_16", "16_25", "16.asf")], [_cmu(data, "cmu_16", "16_25", "16.asf")],
                        _cmu(data, "cmu_16", "16_24", "16.asf"), None),
        "HDM05 bk jog": ("bk", [_hdm(data, "bk", n) for n in (4, 5)], [_hdm(data, "bk", 6)], _hdm(data, "bk", 3), None),
        "HDM05 bk jog, 46 training frames": ("bk", [_hdm(data, "bk", 5)], [_hdm(data, "bk", 6)], _hdm(data, "bk", 3), (91, SHORT)),
        "HDM05 tr jog, 49 training frames": ("tr", [_hdm(data, "tr", 15)], [_hdm(data, "tr", 17)], _hdm(data, "tr", 14), (30, SHORT)),
        "HDM05 dg jog": ("dg", [_hdm(data, "dg", 9)], [_hdm(data, "dg", 10)], _hdm(data, "dg", 8), None),
    }


def row_takes(args, index: int, spec) -> tuple[list, list, Sequence, Sequence]:
    """One row's joints-only training and validation sequences, its joints-only test scene (the
    solid body's 3 noisy 80x60 views) and the test take converted with its pose (to render it,
    and for the floors)."""
    subject, train, validation, test, keep = spec
    train_seqs = []
    for path, asf in train:
        joints = joints_of(path, asf, level=True)
        first, count = keep or (0, 240)  # a short take starts mid-stride
        train_seqs.append(joints_only_sequence(joints[first:first + count], subject))
    validation_seqs = [joints_only_sequence(joints_of(path, asf, level=True), subject) for path, asf in validation]
    # The test take: converted to render it (the solid body on its skeleton), then stripped
    # to its joints, cameras and silhouettes.
    path, asf = test
    converted = convert_motion(path, None, asf=asf, source_fps=120.0, fps=FPS, level_floor=True).sequence.replace(subject=subject)
    from jaxtrack.experiment import render_test_take

    scene = render_test_take(jax.random.fold_in(jax.random.key(0), index), converted, views=3, size=(80, 60),
                             frames=args.frames, renderer="solid")
    return train_seqs, validation_seqs, scene.replace(pose=None, pose_layout=None, skeleton_offsets=None), converted


def _names(subject: str, row: str, train_seqs: list, validation_seqs: list) -> dict:
    return {"train": [f"{subject}-train{i}" for i in range(len(train_seqs))],
            "validation": [f"{subject}-validation{i}" for i in range(len(validation_seqs))], "test": [row]}


def _selected_rows(args):
    for index, (row, spec) in enumerate(tracking_rows(args.data).items()):
        if not args.rows or row in args.rows:
            yield index, row, spec


def track_table(args) -> list[dict]:
    from jaxtrack.experiment import ExperimentConfig, run_experiment

    os.makedirs(args.work, exist_ok=True)
    out = []
    for index, row, spec in _selected_rows(args):
        train_seqs, validation_seqs, test_seq, _ = row_takes(args, index, spec)
        config = ExperimentConfig(runs=args.runs, budget=args.budget, seed=0)
        started = time.perf_counter()
        results = run_experiment(train_seqs, validation_seqs, [test_seq], config, names=_names(spec[0], row, train_seqs, validation_seqs),
                                 out_dir=os.path.join(args.work, row.replace(" ", "_").replace(",", "")), progress=False,
                                 animations=False)
        per_method = results["sequences"][row]
        record = {"row": row, "seconds": time.perf_counter() - started, "train_frames": [s.num_frames for s in train_seqs],
                  "ik_residual_mm": results["ik_residual_mm"], "warnings": results.get("warnings", []),
                  "methods": {m: {"error_mm": r["error_mm_mean"], "error_sd_mm": r["error_mm_std"],
                                  "frame0_error_mm": r["frame0_error_mm"]} for m, r in per_method.items()}}
        out.append(record)
        cells = "  ".join(f"{m} {r['error_mm']:.0f} (f0 {r['frame0_error_mm']:.0f})" for m, r in record["methods"].items())
        print(f"{row}: {cells}  [{record['seconds']:.0f} s]", flush=True)
    return out


# --- floors --------------------------------------------------------------------------------

def likelihood_optimum_mm(scene, frames, *, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """How far the likelihood's own best pose lies from the truth: each frame's pose climbed by
    L-BFGS (``optax.lbfgs``, its zoom line search) on the tracker's log-likelihood (silhouettes and
    ground prior, the tracker's fitted body) from the truth on that body. Returns per frame and
    joint its error (mm) against the truth's joints, (frames, J), and per frame the log-likelihood
    gained. A tracker
    that follows this likelihood settles about as far from the truth as its optimum."""
    import optax

    likelihood, skeleton = scene.likelihood, scene.body.skeleton
    optimiser = optax.lbfgs()

    @jax.jit
    def climb(pose, observation):
        def loss(p):
            return -likelihood.log_likelihood(p[None], observation)[0]

        value_and_grad = optax.value_and_grad_from_state(loss)

        def step(carry, _):
            p, state = carry
            value, grad = value_and_grad(p, state=state)
            updates, state = optimiser.update(grad, state, p, value=value, grad=grad, value_fn=loss)
            return (optax.apply_updates(p, updates), state), value

        (best, _), _ = jax.lax.scan(step, (pose, optimiser.init(pose)), None, length=steps)
        return best, loss(pose) - loss(best)

    errors, gains = [], []
    for frame in frames:
        observation = jax.tree.map(lambda x, f=frame: x[f], scene.observations)
        best, gain = climb(jnp.asarray(scene.truth_poses[frame], jnp.float32), observation)
        joints = np.asarray(forward_kinematics(skeleton, best[None]))[0]
        errors.append(1000.0 * np.linalg.norm(joints - scene.truth_joints[frame], axis=-1))
        gains.append(float(gain))
    return np.asarray(errors), np.asarray(gains)


def floor_table(args) -> list[dict]:
    """Per row, the floors under the tracking table: the nearest training pose
    (``experiment.nearest_pose_floor_mm``: the training motion as the manifolds see it, converted
    from the joints-only files) and the likelihood's own optimum near the truth (frame 0 and every
    ``args.floor_every``-th frame)."""
    from jaxtrack.experiment import ExperimentConfig, nearest_pose_floor_mm, new_results, prepare_inputs

    out = []
    for index, row, spec in _selected_rows(args):
        train_seqs, validation_seqs, test_seq, converted = row_takes(args, index, spec)
        config = ExperimentConfig(runs=1, budget=args.budget, seed=0)
        inputs = prepare_inputs(train_seqs, validation_seqs, [test_seq], config, new_results(config),
                                names=_names(spec[0], row, train_seqs, validation_seqs), say=lambda *a, **k: None)
        scene = inputs.scenes[0]
        train_motion = [types.SimpleNamespace(pose=np.asarray(p, np.float64)) for p in inputs.train_poses]  # what the floor reads
        test_motion = converted.cropped(min(args.frames, converted.num_frames)) if args.frames else converted
        nearest = nearest_pose_floor_mm(train_motion, test_motion)
        frames = list(range(0, scene.num_frames, args.floor_every))
        per_joint, gain = likelihood_optimum_mm(scene, frames, steps=args.floor_steps)
        optimum = per_joint.mean(axis=1)
        record = {"row": row, "nearest_training_pose_mm": nearest, "start_error_mm": scene.start_error_mm,
                  "likelihood_optimum_mm": {"frames": frames, "per_frame": np.round(optimum, 2).tolist(),
                                            "frame0": float(optimum[0]), "mean": float(optimum.mean()),
                                            "log_likelihood_gained": np.round(gain, 2).tolist(),
                                            "per_joint_mean": dict(zip(HUMANEVA_JOINTS, np.round(per_joint.mean(0), 1).tolist()))}}
        out.append(record)
        print(f"{row}: nearest training pose {nearest:5.1f} mm; the likelihood's optimum from the truth: frame 0 "
              f"{optimum[0]:5.1f} mm, mean over {len(frames)} frames {optimum.mean():5.1f} mm, log-likelihood gained "
              f"{np.median(gain):.1f} (median) (start {scene.start_error_mm:.1f} mm); per joint "
              + " ".join(f"{n} {e:.0f}" for n, e in zip(HUMANEVA_JOINTS, per_joint.mean(0))),
              flush=True)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("command", choices=("convert", "track", "floor"))
    parser.add_argument("--data", default="../shared/data", help="the shared motion-capture folder")
    parser.add_argument("--noise-mm", type=float, nargs="+", default=[0.0, 8.0], help="marker-like noise per axis (convert)")
    parser.add_argument("--every", type=int, default=7, help="frames between the starts of the short cuts (convert)")
    parser.add_argument("--work", default="/tmp/joints_only", help="experiment outputs (track)")
    parser.add_argument("--rows", nargs="*", help="only these rows (track)")
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--budget", type=int, default=500)
    parser.add_argument("--frames", type=int, default=150, help="test frames tracked")
    parser.add_argument("--floor-every", type=int, default=10, help="frames between the likelihood's optima (floor)")
    parser.add_argument("--floor-steps", type=int, default=100, help="L-BFGS steps per frame (floor)")
    parser.add_argument("--json", help="write the rows here")
    args = parser.parse_args()
    rows = {"convert": convert_table, "track": track_table, "floor": floor_table}[args.command](args)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(rows, handle, indent=1)


if __name__ == "__main__":
    main()
