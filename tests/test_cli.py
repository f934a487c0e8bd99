import os
from pathlib import Path

import imageio.v3 as iio
import jax
import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.demo import run_likelihood_demo
from jaxtrack.io import load_sequence, save_sequence

from helpers import interrupt_the_second_chunk, small_scene


@pytest.mark.slow  # moved to the slow suite for the default suite's 10 minutes
def test_render_writes_png_and_gif(tmp_path, capsys):
    seq = small_scene()[2]
    path = tmp_path / "walk.npz"
    save_sequence(path, seq)
    assert main(["render", str(path), "--every", "2", "--scale", "2"]) == 0
    png = iio.imread(tmp_path / "walk_sheet.png")
    gif = iio.imread(tmp_path / "walk.gif", index=None)
    assert png.ndim == 3 and png.shape[0] > 100
    assert gif.shape[0] == 4 and gif.shape[1:3] == (60, 4 * 80)  # 8 frames / 2, 4 views side by side
    # the skeleton is drawn in green over the grey silhouettes
    assert ((gif[..., 1] > 150) & (gif[..., 0] < 100)).any()
    assert "wrote" in capsys.readouterr().out


def test_render_reports_bad_files(tmp_path, capsys):
    assert main(["render", str(tmp_path / "missing.npz")]) == 2
    assert "no sequence file" in capsys.readouterr().err
    no_cameras = tmp_path / "joints.npz"
    np.savez(no_cameras, fps=30.0, joints3d=np.zeros((2, 15, 3)))
    assert main(["render", str(no_cameras)]) == 2
    assert "neither silhouettes nor images" in capsys.readouterr().err


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_commands_refuse_to_write_over_their_inputs_before_any_work(tmp_path, capsys, monkeypatch):
    """``track T.npz --out T.npz`` used to replace the ground truth with estimates under the same
    keys, ``fit X.npz --out X.npz`` the training data with the model: refused, by any name of
    the same file, before anything is loaded; the inputs are left byte for byte."""
    seq = small_scene()[2]
    test = tmp_path / "walk.npz"
    save_sequence(test, seq)
    before = test.read_bytes()
    monkeypatch.chdir(tmp_path)
    (tmp_path / "link.npz").symlink_to(test)
    commands = [
        ["track", "walk.npz", "--model", "m.eqx", "--validation", "walk.npz", "--out", "walk.npz"],
        ["track", "walk.npz", "--model", "m.eqx", "--validation", "walk.npz", "--out", "./walk"],  # .npz is appended
        ["fit", "walk.npz", "--out", str(tmp_path / "link.npz")],
        ["scene", "link.npz", "walk"],
        ["convert", "walk.npz", "walk.npz"],
        ["render", "walk.npz", "--out", "walk", "--estimate", "walk_sheet.png"],
    ]
    for command in commands:
        assert main(command) == 2, command
        err = capsys.readouterr().err
        assert "is also an input of this command; refusing to write over it" in err, (command, err)
    assert test.read_bytes() == before
    # An output whose folder is a file, or that is a folder, is refused first too.
    assert main(["fit", "walk.npz", "--out", "walk.npz/model.eqx"]) == 2
    assert "exists and is not a folder" in capsys.readouterr().err
    assert main(["fit", "walk.npz", "--out", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err
    assert main(["experiment", "--train", "walk.npz", "--validation", "walk.npz", "--test", "walk.npz", "--out", "link.npz"]) == 2
    assert "is one of the input files" in capsys.readouterr().err


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_a_camera_that_cannot_see_the_person_is_refused_before_tracking():
    """One camera turned to face away, or moved so the body is outside its image: the filter
    would run on uniform weights in that view; refused, naming the camera, before any jit."""
    from jaxtrack.tracking import prepare_test

    seq = small_scene()[2]
    R, t = np.asarray(seq.camera_R).copy(), np.asarray(seq.camera_t).copy()
    turned = R.copy()
    turned[1] = np.diag([-1.0, 1.0, -1.0]) @ R[1]  # half a turn about the camera's y axis: the body is behind it
    t_turned = t.copy()
    t_turned[1] = np.diag([-1.0, 1.0, -1.0]) @ t[1]
    with pytest.raises(ValueError, match=r"camera 'C2' is behind walk's initial pose \(frame 0\)"):
        prepare_test(seq.replace(camera_R=turned, camera_t=t_turned), "walk", key=jax.random.key(0))
    shifted = t.copy()
    shifted[2, 0] += 50.0  # 50 m sideways in camera coordinates: in front, but outside the image
    with pytest.raises(ValueError, match=r"camera 'C3' does not see walk's initial pose \(frame 0\): all 15 points project"):
        prepare_test(seq.replace(camera_t=shifted), "walk", key=jax.random.key(0))


@pytest.mark.slow
def test_track_exits_non_zero_when_it_tracked_blind(tmp_path, capsys):
    """A tracker whose every particle scores -inf: the estimates are written, the degenerate
    fraction printed, and the command exits 3 with the reason (0 with --max-degenerate 1)."""
    seq = small_scene(num_frames=4)[2]
    test = tmp_path / "walk.npz"
    save_sequence(test, seq)
    plugin = tmp_path / "blind_tracker.py"
    plugin.write_text(
        "import jax.numpy as jnp\n"
        "from jaxtrack.dynamics import fit_pose_random_walk\n"
        "from jaxtrack.filters import SIR\n"
        "from jaxtrack.likelihood import as_likelihood\n"
        "from jaxtrack.tracking import TrackerRecipe, register_tracker\n"
        "blind = as_likelihood(lambda poses, observation: jnp.full(poses.shape[0], -jnp.inf, poses.dtype))\n"
        "register_tracker(TrackerRecipe('blind', 'Blind', 'every particle scores -inf',\n"
        "    fit=lambda key, motion: fit_pose_random_walk(list(motion.validation)),\n"
        "    build=lambda dynamics, likelihood, budget: SIR(dynamics, blind, 8)), replace=True)\n"
    )
    model = tmp_path / "m.eqx"
    assert main(["fit", str(test), "--out", str(model), "--steps", "1"]) == 0
    args = ["track", str(test), "--plugin", str(plugin), "--method", "blind", "--model", str(model), "--validation", str(test),
            "--budget", "8", "--out", str(tmp_path / "est")]
    assert main(args) == 3
    captured = capsys.readouterr()
    assert "degenerate frames 100 %" in captured.out and "tracked blind" in captured.err
    assert np.all(np.isfinite(load_sequence(tmp_path / "est.npz").pose))  # written, and finite
    assert main([*args, "--max-degenerate", "1"]) == 0


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_writes_are_atomic_and_name_the_file_written(tmp_path):
    from jaxtrack.io import atomic_write, check_output, output_file

    seq = small_scene()[2]
    assert save_sequence(tmp_path / "a", seq) == str(tmp_path / "a.npz")
    assert output_file("x", ".npz") == "x.npz" and output_file("x.npz", ".npz") == "x.npz"
    assert check_output(tmp_path / "new" / "b", suffix=".npz") == str(tmp_path / "new" / "b.npz")
    assert (tmp_path / "new").is_dir()
    target = tmp_path / "a.npz"
    before = target.read_bytes()
    with pytest.raises(RuntimeError, match="interrupted"):
        with atomic_write(target) as handle:
            handle.write(b"half a file")
            raise RuntimeError("interrupted")
    assert target.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.npz", "new"]  # no temporary left behind
    np.testing.assert_array_equal(load_sequence(target).silhouettes, seq.silhouettes)


@pytest.mark.slow
def test_demo_end_to_end(tmp_path):
    report = run_likelihood_demo(str(tmp_path / "demo"), num_frames=6, particles=64, refine_frames=1, verbose=False)
    assert load_sequence(report.scene_path).silhouettes.shape == (4, 6, 60, 80)
    assert iio.imread(report.contact_sheet_path).ndim == 3
    assert report.window is not None and report.window[0] < 60
    assert report.truth_wins_fraction >= 5 / 6
    assert report.refine_error_after_mm < report.refine_error_before_mm


@pytest.mark.slow
def test_experiment_demo(tmp_path):
    from jaxtrack.demo import run_demo

    results, paths = run_demo(str(tmp_path / "demo"), frames=8, budget=100, runs=1, verbose=False)
    assert set(results["sequences"]) == {"S1 walk", "S2 jog"}
    for per_method in results["sequences"].values():
        assert set(per_method) == {"sir", "apf", "mrpf", "gpapf", "latentpf", "glegbpf"}
        assert all(np.isfinite(v["error_mm_mean"]) for v in per_method.values())
    assert "| S1 walk |" in Path(paths["table"]).read_text()


@pytest.mark.slow  # moved to the slow suite for the default suite's 10 minutes
def test_track_saves_its_estimates_chunk_by_chunk(tmp_path, capsys, monkeypatch):
    """``track --chunk-frames K`` gives the result of one pass, writes the frames done so far to
    OUT.partial.npz after each chunk, and removes it once the whole output is written; an
    interrupted run leaves the partial file, a valid sequence of the frames tracked."""
    seq = small_scene(num_frames=4)[2]
    test = tmp_path / "walk.npz"
    save_sequence(test, seq)
    model = tmp_path / "m.eqx"
    assert main(["fit", str(test), "--out", str(model), "--steps", "1"]) == 0
    args = ["track", str(test), "--method", "sir", "--model", str(model), "--validation", str(test), "--budget", "16"]
    assert main([*args, "--chunk-frames", "0", "--out", str(tmp_path / "whole")]) == 0
    assert main([*args, "--chunk-frames", "2", "--out", str(tmp_path / "chunked")]) == 0
    out = capsys.readouterr().out
    assert "2/4 frames tracked" in out and "4/4 frames tracked" in out
    np.testing.assert_array_equal(load_sequence(tmp_path / "chunked.npz").pose, load_sequence(tmp_path / "whole.npz").pose)
    assert not (tmp_path / "chunked.partial.npz").exists()

    interrupt_the_second_chunk(monkeypatch)
    assert main([*args, "--chunk-frames", "2", "--out", str(tmp_path / "cut")]) == 130
    assert "interrupted" in capsys.readouterr().err
    partial = load_sequence(tmp_path / "cut.partial.npz")
    assert partial.num_frames == 2 and partial.silhouettes.shape[1] == 2
    np.testing.assert_array_equal(partial.pose, load_sequence(tmp_path / "whole.npz").pose[:2])
    assert not (tmp_path / "cut.npz").exists()


@pytest.mark.slow
def test_ctrl_c_during_chunked_tracking_stops_once_the_chunk_is_saved(tmp_path, capsys, monkeypatch):
    """A real SIGINT in the middle of the second chunk: the chunk finishes, its estimates are saved,
    and only then does ``track`` stop (status 130), with no XLA program running."""
    import signal
    import sys

    seq = small_scene(num_frames=6)[2]
    test = tmp_path / "walk.npz"
    save_sequence(test, seq)
    model = tmp_path / "m.eqx"
    assert main(["fit", str(test), "--out", str(model), "--steps", "1"]) == 0
    real_scan = sys.modules["jaxtrack.filters._run"]._scan
    calls = []

    def ctrl_c_in_the_second_chunk(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            os.kill(os.getpid(), signal.SIGINT)
        return real_scan(*a, **k)

    monkeypatch.setattr("jaxtrack.filters._run._scan", ctrl_c_in_the_second_chunk)
    args = ["track", str(test), "--method", "sir", "--model", str(model), "--validation", str(test), "--budget", "16",
            "--chunk-frames", "2", "--out", str(tmp_path / "cut")]
    capsys.readouterr()
    before = signal.getsignal(signal.SIGINT)  # Python's default; SIG_IGN where the suite runs as a background job
    assert main(args) == 130
    captured = capsys.readouterr()
    assert "stopping once this chunk is saved" in captured.err and "interrupted" in captured.err
    assert "4/6 frames tracked" in captured.out and "6/6" not in captured.out and len(calls) == 2
    assert load_sequence(tmp_path / "cut.partial.npz").num_frames == 4
    assert not (tmp_path / "cut.npz").exists()
    assert signal.getsignal(signal.SIGINT) is before  # the handler is put back


@pytest.mark.slow
def test_track_with_a_pose_residual(tmp_path, capsys):
    """``track --residual SCALE`` runs a latent tracker with the residual (with and without
    ``--no-ground-prior``); a tracker whose state is the pose refuses it with a clear message."""
    seq = small_scene(num_frames=4)[2]
    test = tmp_path / "walk.npz"
    save_sequence(test, seq)
    model = tmp_path / "gle.eqx"
    assert main(["fit", str(test), "--model", "tle", "--latent-dim", "2", "--out", str(model)]) == 0
    args = ["track", str(test), "--model", str(model), "--validation", str(test), "--budget", "16"]
    assert main([*args, "--method", "glegbpf", "--residual", "1", "--out", str(tmp_path / "est")]) == 0
    assert np.all(np.isfinite(load_sequence(tmp_path / "est.npz").pose))
    # The same key without the ground prior: the silhouettes alone weigh the particles.
    assert main([*args, "--method", "glegbpf", "--residual", "1", "--no-ground-prior", "--out", str(tmp_path / "bare")]) == 0
    bare = load_sequence(tmp_path / "bare.npz").pose
    assert np.all(np.isfinite(bare)) and not np.array_equal(bare, load_sequence(tmp_path / "est.npz").pose)
    capsys.readouterr()
    assert main([*args, "--method", "sir", "--residual", "1", "--out", str(tmp_path / "sir")]) == 2
    assert "SIR takes no pose residual" in capsys.readouterr().err


@pytest.mark.slow
def test_a_second_call_loads_its_compiled_trackers_from_the_cache(tmp_path):
    """The command line keeps compiled programs in JAXTRACK_CACHE_DIR: the first ``track`` fills
    it, a second identical call adds nothing (it loaded them), and ``--no-compile-cache`` or
    JAXTRACK_CACHE_DIR=off writes none."""
    import os
    import subprocess
    import sys

    seq = small_scene(num_frames=4)[2]
    test = tmp_path / "walk.npz"
    save_sequence(test, seq)
    model = tmp_path / "m.eqx"
    assert main(["fit", str(test), "--out", str(model), "--steps", "1"]) == 0
    cache = tmp_path / "cache"

    def run(*extra, env_cache=str(cache)):
        argv = [*extra, "track", str(test), "--method", "sir", "--model", str(model), "--validation", str(test), "--budget", "16",
                "--out", str(tmp_path / "est")]
        code = "import sys; from jaxtrack.cli import main; sys.exit(main(sys.argv[1:]))"
        env = {k: v for k, v in os.environ.items() if k != "JAX_COMPILATION_CACHE_DIR"}  # the tests' own cache (conftest.py)
        done = subprocess.run([sys.executable, "-c", code, *argv], env={**env, "JAXTRACK_CACHE_DIR": env_cache},
                              capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
        return sorted(p.name for p in cache.rglob("*") if p.is_file()) if cache.exists() else []

    first = run()
    assert first, "nothing was cached"
    assert run() == first
    for path in [p for p in cache.rglob("*") if p.is_file()]:
        path.unlink()
    assert run("--no-compile-cache") == [] and run(env_cache="off") == []


def test_outputs_follow_the_umask_and_unwritable_folders_are_refused_first(tmp_path):
    import stat

    from jaxtrack.io import OutputPathError, atomic_write, check_output

    old = os.umask(0o027)
    try:
        with atomic_write(tmp_path / "a.bin") as handle:
            handle.write(b"x")
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.stat(tmp_path / "a.bin").st_mode) == 0o640
    with pytest.raises(OutputPathError, match="cannot write files in the output folder"):
        check_output("/proc/jaxtrack-test.npz")
