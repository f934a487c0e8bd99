"""Property-based fuzzing of every reader (ASF/AMC, BVH, sequence files, model files): random
truncations, byte flips, token and value mutations, duplicated and dropped lines. Each input
must end, within a time limit, either in the package's own error (a ``JaxtrackError``, which
names the file) or in a result that is valid (finite values, consistent shapes), never in
another exception, a hang, or a warning (the suite turns warnings into errors)."""

from __future__ import annotations

import contextlib
import signal
import time

import hypothesis.strategies as st
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from jaxtrack.errors import JaxtrackError
from jaxtrack.io import load_asf_amc, load_bvh, load_sequence, save_sequence
from jaxtrack.manifold import load_model, make_gpdm, save_model

from helpers import ASF, small_scene, write_amc, write_bvh

SECONDS_PER_INPUT = 5.0
FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
                derandomize=True)
REPLACEMENTS = [b"nan", b"inf", b"-inf", b"1e400", b"-1e308", b"1e308", b"0", b"-0", b"", b"x", b"999999999999", b"-1",
                b"1e-300", b"(", b"}", b"{", b"begin", b"end", b"\x00", b"\xff\xfe"]


class Hang(Exception):
    pass


@contextlib.contextmanager
def time_limit(seconds: float):
    """Raise ``Hang`` if the block runs longer than ``seconds`` (SIGALRM; the main thread)."""

    def expire(signum, frame):
        raise Hang(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@st.composite
def mutations(draw, data: bytes) -> bytes:
    """One to three random edits of ``data``: truncation, byte flips, a token replaced, a line
    duplicated or dropped."""
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["truncate", "flip", "token", "duplicate", "drop"]))
        if kind == "truncate" and data:
            data = data[: draw(st.integers(0, len(data) - 1))]
        elif kind == "flip" and data:
            edited = bytearray(data)
            for _ in range(draw(st.integers(1, 4))):
                edited[draw(st.integers(0, len(edited) - 1))] = draw(st.integers(0, 255))
            data = bytes(edited)
        elif kind == "token":
            tokens = data.split(b" ")
            tokens[draw(st.integers(0, len(tokens) - 1))] = draw(st.sampled_from(REPLACEMENTS))
            data = b" ".join(tokens)
        elif kind in ("duplicate", "drop"):
            lines = data.split(b"\n")
            i = draw(st.integers(0, len(lines) - 1))
            if kind == "drop":
                del lines[i]
            else:
                lines.insert(draw(st.integers(0, len(lines))), lines[i])
            data = b"\n".join(lines)
    return data


def read_or_refuse(read):
    """Run ``read`` under the time limit; return its result, or None if it refused with the
    package's own error. Anything else fails the test (with the input's text in the report)."""
    start = time.perf_counter()
    try:
        with time_limit(SECONDS_PER_INPUT):
            return read()
    except JaxtrackError as err:
        assert str(err), "an error without a message"
        return None
    finally:
        assert time.perf_counter() - start < SECONDS_PER_INPUT


def check_motion(motion):
    assert motion.num_frames >= 1
    assert np.all(np.isfinite(motion.positions)) and np.all(np.isfinite(motion.values))
    assert motion.positions.shape == (motion.num_frames, len(motion.joint_names), 3)
    assert motion.values.shape == (motion.num_frames, len(motion.channels))
    assert np.isfinite(motion.fps) and motion.fps > 0


@pytest.fixture(scope="module")
def motion_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("motion")
    asf, amc, bvh = folder / "t.asf", folder / "t.amc", folder / "t.bvh"
    asf.write_text(ASF)
    frames = [((0, 0, 0, 0, 0, 0), (0, 0, 0), (0,)), ((1, 2, 3, 0, 0, 90), (10, 20, 30), (90,)), ((1, 2, 3, 5, 5, 5), (1, 2, 3), (4,))]
    write_amc(amc, frames)
    write_bvh(bvh, [[0] * 9, [1, 2, 3, 10, 20, 30, 5, 5, 5], [2, 2, 2, 1, 2, 3, 4, 5, 6]])
    return folder, asf, amc, bvh


MOTION_READERS = {  # which file is edited, and how the pair is read
    "asf": lambda asf, amc, bvh: load_asf_amc(asf, amc, 120.0),
    "amc": lambda asf, amc, bvh: load_asf_amc(asf, amc, 120.0),
    "bvh": lambda asf, amc, bvh: load_bvh(bvh),
}


@pytest.mark.parametrize("edited_kind", list(MOTION_READERS))
@FUZZ
@given(data=st.data())
def test_motion_readers_never_crash_hang_or_return_nonsense(motion_files, edited_kind, data):
    folder, *originals = motion_files
    files = dict(zip(("asf", "amc", "bvh"), originals))
    edited = folder / f"edited.{edited_kind}"
    edited.write_bytes(data.draw(mutations(files[edited_kind].read_bytes())))
    files[edited_kind] = edited
    motion = read_or_refuse(lambda: MOTION_READERS[edited_kind](files["asf"], files["amc"], files["bvh"]))
    if motion is not None:
        check_motion(motion)


