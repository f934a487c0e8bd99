from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.demo import run_likelihood_demo
from jaxtrack.io import load_sequence, save_sequence

from helpers import small_scene


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
        assert set(per_method) == {"sir", "apf", "mrpf", "gpapf", "latentpf"}
        assert all(np.isfinite(v["error_mm_mean"]) for v in per_method.values())
    assert "| S1 walk |" in Path(paths["table"]).read_text()
