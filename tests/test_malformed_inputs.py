"""A corpus of malformed inputs, each run through the command line as a user would: every one
must end in exit status 2 and one line on stderr that names the file (and the line or key where
there is one) and the reason, never a traceback, and must write nothing. ``--debug`` shows the
traceback; an error that is not bad input (a bug, here in a plugin) says so in one line too."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.io import save_sequence
from jaxtrack.manifold import make_gplvm, save_model

from helpers import ASF, small_scene, write_amc, write_bvh

AMC_FRAMES = [((0, 0, 0, 0, 0, 0), (0, 0, 0), (0,)), ((1, 2, 3, 0, 0, 90), (0, 0, 0), (90,))]


def _asf(tmp_path, text):
    asf, amc = tmp_path / "bad.asf", tmp_path / "t.amc"
    asf.write_text(text)
    write_amc(amc, AMC_FRAMES)
    return ["convert", str(amc), str(tmp_path / "out.npz"), "--asf", str(asf), "--source-fps", "120"]


def _amc(tmp_path, edit):
    asf, amc = tmp_path / "t.asf", tmp_path / "bad.amc"
    asf.write_text(ASF)
    write_amc(amc, AMC_FRAMES)
    amc.write_text(edit(amc.read_text()))
    return ["convert", str(amc), str(tmp_path / "out.npz"), "--asf", str(asf), "--source-fps", "120"]


def _bvh(tmp_path, edit):
    bvh = tmp_path / "bad.bvh"
    write_bvh(bvh, [[0] * 9, [1, 2, 3, 10, 20, 30, 5, 5, 5]])
    bvh.write_text(edit(bvh.read_text()))
    return ["convert", str(bvh), str(tmp_path / "out.npz")]


def _mapping(tmp_path):
    args = _bvh(tmp_path, lambda t: t)
    (tmp_path / "bad.json").write_text('{"pelvis": "hips",\n  "thorax": }\n')
    return [*args, "--mapping", str(tmp_path / "bad.json")]


def _sequence_bytes(tmp_path, make):
    path = tmp_path / "bad.npz"
    path.write_bytes(make(tmp_path))
    return ["render", str(path), "--out", str(tmp_path / "picture")]


def _saved_scene(tmp_path) -> bytes:
    path = save_sequence(tmp_path / "scene.npz", small_scene(num_frames=3, width=16, height=12)[-1])
    with open(path, "rb") as handle:
        return handle.read()


def _npy(tmp_path) -> bytes:
    np.save(tmp_path / "a.npy", np.zeros(3))
    return (tmp_path / "a.npy").read_bytes()


def _sequence_keys(tmp_path, change):
    fields = {k: np.array(v) for k, v in small_scene(num_frames=3, width=16, height=12)[-1].to_dict().items()}
    change(fields)
    np.savez(tmp_path / "bad.npz", **fields)
    return ["render", str(tmp_path / "bad.npz"), "--out", str(tmp_path / "picture")]


def _estimate_frames(tmp_path):
    scene = small_scene(num_frames=4, width=16, height=12)[-1]
    save_sequence(tmp_path / "scene.npz", scene)
    save_sequence(tmp_path / "bad.npz", scene.cropped(2))
    return ["render", str(tmp_path / "scene.npz"), "--estimate", str(tmp_path / "bad.npz"), "--out", str(tmp_path / "picture")]


def _model(tmp_path, edit):
    path = tmp_path / "bad.eqx"
    save_model(path, make_gplvm(np.random.default_rng(0).normal(size=(10, 4)), 2))
    path.write_bytes(edit(path.read_bytes()))
    return ["plot-latent", str(path), "--out", str(tmp_path / "latent.png")]


def _header_edit(data: bytes) -> bytes:
    head, _, payload = data.partition(b"\n")
    return json.dumps({**json.loads(head), "frames": 11}).encode() + b"\n" + payload


CORPUS = {
    # case: (argv builder, file named in the message, reason)
    "ASF hierarchy cycle": (lambda p: _asf(p, ASF.replace("    up side\n", "    up side\n    side up\n")), "bad.asf:", "second parent"),
    "ASF bone length 0": (lambda p: _asf(p, ASF.replace("length 2.0", "length 0")), "bad.asf:", "length must be positive"),
    "ASF direction 0 0 0": (lambda p: _asf(p, ASF.replace("direction 0 1 0", "direction 0 0 0")), "bad.asf:", "needs a direction"),
    "ASF name without a value": (lambda p: _asf(p, ASF.replace("name up", "name")), "bad.asf:", "'name' without a value"),
    "ASF lengths that overflow": (lambda p: _asf(p, ASF.replace("length 2.0", "length 1e300").replace("  length 1.0\n  angle",
                                                                                                       "  length 1e-300\n  angle")),
                                  "bad.asf", "overflow to infinity"),
    "mapping that fits no joint": (lambda p: _asf(p, ASF), "t.amc", "no built-in joint mapping fits"),
    "ASF truncated in a bone": (lambda p: _asf(p, ASF[: ASF.index("dof rx ry rz")]), "bad.asf:", "not closed with 'end'"),
    "AMC repeated frame number": (lambda p: _amc(p, lambda t: t.replace("\n2\n", "\n1\n")), "bad.amc:", "frame number 1 where 2"),
    "AMC NaN": (lambda p: _amc(p, lambda t: t.replace("side 90", "side nan")), "bad.amc:", "non-finite"),
    "AMC unknown bone": (lambda p: _amc(p, lambda t: t.replace("side 90", "elbow 90")), "bad.amc:", "elbow"),
    "BVH frame time inf": (lambda p: _bvh(p, lambda t: t.replace("Frame Time: 0.04", "Frame Time: inf")), "bad.bvh:", "Frame Time inf"),
    "BVH frame time 1e-300": (lambda p: _bvh(p, lambda t: t.replace("Frame Time: 0.04", "Frame Time: 1e-300")), "bad.bvh:", "between"),
    "BVH NaN value": (lambda p: _bvh(p, lambda t: t.replace("1 2 3 10", "1 nan 3 10")), "bad.bvh:", "non-finite value 'nan'"),
    "BVH missing frame": (lambda p: _bvh(p, lambda t: t.replace("Frames: 2", "Frames: 3")), "bad.bvh:", "header says 3 frames"),
    "BVH unbalanced brace": (lambda p: _bvh(p, lambda t: t.replace("}\nMOTION", "}\n}\nMOTION")), "bad.bvh:", "unbalanced"),
    "mapping JSON": (_mapping, "bad.json:2", "not valid JSON"),
    "text file as .npz": (lambda p: _sequence_bytes(p, lambda _: b"hello world"), "bad.npz", "this file starts b'hello"),
    ".npy renamed .npz": (lambda p: _sequence_bytes(p, _npy), "bad.npz", "single NumPy array"),
    "truncated .npz": (lambda p: _sequence_bytes(p, lambda q: _saved_scene(q)[:-200]), "bad.npz", "not a readable .npz"),
    "corrupt deflate stream": (lambda p: _sequence_bytes(p, lambda q: (lambda b: b[:400] + bytes(64) + b[464:])(_saved_scene(q))),
                               "bad.npz", "not a readable .npz"),
    "NaN joints": (lambda p: _sequence_keys(p, lambda f: f["joints3d"].__setitem__((0, 0, 0), np.nan)), "bad.npz", "joints3d"),
    "zero frames": (lambda p: _sequence_keys(p, lambda f: f.update(joints3d=f["joints3d"][:0], pose=f["pose"][:0],
                                                                   silhouettes=f["silhouettes"][:, :0])), "bad.npz", "no frames"),
    "unknown key": (lambda p: _sequence_keys(p, lambda f: f.update(colour=np.zeros(3))), "bad.npz", "unknown key"),
    "parents with a cycle": (lambda p: _sequence_keys(p, lambda f: f["parents"].__setitem__(1, 2)), "bad.npz", "parents"),
    "estimate with fewer frames": (_estimate_frames, "bad.npz", "2 frames of 15 joints, but"),
    "model truncated": (lambda p: _model(p, lambda b: b[:-50]), "bad.eqx", "truncated"),
    "model payload edited": (lambda p: _model(p, lambda b: b[:-5] + bytes([b[-5] ^ 1]) + b[-4:]), "bad.eqx", "edited or corrupted"),
    "model header edited": (lambda p: _model(p, _header_edit), "bad.eqx", "header's SHA-256"),
    "not a model": (lambda p: _model(p, lambda b: b"PK\x03\x04 zip"), "bad.eqx", "not a jaxtrack model file"),
}


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
@pytest.mark.parametrize("case", list(CORPUS))
def test_malformed_input_gives_one_line_naming_the_file(case, tmp_path, capsys):
    build, where, reason = CORPUS[case]
    argv = build(tmp_path)
    before = set(tmp_path.rglob("*"))
    assert main(argv) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith(f"jaxtrack {argv[0]}: error: ") and where in lines[0] and reason in lines[0], lines[0]
    assert "Traceback" not in captured.err + captured.out
    assert set(tmp_path.rglob("*")) == before  # nothing written, no temporary file left


@pytest.mark.slow
def test_debug_shows_the_traceback_and_a_bug_is_named_as_one(tmp_path, capsys):
    argv = CORPUS["ASF bone length 0"][0](tmp_path)
    with pytest.raises(ValueError, match="length must be positive"):
        main(["--debug", *argv])
    plugin = tmp_path / "broken.py"
    plugin.write_text(
        "from jaxtrack.tracking import TrackerRecipe, register_tracker\n"
        "def fit(key, motion):\n"
        "    raise KeyError('a bug in the plugin')\n"
        "register_tracker(TrackerRecipe('broken', 'Broken', 'fails', fit=fit, build=lambda *a: None), replace=True)\n"
    )
    scene = tmp_path / "scene.npz"
    save_sequence(scene, small_scene(num_frames=4)[-1])
    model = tmp_path / "m.eqx"
    assert main(["fit", str(scene), "--out", str(model), "--steps", "1"]) == 0
    capsys.readouterr()
    argv = ["track", str(scene), "--plugin", str(plugin), "--method", "broken", "--model", str(model), "--validation", str(scene),
            "--out", str(tmp_path / "est")]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "internal error: KeyError" in err and "--debug" in err and "Traceback" not in err
    with pytest.raises(KeyError, match="a bug in the plugin"):
        main(["--debug", *argv])