@pytest.fixture(scope="module")
def sequence_file(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sequence")
    path = save_sequence(folder / "scene.npz", small_scene()[-1])  # the scene other modules build too (one compile)
    with np.load(path) as archive:
        return folder, path, {k: archive[k] for k in archive.files}


def _mutate_array(draw, value: np.ndarray):
    kind = draw(st.sampled_from(["nan", "inf", "huge", "negative", "shape", "transpose", "dtype", "empty", "scalar"]))
    value = np.array(value)
    if kind in ("nan", "inf", "huge", "negative") and value.size and value.dtype.kind == "f":
        flat = value.reshape(-1)
        flat[draw(st.integers(0, flat.size - 1))] = {"nan": np.nan, "inf": np.inf, "huge": 1e300, "negative": -1.0}[kind]
        return flat.reshape(value.shape)
    if kind == "shape" and value.ndim:
        return value.reshape(-1)[: max(0, value.size - 1)]
    if kind == "transpose" and value.ndim >= 2:
        return np.swapaxes(value, 0, -1)
    if kind == "dtype":
        dtype = draw(st.sampled_from([np.complex64, np.bool_, np.int8, "U3"]))
        if value.dtype.kind == "U" and dtype in (np.complex64, np.int8):  # NumPy cannot convert names to numbers
            dtype = np.bool_
        return value.astype(dtype)
    if kind == "empty":
        return value[:0] if value.ndim else np.zeros(0)
    if kind == "scalar":
        return np.asarray(draw(st.sampled_from([0.0, -1.0, np.nan, 1e300])))
    return value


@FUZZ
@given(data=st.data())
def test_sequence_reader_refuses_every_bad_value_with_its_own_error(sequence_file, data):
    folder, _, fields = sequence_file
    fields = dict(fields)
    for _ in range(data.draw(st.integers(1, 2))):
        key = data.draw(st.sampled_from(sorted(fields)))
        action = data.draw(st.sampled_from(["mutate", "mutate", "drop", "rename"]))
        if action == "drop":
            del fields[key]
        elif action == "rename":
            fields[key + "_x"] = fields.pop(key)
        else:
            fields[key] = _mutate_array(data.draw, fields[key])
    path = folder / "mutated.npz"
    with open(path, "wb") as handle:
        np.savez(handle, **fields)
    sequence = read_or_refuse(lambda: load_sequence(path))
    if sequence is not None:
        for key, value in sequence.to_dict().items():
            if np.asarray(value).dtype.kind == "f":
                assert np.all(np.isfinite(value)), key


@FUZZ
@given(data=st.data())
def test_sequence_file_bytes_never_crash_the_reader(sequence_file, data):
    folder, path, _ = sequence_file
    edited = folder / "edited.npz"
    with open(path, "rb") as handle:
        edited.write_bytes(data.draw(mutations(handle.read())))
    read_or_refuse(lambda: load_sequence(edited))


@pytest.fixture(scope="module")
def model_file(tmp_path_factory):
    folder = tmp_path_factory.mktemp("model")
    rng = np.random.default_rng(0)
    model = make_gpdm([rng.normal(size=(12, 4)), rng.normal(size=(8, 4))], 2)
    save_model(folder / "gpdm.eqx", model, extra={"pose_layout": ["a", "b", "c", "d"]})
    return folder, folder / "gpdm.eqx", float(model.objective())


@FUZZ
@given(data=st.data())
def test_model_reader_reports_every_edit_of_the_file(model_file, data):
    folder, path, objective = model_file
    original = path.read_bytes()
    edited_bytes = data.draw(mutations(original))
    edited = folder / "edited.eqx"
    edited.write_bytes(edited_bytes)
    loaded = read_or_refuse(lambda: load_model(edited))
    if loaded is not None:  # only an edit that changed nothing (or only JSON whitespace) may load
        model, _ = loaded
        assert float(model.objective()) == pytest.approx(objective, rel=1e-12)
        assert bool(jnp.all(jnp.isfinite(model.latent)))


def test_fuzzing_harness_catches_a_hang_and_a_foreign_error():
    """The harness itself: a reader that loops or raises something else fails the property."""
    with pytest.raises(Hang):
        with time_limit(0.2):
            while True:
                pass
    with pytest.raises(TypeError):
        read_or_refuse(lambda: (_ for _ in ()).throw(TypeError("not ours")))
    assert read_or_refuse(lambda: (_ for _ in ()).throw(JaxtrackError("ours"))) is None


LONG_FUZZ = settings(max_examples=400, deadline=None, derandomize=True, database=None,
                     suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@pytest.mark.slow  # 400 inputs per reader instead of 60: about 2-3 minutes on 2 cores
def test_every_reader_under_a_longer_fuzz(motion_files, sequence_file, model_file):
    """The same properties as above, each over 400 inputs drawn from other seeds than the default
    suite's (their own test functions)."""
    def motion_property(kind):
        return lambda data: test_motion_readers_never_crash_hang_or_return_nonsense.hypothesis.inner_test(motion_files, kind,
                                                                                                         data=data)

    properties = [
        *(motion_property(kind) for kind in MOTION_READERS),
        lambda data: test_sequence_reader_refuses_every_bad_value_with_its_own_error.hypothesis.inner_test(sequence_file, data=data),
        lambda data: test_sequence_file_bytes_never_crash_the_reader.hypothesis.inner_test(sequence_file, data=data),
        lambda data: test_model_reader_reports_every_edit_of_the_file.hypothesis.inner_test(model_file, data=data),
    ]
    for prop in properties:
        LONG_FUZZ(given(data=st.data())(prop))()
