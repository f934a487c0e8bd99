"""People the manifold has never seen: leave-one-subject-out protocols (paper 002 sec. 3's
cross-subject experiment) as experiment inputs, with their within-subject counterparts.

A ``SubjectProtocol`` names, per subject, a test take, training takes and (optionally) a
validation take, as files of the shared motion capture (``../shared/data``: ASF/AMC at 120 Hz,
and CMU subject 35's trials as GPmat stores them at 30 Hz). Its folds:

- ``cross``, subject s left out: the manifold is trained on every other subject's training
  takes, the dynamics fitted on their validation takes, and s's test take is tracked;
- ``within``, subject s: trained on s's own training takes, validated on s's validation take
  (its first training take when it has none), tested on the same test take.

So the two rows of one subject differ only in whose motion the trackers learnt from: their ratio
is the cost of crossing people. The takes are converted once by the library's loaders
(``io.convert_motion``: inverse kinematics onto the HumanEva skeleton, resampled to 60 Hz) and
each test take is rendered into noisy multi-view silhouettes by a body that is not the tracker's
(``data.SolidBody``: ellipsoids with feet and hands, or the subject's capsules with other radii),
the file keeping only the joints, the skeleton and the cameras.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from collections.abc import Sequence

import jax
import numpy as np

from ..errors import ConfigurationError
from ._config import ExperimentConfig

FOLD_MODES = ("cross", "within")
RENDERERS = ("solid", "capsules")
DEFAULT_AZIMUTH = 45.0  # degrees: the default rig's first camera (camera.default_rig)
# what a row written before the setting existed ran with
SETTING_DEFAULTS = {"azimuth": DEFAULT_AZIMUTH, "centre_subjects": False, "start": "truth", "level_floor": False}
OTHER_RADII = {"torso": 1.2, "legs": 0.85, "arms": 1.1, "head": 1.0}
"""The capsule renderer's radii, as factors of the subject's default radii per capsule group
(the real-motion tables' mismatched body, benchmarks/real_motion.py)."""


@dataclasses.dataclass(frozen=True)
class Take:
    """One recorded take of one subject.

    Attributes:
        subject: who performs it (the sequence file's ``subject`` key).
        name: the take's name (the converted file's stem), unique within a protocol.
        source: the motion file, relative to the data folder (``.amc``, ``.bvh``; or GPmat's
            ``cmu35WalkJog.mat``, the trial being ``name``).
        fps: the source's frame rate (AMC files do not store it).
        asf: the ASF skeleton of an AMC or GPmat source, relative to the data folder.
    """

    subject: str
    name: str
    source: str
    fps: float
    asf: str | None = None


@dataclasses.dataclass(frozen=True)
class ProtocolSubject:
    """One subject's roles: its test take, its training takes and its validation take."""

    name: str
    test: Take
    train: tuple[Take, ...]
    validation: Take | None = None


@dataclasses.dataclass(frozen=True)
class Fold:
    """One experiment of a protocol: whose takes train, validate and test.

    Attributes:
        mode: ``"cross"`` (the test subject left out of training) or ``"within"`` (trained on
            the test subject's own other takes).
        subject: the test subject.
        note: what departs from the protocol's rule (a validation take reused from training).
    """

    protocol: str
    mode: str
    subject: str
    train: tuple[Take, ...]
    validation: tuple[Take, ...]
    test: Take
    note: str = ""

    @property
    def label(self) -> str:
        return f"{self.mode}-{self.subject}"

    @property
    def names(self) -> dict[str, list[str]]:
        """The takes' names by role, as ``run_experiment``'s ``names`` takes them."""
        return {"train": [t.name for t in self.train], "validation": [t.name for t in self.validation], "test": [self.test.name]}


@dataclasses.dataclass(frozen=True)
class SubjectProtocol:
    """A leave-one-subject-out protocol (module docstring).

    Attributes:
        name: the protocol's name (``jaxtrack protocol NAME``).
        description: one line for the help and the table.
        subjects: at least two.
        test_frames: frames tracked of each test take (60 Hz; None: all).
        train_frames: first frames of each training take kept (None: all).
    """

    name: str
    description: str
    subjects: tuple[ProtocolSubject, ...]
    test_frames: int | None = 150
    train_frames: int | None = 240

    def __post_init__(self):
        names = [s.name for s in self.subjects]
        if len(names) < 2 or len(set(names)) != len(names):
            raise ConfigurationError(f"protocol {self.name!r}: needs two or more distinct subjects, got {names}")
        seen = {}
        for s in self.subjects:
            for take in (s.test, *s.train, *([s.validation] if s.validation else [])):
                if seen.setdefault(take.name, take) != take:
                    raise ConfigurationError(f"protocol {self.name!r}: a take name is used twice for different takes: {take.name}")

    def takes(self) -> list[Take]:
        """Every take the protocol reads, each once."""
        out = {}
        for s in self.subjects:
            for take in (s.test, *s.train, *([s.validation] if s.validation else [])):
                out.setdefault(take.name, take)
        return list(out.values())

    def subject(self, name: str) -> ProtocolSubject:
        for s in self.subjects:
            if s.name == name:
                return s
        raise ConfigurationError(f"protocol {self.name!r} has no subject {name!r}; its subjects: "
                                 f"{', '.join(s.name for s in self.subjects)}")

    def fold(self, mode: str, subject: str) -> Fold:
        """The ``mode`` fold whose test subject is ``subject``."""
        test = self.subject(subject)
        if mode == "cross":
            others = [s for s in self.subjects if s.name != subject]
            validation = tuple(s.validation for s in others if s.validation is not None)
            note = ""
            if not validation:
                validation, note = tuple(s.train[0] for s in others), "validation: the training subjects' first training takes"
            return Fold(self.name, mode, subject, tuple(t for s in others for t in s.train), validation, test.test, note)
        if mode == "within":
            if test.validation is not None:
                return Fold(self.name, mode, subject, test.train, (test.validation,), test.test)
            return Fold(self.name, mode, subject, test.train, test.train[:1], test.test,
                        f"validation: the training take {test.train[0].name} ({subject} has no third take)")
        raise ConfigurationError(f"fold mode must be one of {FOLD_MODES}, got {mode!r}")

    def without(self, *subjects: str) -> SubjectProtocol:
        """The protocol on the other subjects only: its cross folds are the nested validation of
        a setting for ``subjects`` (chosen there, the setting never saw their motion)."""
        for name in subjects:
            self.subject(name)
        kept = tuple(s for s in self.subjects if s.name not in subjects)
        if len(kept) < 2:
            raise ConfigurationError(f"protocol {self.name!r} without {', '.join(subjects)} keeps {len(kept)} subject; "
                                     "a protocol needs two or more")
        return dataclasses.replace(self, name=f"{self.name}-without-{'-'.join(subjects)}", subjects=kept)

    def folds(self, modes=FOLD_MODES, subjects=None) -> list[Fold]:
        """Every requested fold: subject by subject, each mode in turn."""
        chosen = [s.name for s in self.subjects] if subjects is None else list(subjects)
        return [self.fold(mode, s) for s in chosen for mode in modes]


def _cmu(subject: str, folder: str, asf: str, test: str, train: tuple[str, ...], validation: str | None) -> ProtocolSubject:
    def take(name):
        return Take(subject, name, f"multi_subject/{folder}/{name}.amc", 120.0, f"multi_subject/{folder}/{asf}")

    return ProtocolSubject(subject, take(test), tuple(map(take, train)), take(validation) if validation else None)


def _cmu35_walks() -> ProtocolSubject:
    def gpmat(name):
        return Take("cmu35", name, "cmu35/cmu35WalkJog.mat", 30.0, "cmu35/35.asf")

    test = Take("cmu35", "35_01", "cmu35/35_01.amc", 120.0, "cmu35/35.asf")  # the one raw 120 Hz take
    return ProtocolSubject("cmu35", test, (gpmat("35_02"), gpmat("35_03")), gpmat("35_04"))


def _hdm05(actor: str, test: int, train: tuple[int, ...], validation: int | None) -> ProtocolSubject:
    def take(number):
        stem = f"HDM_{actor}_jogLeftCircle4StepsRstart_{number:03d}_120"
        return Take(f"hdm05-{actor}", stem, f"multi_subject/hdm05_{actor}/{stem}.amc", 120.0,
                    f"multi_subject/hdm05_{actor}/HDM_{actor}.asf")

    return ProtocolSubject(f"hdm05-{actor}", take(test), tuple(map(take, train)), take(validation) if validation else None)


PROTOCOLS = {
    "walk-loso": SubjectProtocol(
        "walk-loso", "walking, CMU subjects 07, 16 and 35, each left out in turn",
        (_cmu("cmu07", "cmu_07", "07-walk.asf", "07_01-walk", ("07_02-walk", "07_06-walk"), "07_07-walk"),
         _cmu("cmu16", "cmu_16", "16.asf", "16_24", ("16_25",), None),
         _cmu35_walks()),
        test_frames=150),
    "jog-loso": SubjectProtocol(
        "jog-loso", "jogging on a left circle, HDM05's five actors, each left out in turn",
        (_hdm05("bd", 1, (2,), None), _hdm05("bk", 3, (4, 5), 6), _hdm05("dg", 8, (9,), 10), _hdm05("mm", 11, (12,), 13),
         _hdm05("tr", 14, (15, 16), 17)),
        test_frames=150),
}
"""The built-in protocols on ``../shared/data`` (docs/subjects.md)."""


def get_protocol(name: str) -> SubjectProtocol:
    try:
        return PROTOCOLS[name]
    except KeyError:
        raise ConfigurationError(f"no protocol {name!r}; built in: {', '.join(PROTOCOLS)}") from None


def load_take_motion(take: Take, data_folder: str):
    """The take's ``io.MotionCapture``, read by the library's loaders."""
    from ..io import load_motion, read_gpmat_trials

    source = os.path.join(data_folder, take.source)
    asf = os.path.join(data_folder, take.asf) if take.asf else None
    if not os.path.exists(source):
        raise FileNotFoundError(f"{source}: missing (take {take.name} of {take.subject}; is --data the shared data folder?)")
    if source.endswith(".mat"):
        return read_gpmat_trials(source, asf, [take.name])[take.name]
    return load_motion(source, asf=asf, source_fps=take.fps)


def convert_takes(takes, data_folder: str, folder: str, *, fps: float = 60.0, seed: int = 0, level_floor: bool = False,
                  say=print) -> dict:
    """Convert every take once into ``folder/<name>.npz`` (``io.convert_motion`` at ``fps``,
    the sequence's ``subject`` set, each take levelled onto its floor with ``level_floor``);
    files already there are read, not converted again (keep levelled and unlevelled takes in
    separate folders).

    Returns:
        ``{take name: Sequence}``.
    """
    from ..io import convert_motion, load_sequence, save_sequence

    os.makedirs(folder, exist_ok=True)
    sequences = {}
    for take in takes:
        path = os.path.join(folder, f"{take.name}.npz")
        if not os.path.exists(path):
            report = convert_motion(load_take_motion(take, data_folder), None, fps=fps, seed=seed, level_floor=level_floor)
            save_sequence(path, report.sequence.replace(subject=take.subject))
            say(f"converted {take.subject} {take.name}: {report.num_frames} frames at {fps:g} Hz, inverse-kinematics residual "
                f"{report.mean_residual_mm:.1f} mm; {report.floor.describe()}{', levelled' if report.levelled else ''}")
        sequences[take.name] = load_sequence(path)
    return sequences


def render_test_take(key, sequence, *, views: int, size: tuple[int, int] = (80, 60), frames=None, renderer: str = "solid",
                     clean: bool = False, withhold: bool = True, azimuth: float | Sequence[float] = DEFAULT_AZIMUTH):
    """The test take in ``views`` noisy ``size`` (W, H) silhouette views of the default rig
    (its first camera at ``azimuth`` degrees, ``camera.default_rig``),
    drawn by a body that is not the tracker's: ``solid`` (``data.SolidBody`` on the subject's
    skeleton) or ``capsules`` (the subject's capsules with ``OTHER_RADII``).

    Args:
        clean: no background-subtraction noise (default: ``data.SilhouetteNoise()``).
        withhold: drop the radii from the file (the default), so the tracker dresses the
            skeleton in its default capsules; False keeps the rendered capsules' radii.
    """
    from ..camera import default_rig
    from ..data import NO_NOISE, SilhouetteNoise, SolidBody, scene_from_sequence

    if renderer not in RENDERERS:
        raise ConfigurationError(f"renderer must be one of {RENDERERS}, got {renderer!r}")
    body = sequence.body()
    frames = None if frames is None else min(int(frames), sequence.num_frames)
    rig = default_rig(*size, num_views=views, azimuth=azimuth)
    noise = NO_NOISE if clean else SilhouetteNoise()
    if renderer == "solid":
        scene = scene_from_sequence(key, sequence, rig, noise, frames=frames, solid=SolidBody(body.skeleton))
    else:
        radii = np.asarray(body.radii, np.float64) * np.array([OTHER_RADII[g] for g in body.capsule_groups])
        scene = scene_from_sequence(key, sequence.replace(capsule_radii=radii), rig, noise, frames=frames)
    return scene.replace(capsule_radii=None) if withhold else scene


def shift_joint_angles(sequence, offset):
    """The sequence with ``offset`` (A,) radians added to every frame's joint angles (its stored
    joints dropped: they would no longer match the pose)."""
    from ..body import GLOBAL_DOFS

    pose = np.asarray(sequence.pose, np.float64).copy()
    pose[:, GLOBAL_DOFS:] += np.asarray(offset, np.float64)
    return sequence.replace(pose=pose, joints3d=None)


def centre_subjects(fold: Fold, train: list, validation: list) -> tuple[list, list]:
    """Each training subject's posture taken out: every training and validation take of subject
    s shifted by ``P - M_s``, ``M_s`` the mean joint angles of s's training takes and ``P`` those
    of all the training takes pooled, so the manifold learns one posture and the gait, not the
    people (issue #46's "poses normalised per subject"; docs/subjects.md, "A person's own
    posture"). One training subject (a within fold): nothing moves.

    Args:
        fold: whose takes ``train`` and ``validation`` are (in ``fold.train`` / ``fold.validation`` order).
        train, validation: the fold's sequences (the training takes cropped as the protocol keeps them).
    """
    from ..body import GLOBAL_DOFS

    def angles(sequence):
        return np.asarray(sequence.pose, np.float64)[:, GLOBAL_DOFS:]

    subjects = dict.fromkeys(t.subject for t in fold.train)
    means = {s: np.concatenate([angles(x) for t, x in zip(fold.train, train) if t.subject == s]).mean(0) for s in subjects}
    pooled = np.concatenate([angles(x) for x in train]).mean(0)

    def centred(take, sequence):
        return shift_joint_angles(sequence, pooled - means[take.subject]) if take.subject in means else sequence

    return ([centred(t, x) for t, x in zip(fold.train, train)], [centred(t, x) for t, x in zip(fold.validation, validation)])


def _cropped(sequence, frames: int | None):
    return sequence.cropped(min(frames, sequence.num_frames)) if frames else sequence


def fold_takes(protocol: SubjectProtocol, fold: Fold, sequences: dict, *, centre: bool = False) -> tuple[list, list]:
    """A fold's training takes (their first ``protocol.train_frames`` frames) and validation takes
    (whole), as ``run_protocol`` trains on them; with ``centre``, each training subject's posture
    taken out (``centre_subjects``).

    Args:
        sequences: take name -> converted ``Sequence`` (``convert_takes``).
    """
    train = [_cropped(sequences[t.name], protocol.train_frames) for t in fold.train]
    validation = [sequences[t.name] for t in fold.validation]
    return centre_subjects(fold, train, validation) if centre else (train, validation)


def fold_test_scene(protocol: SubjectProtocol, fold: Fold, sequences: dict, *, seed: int = 0, views: int = 3,
                    size: tuple[int, int] = (80, 60), renderer: str = "solid", azimuth: float | Sequence[float] = DEFAULT_AZIMUTH):
    """A fold's test take rendered as ``run_protocol`` renders it (``render_test_take``, its first
    ``protocol.test_frames`` frames): the key is ``fold_in(key(seed), i)``, ``i`` the test take's
    index among ``protocol.takes()``, so a subject's cross and within folds track the same
    silhouettes.

    Args:
        sequences: take name -> converted ``Sequence`` (``convert_takes``).
    """
    index = [t.name for t in protocol.takes()].index(fold.test.name)
    key = jax.random.fold_in(jax.random.key(seed), index)
    return render_test_take(key, sequences[fold.test.name], views=views, size=size, frames=protocol.test_frames,
                            renderer=renderer, azimuth=azimuth)


def drift_ratio(curve) -> float:
    """Mean error of the last quarter of the frames over that of the first quarter."""
    curve = np.asarray(curve, np.float64)
    quarter = max(1, len(curve) // 4)
    return float(np.mean(curve[-quarter:]) / np.mean(curve[:quarter]))


def nearest_pose_floor_mm(train, test) -> float:
    """How close the training motion comes to the test take, before any tracking: each test
    frame's joint angles replaced by the nearest training frame's (Euclidean, radians), on the
    test subject's skeleton with its own root, against its own pose (mm, mean over joints and
    frames): about what a tracker confined to the training poses would score with a perfect
    root (not a strict bound: "nearest" is in joint angles, not in millimetres).

    Args:
        train: sequences with ``pose``; test: a sequence with ``pose`` and its body.
    """
    import jax.numpy as jnp

    from ..body import GLOBAL_DOFS, forward_kinematics, joint_angles

    candidates = np.concatenate([np.asarray(joint_angles(np.asarray(s.pose, np.float64))) for s in train])
    pose = np.asarray(test.pose, np.float64)
    angles = joint_angles(pose)
    nearest = np.empty_like(angles)
    for start in range(0, len(angles), 64):  # (64, N) distances at a time
        block = angles[start:start + 64]
        d = (block ** 2).sum(-1)[:, None] - 2.0 * block @ candidates.T + (candidates ** 2).sum(-1)[None]
        nearest[start:start + 64] = candidates[np.argmin(d, axis=1)]
    skeleton = test.body().skeleton
    truth = forward_kinematics(skeleton, jnp.asarray(pose))
    closest = forward_kinematics(skeleton, jnp.asarray(np.concatenate([pose[:, :GLOBAL_DOFS], nearest], axis=1)))
    return float(1000.0 * jnp.linalg.norm(closest - truth, axis=-1).mean())


def _fold_row(fold: Fold, results: dict, config: ExperimentConfig, seconds: float, settings: dict) -> dict:
    per_method = results["sequences"].get(fold.test.name, {})
    methods = {}
    for m, r in per_method.items():
        methods[m] = {"error_mm_mean": r["error_mm_mean"], "error_mm_std": r["error_mm_std"], "error_mm_per_run": r["error_mm_per_run"],
                      "frame0_error_mm": r["frame0_error_mm"], "last_over_first_quarter": drift_ratio(r["per_frame_error_mm"]),
                      "per_frame_error_mm": r["per_frame_error_mm"], "frames_per_second": r["frames_per_second"]}
    return {"protocol": fold.protocol, "mode": fold.mode, "subject": fold.subject, "test": fold.test.name,
            "train": [t.name for t in fold.train], "validation": [t.name for t in fold.validation], "note": fold.note,
            "seconds": seconds, "budget": config.budget, "runs": config.runs, **settings, "methods": methods,
            "refused": dict(results.get("refused", {})),
            "start_error_mm": next(iter(per_method.values()), {}).get("start_error_mm"),
            "start_found_on": (results.get("start") or {}).get("manifold")}


def run_protocol(protocol: SubjectProtocol, data_folder: str, out_dir: str, config: ExperimentConfig, *, modes=FOLD_MODES,
                 subjects=None, views: int = 3, size: tuple[int, int] = (80, 60), renderer: str = "solid",
                 azimuth: float | Sequence[float] = DEFAULT_AZIMUTH, centre: bool = False, level_floor: bool = True,
                 progress: bool = False, say=print) -> list[dict]:
    """Run the protocol's folds end to end and write ``out_dir/protocol.json`` and
    ``out_dir/table.md`` after each fold (each fold's own experiment outputs in
    ``out_dir/<mode>-<subject>/``). A fold already in ``protocol.json`` with the same settings is
    not run again, so an interrupted protocol resumes.

    Args:
        config: the experiment's settings (trackers, budget, runs, seed, ...); its ``frames``
            is replaced by the protocol's ``test_frames``.
        modes, subjects: which folds (default: every subject, cross and within).
        views, size, renderer, azimuth: the test scenes (``render_test_take``; ``azimuth``: the
            first camera's direction in degrees, or one per camera).
        centre: take each training subject's posture out of its takes (``centre_subjects``);
            the nearest training pose is then measured on the centred takes.
        level_floor: level every take onto the floor under its stance foot when converting it
            (``io.fit_floor``; the takes in ``out_dir/converted-levelled``, otherwise in
            ``out_dir/converted``): the trackers' floor is level, CMU subject 07's is not
            (docs/floor.md, "A tilted capture").

    Returns:
        one row per fold (``protocol_table`` draws them).
    """
    from ..camera import default_rig
    from ..io import check_folder
    from ._run import run_experiment

    for mode in modes:
        if mode not in FOLD_MODES:
            raise ConfigurationError(f"fold mode must be one of {FOLD_MODES}, got {mode!r}")
    azimuth = [float(a) for a in azimuth] if np.ndim(azimuth) else float(azimuth)
    try:
        default_rig(*size, num_views=views, azimuth=azimuth)  # refused before any conversion
    except ValueError as error:
        raise ConfigurationError(str(error)) from None
    folds = protocol.folds(modes, subjects)  # unknown subjects refused before any conversion
    check_folder(out_dir)
    sequences = convert_takes(protocol.takes(), data_folder, os.path.join(out_dir, "converted-levelled" if level_floor else "converted"),
                              seed=config.seed, level_floor=level_floor, say=say)
    settings = {"views": views, "size": list(size), "renderer": renderer, "azimuth": azimuth,
                "seed": config.seed, "test_frames": protocol.test_frames,
                "train_frames": protocol.train_frames, "methods_requested": list(config.methods), "centre_subjects": bool(centre),
                "start": config.start, "level_floor": bool(level_floor)}
    json_path = os.path.join(out_dir, "protocol.json")
    rows = []
    if os.path.exists(json_path):
        with open(json_path, encoding="utf-8") as handle:
            rows = [r for r in json.load(handle).get("rows", [])
                    if all(r.get(k, SETTING_DEFAULTS.get(k)) == v for k, v in settings.items())]
    config = dataclasses.replace(config, frames=None)
    for fold in folds:
        train, validation = fold_takes(protocol, fold, sequences, centre=centre)
        floor = nearest_pose_floor_mm(train, _cropped(sequences[fold.test.name], protocol.test_frames))
        done = [r for r in rows if r["mode"] == fold.mode and r["subject"] == fold.subject and r["budget"] == config.budget
                and r["runs"] == config.runs]
        if done:
            done[0]["nearest_training_pose_mm"] = floor
            say(f"{fold.label}: in {json_path} already")
            continue

        # One scene per test take: the same silhouettes in the cross and the within fold.
        scene = fold_test_scene(protocol, fold, sequences, seed=config.seed, views=views, size=size, renderer=renderer,
                                azimuth=azimuth)
        say(f"{fold.label}: train {', '.join(t.name for t in fold.train)}; validation {', '.join(t.name for t in fold.validation)}; "
            f"test {fold.test.name} ({scene.num_frames} frames){'; ' + fold.note if fold.note else ''}")
        start = time.perf_counter()
        results = run_experiment(train, validation, [scene], config, out_dir=os.path.join(out_dir, fold.label),
                                 names=fold.names, progress=progress, animations=False)
        row = _fold_row(fold, results, config, time.perf_counter() - start, settings)
        row["nearest_training_pose_mm"] = floor
        rows.append(row)
        write_protocol_outputs(protocol, rows, out_dir)
        say(f"{fold.label}: " + ", ".join(f"{m} {r['error_mm_mean']:.1f}" for m, r in row["methods"].items())
            + f" mm ({row['seconds']:.0f} s)")
        jax.clear_caches()  # each fold compiles its own trackers; keeping them all exhausts the memory maps
    write_protocol_outputs(protocol, rows, out_dir)
    return rows


def write_protocol_outputs(protocol: SubjectProtocol, rows: list[dict], out_dir: str) -> None:
    from ..io import atomic_write

    document = {"protocol": protocol.name, "description": protocol.description, "rows": rows}
    with atomic_write(os.path.join(out_dir, "protocol.json")) as handle:
        handle.write(json.dumps(document, indent=1).encode())
    with atomic_write(os.path.join(out_dir, "table.md")) as handle:
        handle.write((protocol_table(rows, title=f"{protocol.name}: {protocol.description}") + "\n").encode())
    if rows:
        plot_protocol(rows, os.path.join(out_dir, "protocol.png"), title=protocol.name)


def plot_protocol(rows: list[dict], path: str, *, title: str = "") -> str:
    """Per left-out subject, each tracker's mean error trained on other people (solid bars) and on
    the subject's own takes (hatched), with the nearest training pose of each (dashed and dotted
    lines): the cost of crossing people at a glance. Errors above 300 mm are clipped (marked)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ._report import method_label

    budgets = sorted({r["budget"] for r in rows})
    subjects = list(dict.fromkeys(r["subject"] for r in rows))
    methods = list(dict.fromkeys(m for r in rows for m in r["methods"]))
    fig, axes = plt.subplots(len(budgets), 1, figsize=(max(6.0, 1.9 * len(subjects) + 1.5), 3.2 * len(budgets)), squeeze=False)
    width = 0.8 / max(1, len(methods))
    clip = 300.0
    for ax, budget in zip(axes[:, 0], budgets):
        for j, method in enumerate(methods):
            for mode, style in (("cross", {}), ("within", {"hatch": "///", "alpha": 0.55})):
                xs, ys = [], []
                for i, subject in enumerate(subjects):
                    row = next((r for r in rows if r["subject"] == subject and r["mode"] == mode and r["budget"] == budget), None)
                    if row is not None and method in row["methods"]:
                        offset = -0.2 * width if mode == "cross" else 0.2 * width
                        xs.append(i + (j - (len(methods) - 1) / 2) * width + offset)
                        ys.append(row["methods"][method]["error_mm_mean"])
                bars = ax.bar(xs, [min(y, clip) for y in ys], width * 0.6, color=f"C{j}", edgecolor=f"C{j}",
                              label=method_label(method) if mode == "cross" else None, **style)
                for bar, y in zip(bars, ys):
                    if y > clip:
                        ax.text(bar.get_x(), clip, f"{y:.0f}", fontsize=6, rotation=90, va="top")
        for i, subject in enumerate(subjects):
            for mode, line in (("cross", "--"), ("within", ":")):
                row = next((r for r in rows if r["subject"] == subject and r["mode"] == mode and r["budget"] == budget), None)
                if row is not None and row.get("nearest_training_pose_mm") is not None:
                    ax.hlines(row["nearest_training_pose_mm"], i - 0.45, i + 0.45, colors="k", linestyles=line, lw=1)
        ax.set_xticks(range(len(subjects)), subjects)
        ax.set_ylabel("mean joint error (mm)")
        ax.set_ylim(0, clip)
        ax.set_title(f"{title}, budget {budget}: solid = trained on other people, hatched = on the subject's own takes;\n"
                     "dashed / dotted line = the nearest training pose (other people / own takes)", fontsize=8)
        ax.legend(fontsize=7, ncol=min(3, len(methods)), loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


MANIFOLD_TRACKERS_FIRST = ("mrpf", "gpapf", "latentpf", "glegbpf", "vlmmpf")


def protocol_table(rows: list[dict], *, title: str = "") -> str:
    """Markdown: per test subject, the cross and within rows (the start pose's error, the nearest
    training pose's (``nearest_pose_floor_mm``), and each tracker's mean error over the runs, mm,
    with its sd and the last quarter's error over the first's), then what the rows say: whether
    GLE-GbPF and the best manifold tracker beat SIR and APF across people, and the cross over
    within ratio of each tracker."""
    from ._report import method_label

    if not rows:
        return title + "\n\n(no folds run yet)"
    methods = list(dict.fromkeys(m for r in rows for m in r["methods"]))
    settings = rows[0]
    azimuth = settings.get("azimuth", DEFAULT_AZIMUTH)
    first = ("" if azimuth == DEFAULT_AZIMUTH else f" (the first at {azimuth:g} degrees)" if np.ndim(azimuth) == 0
             else f" (at {', '.join(f'{a:g}' for a in azimuth)} degrees)")
    centred = ", each training subject's posture taken out" if settings.get("centre_subjects") else ""
    centred += ", each take levelled onto its floor" if settings.get("level_floor") else ""
    started = (", the start found from the first frame's silhouettes on each fold's first manifold (no ground truth)"
               if settings.get("start") == "auto" else "")
    lines = [title, "", f"{settings['views']} views{first}, {settings['size'][0]}x{settings['size'][1]}, {settings['renderer']} renderer, "
             f"budget {settings['budget']}, {settings['runs']} runs{centred}{started}; mean (sd) mm, "
             "drift = last quarter / first quarter", "",
             "| subject | trained on | start | nearest training pose | " + " | ".join(method_label(m) for m in methods) + " |",
             "|---|---|---:|---:|" + "---:|" * len(methods)]
    order = {s: i for i, s in enumerate(dict.fromkeys(r["subject"] for r in rows))}
    for r in sorted(rows, key=lambda r: (r["budget"], order[r["subject"]], r["mode"])):
        cells = []
        for m in methods:
            e = r["methods"].get(m)
            cells.append("refused" if e is None else
                         f"{e['error_mm_mean']:.1f} ({e['error_mm_std']:.1f}) d{e['last_over_first_quarter']:.2f}")
        whose = "others" if r["mode"] == "cross" else "own takes"
        start = f"{r['start_error_mm']:.1f}" if r.get("start_error_mm") is not None else "-"
        floor = f"{r['nearest_training_pose_mm']:.1f}" if r.get("nearest_training_pose_mm") is not None else "-"
        lines.append(f"| {r['subject']} (b{r['budget']}) | {whose} | {start} | {floor} | " + " | ".join(cells) + " |")
    lines += ["", *protocol_verdicts(rows)]
    return "\n".join(lines)


def protocol_verdicts(rows: list[dict]) -> list[str]:
    """What the table says, one line each (``protocol_table``)."""
    out = []
    for budget in sorted({r["budget"] for r in rows}):
        cross = [r for r in rows if r["mode"] == "cross" and r["budget"] == budget]
        within = {r["subject"]: r for r in rows if r["mode"] == "within" and r["budget"] == budget}

        def error(r, m):
            return r["methods"][m]["error_mm_mean"] if m in r["methods"] else float("inf")

        if cross and all(m in cross[0]["methods"] for m in ("glegbpf", "sir", "apf")):
            wins = [r["subject"] for r in cross if error(r, "glegbpf") < min(error(r, "sir"), error(r, "apf"))]
            out.append(f"- budget {budget}: GLE-GbPF beats SIR and APF on {len(wins)} of {len(cross)} left-out subjects"
                       + (f" ({', '.join(wins)})" if wins else ""))
        manifold = [m for m in MANIFOLD_TRACKERS_FIRST if any(m in r["methods"] for r in cross)]
        if cross and manifold and all(m in cross[0]["methods"] for m in ("sir", "apf")):
            wins = [r["subject"] for r in cross if min(error(r, m) for m in manifold) < min(error(r, "sir"), error(r, "apf"))]
            out.append(f"- budget {budget}: the best manifold tracker beats SIR and APF on {len(wins)} of {len(cross)} left-out subjects")
        for r in cross:
            own = within.get(r["subject"])
            if own is None or not manifold:
                continue
            best = min(manifold, key=lambda m: error(r, m))
            best_own = min(manifold, key=lambda m: error(own, m))
            ratios = ", ".join(f"{m} {error(r, m) / error(own, m):.2f}" for m in r["methods"] if m in own["methods"])
            out.append(f"- budget {budget}, {r['subject']}: cross / within: {ratios}; best manifold tracker across people "
                       f"{best} {error(r, best):.1f} mm, {error(r, best) / error(own, best):.2f}x its within-subject error "
                       f"({error(r, best) / error(own, best_own):.2f}x the best within-subject one, {best_own} "
                       f"{error(own, best_own):.1f} mm)")
        drifting = [f"{r['subject']} {r['mode']} {m} {e['last_over_first_quarter']:.2f}" for r in rows if r["budget"] == budget
                    for m, e in r["methods"].items() if e["last_over_first_quarter"] > 1.3]
        out.append(f"- budget {budget}: drift over 1.3: " + ("; ".join(drifting) if drifting else "none"))
    return out
