"""The bad-input corpus: inputs a new user gets wrong, each with the exit status and the words of
the message it must end in (issue #47's classes, run as the user would: through ``jaxtrack``).

Every case is a function that writes its input files into a folder and returns the command
line; ``python tests/bad_inputs/corpus.py OUT`` writes every case's files into ``OUT/<case>/``
and the list of cases (command, exit status, words) to ``OUT/cases.json``, so that the corpus
can be looked at and run by hand. ``test_corpus.py`` runs every case in a fresh folder.

Cases that are valid after all (a seed of 0, a budget SIR can pay) are in the corpus too, with
exit status 0.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # tests/helpers.py

from helpers import ASF, small_scene, write_amc, write_bvh


@dataclasses.dataclass(frozen=True)
class Case:
    """One bad input: ``build(folder)`` writes the files and returns the command line (without
    ``jaxtrack``); the command must exit with ``status`` and print every one of ``words`` on
    stderr, in one line (status 2) and write nothing but what ``build`` wrote."""

    name: str
    build: Callable[[Path], list[str]]
    status: int
    words: tuple[str, ...]
    slow: bool = False


@functools.cache
def _small_sequence(frames: int):
    return small_scene(num_frames=frames, width=16, height=12)[-1]


def scene_file(folder: Path, name: str = "scene.npz", frames: int = 4, **change) -> Path:
    """A small valid test sequence (16x12, 4 views), with ``change`` replacing keys (a value, or a
    function of the file's dict of arrays)."""
    from jaxtrack.io import save_sequence

    sequence = _small_sequence(frames)
    path = folder / name
    if not change:
        save_sequence(path, sequence)
        return path
    fields = {k: np.array(v) for k, v in sequence.to_dict().items()}
    for key, value in change.items():
        fields[key] = value(fields) if callable(value) else value
    np.savez(path, **fields)
    return path


def model_file(folder: Path, name: str = "m.eqx") -> Path:
    """A small GPLVM model file fitted to nothing (its latent points from PCA)."""
    from jaxtrack.manifold import make_gplvm, save_model

    path = folder / name
    save_model(path, make_gplvm(np.random.default_rng(0).normal(size=(10, 4)), 2))
    return path


# --- motion and sequence files (the readers: one line naming the file, and the line or key) ---

AMC_FRAMES = [((0, 0, 0, 0, 0, 0), (0, 0, 0), (0,)), ((1, 2, 3, 0, 0, 90), (0, 0, 0), (90,))]


def _asf(folder: Path, text: str) -> list[str]:
    asf, amc = folder / "bad.asf", folder / "t.amc"
    asf.write_text(text)
    write_amc(amc, AMC_FRAMES)
    return ["convert", str(amc), str(folder / "out.npz"), "--asf", str(asf), "--source-fps", "120"]


def _amc(folder: Path, edit) -> list[str]:
    asf, amc = folder / "t.asf", folder / "bad.amc"
    asf.write_text(ASF)
    write_amc(amc, AMC_FRAMES)
    amc.write_text(edit(amc.read_text()))
    return ["convert", str(amc), str(folder / "out.npz"), "--asf", str(asf), "--source-fps", "120"]


def _bvh(folder: Path, edit) -> list[str]:
    bvh = folder / "bad.bvh"
    write_bvh(bvh, [[0] * 9, [1, 2, 3, 10, 20, 30, 5, 5, 5]])
    bvh.write_text(edit(bvh.read_text()))
    return ["convert", str(bvh), str(folder / "out.npz")]


def _mapping(folder: Path) -> list[str]:
    args = _bvh(folder, lambda t: t)
    (folder / "bad.json").write_text('{"pelvis": "hips",\n  "thorax": }\n')
    return [*args, "--mapping", str(folder / "bad.json")]


def _render(path: Path, folder: Path) -> list[str]:
    return ["render", str(path), "--out", str(folder / "picture")]


def _sequence_bytes(folder: Path, make) -> list[str]:
    path = folder / "bad.npz"
    path.write_bytes(make(folder))
    (folder / "scene.npz").unlink(missing_ok=True)
    return _render(path, folder)


def _saved_scene(folder: Path) -> bytes:
    return scene_file(folder).read_bytes()


def _npy(folder: Path) -> bytes:
    np.save(folder / "a.npy", np.zeros(3))
    data = (folder / "a.npy").read_bytes()
    (folder / "a.npy").unlink()
    return data


def _keys(folder: Path, **change) -> list[str]:
    return _render(scene_file(folder, "bad.npz", **change), folder)


def _estimate_frames(folder: Path) -> list[str]:
    from jaxtrack.io import save_sequence

    scene = _small_sequence(4)
    save_sequence(folder / "scene.npz", scene)
    save_sequence(folder / "bad.npz", scene.cropped(2))
    return ["render", str(folder / "scene.npz"), "--estimate", str(folder / "bad.npz"), "--out", str(folder / "picture")]


def _joints_in(folder: Path, factor: float, name: str) -> list[str]:
    """3-D joint positions of the small scene's walk, scaled by ``factor`` (metres -> other units)."""
    sequence = _small_sequence(4)
    path = folder / name
    np.savez(path, fps=sequence.fps, joints3d=factor * np.asarray(sequence.joints3d), joint_names=np.asarray(sequence.joint_names))
    return ["convert", str(path), str(folder / "out.npz")]


def _fit_with_a_huge_frame(folder: Path) -> list[str]:
    path = scene_file(folder, "train.npz", pose=lambda f: np.where(np.arange(4)[:, None] == 3, 1e300, f["pose"]))
    return ["fit", str(path), "--model", "gpdm", "--steps", "3", "--out", str(folder / "m.eqx")]


# --- model files ---

def _model(folder: Path, edit) -> list[str]:
    path = model_file(folder, "bad.eqx")
    path.write_bytes(edit(path.read_bytes()))
    return ["plot-latent", str(path), "--out", str(folder / "latent.png")]


def _header(edit):
    """An edit of a model file's JSON header line (the payload kept)."""

    def apply(data: bytes) -> bytes:
        head, _, payload = data.partition(b"\n")
        return json.dumps(edit(json.loads(head), payload)).encode() + b"\n" + payload

    return apply


def _version_1(change=None, payload_edit=None):
    """A model file rewritten as format version 1 (no payload length, no checksums), with the
    header's ``change`` and the payload's ``payload_edit``."""

    def apply(data: bytes) -> bytes:
        head, _, payload = data.partition(b"\n")
        header = {k: v for k, v in json.loads(head).items() if k not in ("payload_bytes", "payload_sha256", "header_sha256")}
        header.update({"version": 1, **(change or {})})
        return json.dumps(header).encode() + b"\n" + (payload_edit(payload) if payload_edit else payload)

    return apply


def _nan_payload(payload: bytes) -> bytes:
    """The last 8 bytes of the arrays (a float64 scale) replaced by a NaN."""
    return payload[:-8] + np.array([np.nan]).tobytes()


def _track_with(folder: Path, test: Path, *extra: str, method: str = "sir") -> list[str]:
    from jaxtrack.cli import main

    good = scene_file(folder, "walk.npz") if test.name != "walk.npz" else test
    model = folder / "m.eqx"
    if main(["fit", str(good), "--out", str(model), "--steps", "1"]) != 0:
        raise RuntimeError("the corpus could not fit its model")
    return ["track", str(test), "--method", method, "--model", str(model), "--validation", str(good), "--budget", "16",
            *extra, "--out", str(folder / "est")]


def _track_args(*extra: str) -> Callable[[Path], list[str]]:
    """``track`` on files that need not exist: the arguments are refused before any is read."""
    return lambda d: ["track", str(d / "t.npz"), "--model", str(d / "m.eqx"), "--validation", str(d / "v.npz"),
                      "--out", str(d / "o.npz"), *extra]


CASES: list[Case] = [
    # motion files
    Case("ASF hierarchy cycle", lambda d: _asf(d, ASF.replace("    up side\n", "    up side\n    side up\n")), 2,
         ("bad.asf:", "second parent")),
    Case("ASF bone length 0", lambda d: _asf(d, ASF.replace("length 2.0", "length 0")), 2, ("bad.asf:", "length must be positive")),
    Case("ASF direction 0 0 0", lambda d: _asf(d, ASF.replace("direction 0 1 0", "direction 0 0 0")), 2,
         ("bad.asf:", "needs a direction")),
    Case("ASF name without a value", lambda d: _asf(d, ASF.replace("name up", "name")), 2, ("bad.asf:", "'name' without a value")),
    Case("ASF lengths that overflow", lambda d: _asf(d, ASF.replace("length 2.0", "length 1e300").replace(
        "  length 1.0\n  angle", "  length 1e-300\n  angle")), 2, ("bad.asf", "overflow to infinity")),
    Case("mapping that fits no joint", lambda d: _asf(d, ASF), 2, ("t.amc", "no built-in joint mapping fits")),
    Case("ASF truncated in a bone", lambda d: _asf(d, ASF[: ASF.index("dof rx ry rz")]), 2, ("bad.asf:", "not closed with 'end'")),
    Case("AMC repeated frame number", lambda d: _amc(d, lambda t: t.replace("\n2\n", "\n1\n")), 2,
         ("bad.amc:", "frame number 1 where 2")),
    Case("AMC NaN", lambda d: _amc(d, lambda t: t.replace("side 90", "side nan")), 2, ("bad.amc:", "non-finite")),
    Case("AMC unknown bone", lambda d: _amc(d, lambda t: t.replace("side 90", "elbow 90")), 2, ("bad.amc:", "elbow")),
    Case("BVH frame time inf", lambda d: _bvh(d, lambda t: t.replace("Frame Time: 0.04", "Frame Time: inf")), 2,
         ("bad.bvh:", "Frame Time inf")),
    Case("BVH frame time 1e-300", lambda d: _bvh(d, lambda t: t.replace("Frame Time: 0.04", "Frame Time: 1e-300")), 2,
         ("bad.bvh:", "between")),
    Case("BVH NaN value", lambda d: _bvh(d, lambda t: t.replace("1 2 3 10", "1 nan 3 10")), 2, ("bad.bvh:", "non-finite value 'nan'")),
    Case("BVH missing frame", lambda d: _bvh(d, lambda t: t.replace("Frames: 2", "Frames: 3")), 2, ("bad.bvh:", "header says 3 frames")),
    Case("BVH unbalanced brace", lambda d: _bvh(d, lambda t: t.replace("}\nMOTION", "}\n}\nMOTION")), 2, ("bad.bvh:", "unbalanced")),
    Case("mapping JSON", _mapping, 2, ("bad.json:2", "not valid JSON")),
    Case("joints in centimetres", lambda d: _joints_in(d, 100.0, "walk_cm.npz"), 2,
         ("walk_cm.npz", "joints3d", "they look like centimetres")),
    Case("joints in millimetres", lambda d: _joints_in(d, 1000.0, "walk_mm.npz"), 2,
         ("walk_mm.npz", "joints3d", "they look like millimetres")),
    # sequence files
    Case("text file as .npz", lambda d: _sequence_bytes(d, lambda _: b"hello world"), 2, ("bad.npz", "this file starts b'hello")),
    Case(".npy renamed .npz", lambda d: _sequence_bytes(d, _npy), 2, ("bad.npz", "single NumPy array")),
    Case("truncated .npz", lambda d: _sequence_bytes(d, lambda q: _saved_scene(q)[:-200]), 2, ("bad.npz", "not a readable .npz")),
    Case("corrupt deflate stream", lambda d: _sequence_bytes(d, lambda q: (lambda b: b[:400] + bytes(64) + b[464:])(_saved_scene(q))),
         2, ("bad.npz", "not a readable .npz")),
    Case("NaN joints", lambda d: _keys(d, joints3d=lambda f: np.where(np.arange(f["joints3d"].size).reshape(f["joints3d"].shape) == 0,
                                                                      np.nan, f["joints3d"])), 2, ("bad.npz", "joints3d")),
    Case("zero frames", lambda d: _keys(d, joints3d=lambda f: f["joints3d"][:0], pose=lambda f: f["pose"][:0],
                                        silhouettes=lambda f: f["silhouettes"][:, :0]), 2, ("bad.npz", "no frames")),
    Case("unknown key", lambda d: _keys(d, colour=np.zeros(3)), 2, ("bad.npz", "unknown key")),
    Case("parents with a cycle", lambda d: _keys(d, parents=lambda f: np.where(np.arange(len(f["parents"])) == 1, 2, f["parents"])), 2,
         ("bad.npz", "parents")),
    Case("estimate with fewer frames", _estimate_frames, 2, ("bad.npz", "2 frames of 15 joints, but")),
    Case("offsets x 1e200", lambda d: _keys(d, skeleton_offsets=lambda f: f["skeleton_offsets"] * 1e200), 2,
         ("bad.npz", "skeleton_offsets", "no human bone is longer than 1.5 m")),
    Case("capsule radii of 50 km", lambda d: _keys(d, capsule_radii=lambda f: np.full_like(f["capsule_radii"], 5e4)), 2,
         ("bad.npz", "capsule_radii", "no limb is thicker than 2 m")),
    Case("camera translations x 1e300", lambda d: _keys(d, camera_t=lambda f: f["camera_t"] * 1e300), 2,
         ("bad.npz", "camera_t", "a capture volume is not larger than 1000 m")),
    Case("camera rotation entry 1e300", lambda d: _keys(d, camera_R=lambda f: np.where(np.arange(f["camera_R"].size).reshape(
        f["camera_R"].shape) == 0, 1e300, f["camera_R"])), 2, ("bad.npz", "camera_R", "camera 0 is not a rotation matrix")),
    Case("complex fps", lambda d: _keys(d, fps=np.complex64(60)), 2, ("bad.npz", "fps", "must be a positive scalar")),
    Case("fit on a frame of 1e300", _fit_with_a_huge_frame, 2, ("train.npz", "'pose'", "1e+300 at frame 3", "so not a pose")),
    # model files
    Case("model truncated", lambda d: _model(d, lambda b: b[:-50]), 2, ("bad.eqx", "truncated")),
    Case("model payload edited", lambda d: _model(d, lambda b: b[:-5] + bytes([b[-5] ^ 1]) + b[-4:]), 2,
         ("bad.eqx", "edited or corrupted")),
    Case("model header edited", lambda d: _model(d, _header(lambda h, _: {**h, "frames": 11})), 2, ("bad.eqx", "header's SHA-256")),
    Case("not a model", lambda d: _model(d, lambda b: b"PK\x03\x04 zip"), 2, ("bad.eqx", "not a jaxtrack model file")),
    Case("model header a JSON list", lambda d: _model(d, lambda b: b"[1, 2]\n" + b.partition(b"\n")[2]), 2,
         ("bad.eqx", "its header is a JSON list")),
    Case("version 1 model with a NaN", lambda d: _model(d, _version_1(payload_edit=_nan_payload)), 2, ("bad.eqx", "are not finite")),
    Case("version 1 model of another class", lambda d: _model(d, _version_1({"class": "GPDM"})), 2,
         ("bad.eqx", "the header does not describe the arrays")),
    Case("version 1 model, sequence_starts out of range", lambda d: _model(d, _version_1({"sequence_starts": [0, 99]})), 2,
         ("bad.eqx", "sequence_starts must rise from 0 to the 10 frames")),
    Case("version 1 model that is whole", lambda d: _model(d, _version_1()), 0, (), slow=True),
    # arguments, refused before any file is read
    Case("--seed 10^23", lambda d: ["demo", "--seed", str(10**23)], 2, ("a seed is a whole number from 0 to 4294967295",)),
    Case("demo --runs 0", lambda d: ["demo", "--runs", "0"], 2, ("expected a whole number from 1 up, got 0",)),
    Case("scene --views 0", lambda d: ["scene", "in.npz", "out.npz", "--views", "0"], 2, ("--views", "from 1 to 64, got 0")),
    Case("scene 100000 x 100000", lambda d: ["scene", "in.npz", "out.npz", "--width", "100000", "--height", "100000"], 2,
         ("--width", "from 8 to 4096, got 100000")),
    Case("--max-degenerate nan", _track_args("--max-degenerate", "nan"), 2, ("expected a number from 0 to 1, got nan",)),
    Case("--max-degenerate -1", _track_args("--max-degenerate", "-1"), 2, ("expected a number from 0 to 1, got -1",)),
    Case("scene --frames 0", lambda d: ["scene", "in.npz", "out.npz", "--frames", "0"], 2, ("--frames", "from 1 up, got 0")),
    Case("fit --steps 0", lambda d: ["fit", "in.npz", "--steps", "0", "--out", "m.eqx"], 2, ("--steps", "from 1 up, got 0")),
    Case("--chunk-frames -1", _track_args("--chunk-frames", "-1"), 2, ("--chunk-frames", "from 0 up, got -1")),
    Case("--residual-decay 0", _track_args("--residual-decay", "0"), 2, ("--residual-decay", "above 0 and at most 1, got 0")),
    Case("--out under /proc", lambda d: ["scene", str(scene_file(d)), "/proc/x.npz"], 2, ("/proc", "cannot write files")),
    # valid after all, or refused only once the files are read (these fit a model first: slow)
    Case("pose truncated to integers", lambda d: _track_with(d, scene_file(d, "trunc.npz", pose=lambda f: np.trunc(f["pose"]))), 2,
         ("trunc.npz", "'pose' contradicts 'joints3d'"), slow=True),
    Case("--budget 1 for SIR", lambda d: _track_with(d, scene_file(d, "walk.npz"), "--budget", "1"), 0, (), slow=True),
    Case("--budget 1 for APF", lambda d: _track_with(d, scene_file(d, "walk.npz"), "--budget", "1", method="apf"), 2,
         ("through 5 annealing layers of APF",), slow=True),
    Case("0/255 silhouettes", lambda d: _track_with(d, scene_file(d, "mask.npz", silhouettes=lambda f: f["silhouettes"].astype(np.uint8)
                                                                   * 255)), 0, (), slow=True),
]


# --- the Python API: the same rules, raised as exceptions ---

@dataclasses.dataclass(frozen=True)
class APICase:
    """One misuse of the Python API: ``call(context)`` must raise ``error`` with every one of
    ``words`` in its message, or (``error`` None) return a value for which ``check(value,
    context)`` holds."""

    name: str
    call: Callable[[Any], Any]
    error: type[BaseException] | None
    words: tuple[str, ...] = ()
    check: Callable[[Any, Any], bool] | None = None


@dataclasses.dataclass
class APIContext:
    """What the API cases misuse: a small scene, its likelihood, one frame and a key."""

    folder: Path
    sequence: Any
    rig: Any
    body: Any
    likelihood: Any
    poses: Any
    observed: Any
    key: Any


def api_context(folder: Path) -> APIContext:
    import jax
    import jax.numpy as jnp

    from jaxtrack import make_silhouette_likelihood

    sequence = _small_sequence(4)
    rig, body = sequence.rig(), sequence.body()
    poses = jnp.tile(jnp.asarray(sequence.pose[0])[None], (3, 1))
    return APIContext(folder, sequence, rig, body, make_silhouette_likelihood(body, rig), poses,
                      jnp.asarray(sequence.silhouettes[:, 0], poses.dtype), jax.random.key(0))


def _same_score(value, c) -> bool:
    return bool(np.allclose(np.asarray(value), np.asarray(c.likelihood.log_likelihood(c.poses, c.observed))))


def _jt():
    import jaxtrack

    return jaxtrack


API_CASES: list[APICase] = [
    APICase("0/255 uint8 masks score as 0/1", lambda c: c.likelihood.log_likelihood(c.poses, (c.observed * 255).astype(np.uint8)),
            None, check=_same_score),
    APICase("0/255 float masks", lambda c: c.likelihood.log_likelihood(c.poses, c.observed * 255), ValueError,
            ("values in [0, 1]", "uint8")),
    APICase("transposed observation", lambda c: c.likelihood.log_likelihood(c.poses, np.swapaxes(c.observed, -1, -2)), ValueError,
            ("(views, height, width) = (4, 12, 16)", "transposed")),
    APICase("NaN in the observation", lambda c: c.likelihood.log_likelihood(c.poses, c.observed.at[0, 0, 0].set(np.nan)), ValueError,
            ("NaN or infinite",)),
    APICase("malformed silhouettes= to make_silhouette_likelihood",
            lambda c: _jt().make_silhouette_likelihood(c.body, c.rig, silhouettes=np.zeros((3, 4))), ValueError,
            ("silhouettes=", "(views, height, width)")),
    APICase("empty silhouettes= to make_silhouette_likelihood",
            lambda c: _jt().make_silhouette_likelihood(c.body, c.rig, silhouettes=np.zeros((4, 2, 12, 16))), ValueError,
            ("empty silhouette in view 0",)),
    APICase("a negative lost divergence for the blobs", lambda c: __import__("jaxtrack.likelihood").likelihood.make_blob_likelihood(
        c.body, c.rig, lost_divergence=-1.0), ValueError, ("lost_divergence must be positive or None", "got -1.0")),
    APICase("the colour blobs on a file without images", lambda c: _jt().prepare_test(c.sequence, "walk", key=c.key,
            likelihood="colour-blobs"), ValueError, ("tracked with the colour-blobs likelihood needs images", "(key images)")),
    APICase("restarts on dynamics that cannot restart", lambda c: _jt().filters.RecoveringSIR(_jt().fit_pose_random_walk(
        [np.asarray(c.sequence.pose)]), c.likelihood, 4, lost_below=-10.0), ValueError, ("PoseRandomWalk has none",)),
    APICase("prepare_test(frames=-3)", lambda c: _jt().prepare_test(c.sequence, "walk", key=c.key, frames=-3), ValueError,
            ("walk: frames must be a whole number", "got -3")),
    APICase("prepare_test with an int key", lambda c: _jt().prepare_test(c.sequence, "walk", key=0), TypeError,
            ("key must be a PRNG key", "got 0")),
    APICase("run_filter with an int key", lambda c: _jt().run_filter(_jt().SIR(_jt().fit_pose_random_walk([np.asarray(
        c.sequence.pose)]), c.likelihood, 4), 0, c.poses[0], np.swapaxes(np.asarray(c.sequence.silhouettes), 0, 1)), TypeError,
            ("key must be a PRNG key",)),
    APICase("run_filter with a batch of keys", lambda c: _jt().run_filter(_jt().SIR(_jt().fit_pose_random_walk([np.asarray(
        c.sequence.pose)]), c.likelihood, 4), _split(c.key), c.poses[0], np.swapaxes(np.asarray(c.sequence.silhouettes), 0, 1)),
            TypeError, ("one PRNG key", "vmap over the keys")),
    APICase("integer pose to forward_kinematics", lambda c: _jt().forward_kinematics(c.body.skeleton, np.zeros(c.poses.shape[1], int)),
            None, check=lambda v, c: bool(np.allclose(v, _jt().forward_kinematics(c.body.skeleton, np.zeros(c.poses.shape[1]))))),
    APICase("generate_motion(key)", lambda c: _jt().generate_motion(c.key), TypeError, ("first argument is the gait", "key=")),
    APICase("build_scene of an array", lambda c: _jt().build_scene(c.key, np.asarray(c.sequence.pose), c.rig), TypeError,
            ("SyntheticMotion", "got ndarray")),
    APICase("fit_manifold of one array", lambda c: _jt().fit_manifold(np.asarray(c.sequence.pose), 2, 5), TypeError,
            ("list of (frames, dofs) pose arrays", "pass [poses]")),
    APICase("fit_manifold of NaN poses", lambda c: _jt().fit_manifold([np.full(c.sequence.pose.shape, np.nan)], 2, 5), ValueError,
            ("non-finite value at frame 0",)),
    APICase("fit_manifold of one frame", lambda c: _jt().fit_manifold([np.asarray(c.sequence.pose[:1])], 2, 5), ValueError,
            ("too few for a 2-D latent space",)),
    APICase("mean_joint_error_mm of mismatched shapes", lambda c: _jt().mean_joint_error_mm(np.zeros((4, 15, 3)), np.zeros((3, 15, 3))),
            ValueError, ("same shape",)),
    APICase("inverse_kinematics of 14 joints", lambda c: _jt().inverse_kinematics(np.zeros((4, 14, 3))), ValueError,
            ("(T, 15, 3)",)),
    APICase("default_rig(num_views=0)", lambda c: _jt().default_rig(num_views=0), ValueError, ("num_views must be a positive integer",)),
    APICase("SIR with no particles", lambda c: _jt().SIR(None, c.likelihood, 0), ValueError, ("num_particles must be a positive",)),
    APICase("a negative limb", lambda c: _jt().humaneva_body(limb_lengths={"thigh": -1}), ValueError, ("'thigh'", "positive")),
    APICase("a random walk from one frame", lambda c: _jt().fit_pose_random_walk([np.asarray(c.sequence.pose[:1])]), ValueError,
            ("T >= 2",)),
    APICase("load_sequence of a folder", lambda c: _jt().load_sequence(c.folder), Exception, ("is a folder",)),
    APICase("save_model of a diverged fit", lambda c: _jt().save_model(c.folder / "nan.eqx", _diverged_model()), Exception,
            ("nan.eqx: not saved", "not finite")),
]


def _diverged_model():
    """A GPLVM whose latent points a diverged fit left NaN."""
    import equinox as eqx

    from jaxtrack.manifold import make_gplvm

    model = make_gplvm(np.random.default_rng(0).normal(size=(10, 4)), 2)
    return eqx.tree_at(lambda m: m.latent, model, model.latent * np.nan)


def _split(key):
    import jax

    return jax.random.split(key, 2)



def main(argv=None) -> int:
    """Write every case's files into OUT/<case>/ and the list to OUT/cases.json (``--fast``: only
    the cases that fit no model)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    fast = "--fast" in argv
    argv = [a for a in argv if a != "--fast"]
    if len(argv) != 1:
        print("usage: python tests/bad_inputs/corpus.py OUT [--fast]", file=sys.stderr)
        return 2
    out = Path(argv[0])
    listing = []
    for case in CASES:
        if fast and case.slow:
            continue
        folder = out / "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in case.name).strip("-_.")
        folder.mkdir(parents=True, exist_ok=True)
        listing.append({"case": case.name, "argv": ["jaxtrack", *case.build(folder)], "status": case.status,
                        "words": list(case.words)})
    (out / "cases.json").write_text(json.dumps(listing, indent=1))
    print(f"wrote {len(listing)} cases to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
