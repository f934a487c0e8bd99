"""The HumanEva-style experiment and `jaxtrack track`: inputs checked before anything runs,
and a small end-to-end run (slow)."""

import dataclasses
import json

import jax
import numpy as np
import pytest

from jaxtrack.experiment import ExperimentConfig, run_experiment
from jaxtrack.tracking import check_test_sequence, sequence_poses, track_sequence

from helpers import small_experiment_sequences


@pytest.fixture(scope="module")
def sequences():
    return small_experiment_sequences()


def test_bad_experiment_inputs(sequences):
    train, validation, test = sequences
    with pytest.raises(ValueError, match="cannot be split into 3 equal annealing layers for APF"):
        ExperimentConfig(budget=500, layers=3, methods=("sir", "apf"))
    with pytest.raises(ValueError, match=r"unknown tracker 'pf'; registered trackers: sir, apf, mrpf"):
        ExperimentConfig(methods=("pf",))
    with pytest.raises(ValueError, match="lists a tracker twice"):
        ExperimentConfig(methods=("sir", "sir"))
    with pytest.raises(ValueError, match="GPAPF needs at least 2 layers"):
        ExperimentConfig(methods=("gpapf",), budget=100, layers=1)
    assert ExperimentConfig(methods=("mrpf",), manifold="gpdm").manifold_kinds == ("gpdm",)  # GPDM latent proposal
    assert ExperimentConfig(methods=("mrpf", "gpapf"), manifold="bc-gpdm").manifold_kinds == ("bc-gpdm",)
    with pytest.raises(ValueError, match="manifold must be one of"):
        ExperimentConfig(manifold="isomap")
    with pytest.raises(ValueError, match="fit_optimiser must be one of"):
        ExperimentConfig(fit_optimiser="adam")
    # Each manifold tracker runs on its paper's manifold unless one is named for all.
    assert ExperimentConfig().manifold_kinds == ("gpdm", "gle")
    assert ExperimentConfig(methods=("mrpf", "mrpf-alg1", "gpapf")).manifold_kinds == ("gpdm", "bc-gplvm")
    # A named manifold is every tracker's of its family (GP or Laplacian Eigenmap); the other family keeps its own.
    assert ExperimentConfig(manifold="bc-gplvm").manifold_kinds == ("bc-gplvm", "gle")
    assert ExperimentConfig(manifold="tle").manifold_kinds == ("gpdm", "tle")
    assert ExperimentConfig(methods=("glegbpf", "sir")).manifold_kinds == ("gle",)
    assert ExperimentConfig(methods=("sir", "apf")).manifold_kinds == ()
    assert [ExperimentConfig().manifold_of(m) for m in ("sir", "mrpf", "gpapf", "latentpf", "glegbpf")] == [
        None, "gpdm", "gpdm", "gpdm", "gle"]
    # Each tracker's manifold has its own latent dimension (MRPF 2 as in 000, GPAPF and LatentPF 3) unless one is
    # named for all; one manifold is fitted per (kind, dimension).
    assert ExperimentConfig().manifold_specs == (("gpdm", 2), ("gpdm", 3), ("gle", 3))
    assert [ExperimentConfig().latent_dim_of(m) for m in ("sir", "mrpf", "gpapf", "latentpf", "glegbpf")] == [None, 2, 3, 3, 3]
    assert ExperimentConfig(methods=("mrpf-alg1",)).manifold_specs == (("bc-gplvm", 2),)
    assert ExperimentConfig(latent_dim=2).manifold_specs == (("gpdm", 2), ("gle", 2))
    assert ExperimentConfig(methods=("gpapf", "sir")).manifold_specs == (("gpdm", 3),)
    # Each tracker carries its own velocity default (the one-layer manifold trackers) unless one is named for all.
    assert [ExperimentConfig().velocity_of(m) for m in ("sir", "apf", "mrpf", "gpapf", "latentpf")] == [False, False, True, False, True]
    assert all(ExperimentConfig(velocity=True).velocity_of(m) for m in ("sir", "gpapf"))
    assert not any(ExperimentConfig(velocity=False).velocity_of(m) for m in ("mrpf", "latentpf"))
    with pytest.raises(ValueError, match="needs silhouettes and cameras"):
        check_test_sequence(train[0], "walk.npz")
    with pytest.raises(ValueError, match="needs silhouettes, which the file lacks"):
        check_test_sequence(test[0].replace(silhouettes=None), "walk.npz")
    renamed = test[0].replace(joint_names=np.array(["root"] + [str(n) for n in test[0].joint_names[1:]]))
    with pytest.raises(ValueError, match="joint_names"):
        sequence_poses(renamed, "walk.npz", key=jax.random.key(0))
    with pytest.raises(ValueError, match="needs silhouettes and cameras"):
        run_experiment(train, validation, train[:1], ExperimentConfig(runs=1), progress=False)


@pytest.mark.slow  # 9 s or more on 2 cores with an empty compilation cache (docs/testing.md, 2026-11-27)
def test_bad_inputs_fail_before_any_fitting(sequences, monkeypatch):
    """Frame rates that differ, and a second test file whose silhouettes are empty, used to be
    found after minutes of fitting and tracking (or never): now before the first fit."""
    train, validation, test = sequences

    def no_fitting(*args, **kwargs):
        raise AssertionError("fitting started before the inputs were checked")

    for name in ("fit_manifold", "fit_tracker"):  # the experiment's own references to them
        monkeypatch.setattr(f"jaxtrack.experiment._run.{name}", no_fitting)
    config = ExperimentConfig(runs=1, methods=("sir", "mrpf"))
    slow = validation[0].replace(fps=validation[0].fps / 2)
    with pytest.raises(ValueError, match=r"validation0 is at \d+ Hz but train0 at \d+ Hz"):
        run_experiment(train, [slow], test, config, progress=False)
    empty = test[0].replace(silhouettes=np.zeros_like(test[0].silhouettes))
    with pytest.raises(ValueError, match="test1"):
        run_experiment(train, validation, [test[0], empty], config, progress=False)


def test_track_refuses_a_model_from_another_skeleton(sequences):
    from jaxtrack.manifold import make_bc_gplvm

    train, validation, test = sequences
    with jax.enable_x64(True):
        model = make_bc_gplvm(train[0].pose[:, 6:], 2)
    header = {"extra": {"pose_layout": ["hip_a", "hip_b"] + [str(n) for n in train[0].pose_layout[8:]]}, "sequence_starts": [0, 30]}
    with pytest.raises(ValueError, match="fitted on another skeleton"):
        track_sequence(test[0], model, header, "mrpf", validation[0])


def test_experiment_starts_automatically_without_the_truth(sequences):
    """``start="auto"``: every tracker starts from the pose found in the first frame's images on
    the first manifold the trackers run on (no ground truth read: changing frame 0's truth
    changes the start's error, never the start), the root at the validation motion's mean height;
    with no tracker on a manifold, a BC-GPLVM is fitted for the start alone."""
    from jaxtrack.experiment import fit_methods, new_results, prepare_inputs, prepare_scenes, start_manifold
    from jaxtrack.tracking import leg_length

    train, validation, test = sequences
    config = ExperimentConfig(methods=("sir", "latentpf"), budget=40, runs=1, fit_steps=5, frames=3, start="auto")
    bent = test[0].pose.copy()
    bent[0, list(test[0].pose_layout).index("root_yaw")] += 0.5  # frame 0's truth turned by 0.5 rad
    scenes = []
    for seq in (test[0], test[0].replace(pose=bent, joints3d=None)):
        results = new_results(config)
        inputs = prepare_inputs(train, validation, [seq], config, results, say=lambda *a: None)
        assert inputs.scenes == []  # built after the fits: the start searches a fitted manifold
        fit_methods(inputs, config, results, progress=False, say=lambda *a: None)
        prepare_scenes(inputs, config, results, start_model=start_manifold(inputs, config, results, say=lambda *a: None),
                       say=lambda *a: None)
        scenes.append(inputs.scenes[0])
    assert results["start"] == {"kind": "auto", "manifold": "gpdm-3d", "root_height_m": pytest.approx(
        float(np.mean(validation[0].pose[:, list(validation[0].pose_layout).index("root_z")]))),
        "root_height_legs_m": pytest.approx(leg_length(validation[0].body()))}
    found, moved = scenes
    np.testing.assert_array_equal(np.asarray(found.initial_pose), np.asarray(moved.initial_pose))
    assert 5.0 < found.start_error_mm < 150.0 and abs(moved.start_error_mm - found.start_error_mm) > 5.0
    z = list(test[0].pose_layout).index("root_z")
    assert float(found.initial_pose[z]) == pytest.approx(  # the motion's height on the test person's legs
        results["start"]["root_height_m"] * leg_length(found.body) / results["start"]["root_height_legs_m"], abs=1e-5)


def test_the_stages_run_by_hand_give_the_experiment(sequences):
    """``new_results`` then ``prepare_inputs``, ``fit_methods`` and ``track_methods``, as a caller
    that keeps the prepared scenes runs them: the same errors as ``run_experiment`` for the same
    config (the same keys), and the scene the runs tracked."""
    from jaxtrack.experiment import fit_methods, new_results, prepare_inputs, track_methods

    train, validation, test = sequences
    config = ExperimentConfig(methods=("sir",), budget=40, runs=2, fit_steps=5, frames=3)
    whole = run_experiment(train, validation, test, config, names={"test": ["walk"]}, progress=False)
    results = new_results(config)
    assert results["config"] == whole["config"] and results["sequences"] == {} and not results["complete"]
    inputs = prepare_inputs(train, validation, test, config, results, names={"test": ["walk"]}, say=lambda *a: None)
    track_methods(inputs, fit_methods(inputs, config, results, progress=False, say=lambda *a: None), config, results,
                  say=lambda *a: None)
    np.testing.assert_array_equal(results["sequences"]["walk"]["sir"]["error_mm_per_run"],
                                  whole["sequences"]["walk"]["sir"]["error_mm_per_run"])
    assert inputs.scenes[0].num_frames == 3 and inputs.scenes[0].start_error_mm < 5.0


def test_an_automatic_start_without_a_manifold_tracker_fits_one(sequences):
    """SIR alone with ``start="auto"``: a BC-GPLVM fitted for the start; ``start="truth"``
    (the default) says so in the results."""
    train, validation, test = sequences
    config = ExperimentConfig(methods=("sir",), budget=40, runs=1, fit_steps=5, frames=3, start="auto")
    run = run_experiment(train, validation, test, config, progress=False)
    assert run["start"]["manifold"].startswith("bc-gplvm-") and run["sequences"]["test0"]["sir"]["start_error_mm"] > 5.0
    truth = run_experiment(train, validation, test, dataclasses.replace(config, start="truth"), progress=False)
    assert truth["start"] == {"kind": "truth"} and truth["sequences"]["test0"]["sir"]["start_error_mm"] < 5.0


@pytest.mark.slow
def test_experiment_end_to_end(sequences, tmp_path):
    train, validation, test = sequences
    config = ExperimentConfig(budget=50, layers=5, runs=2, fit_steps=30, frames=6)
    results = run_experiment(train, validation, test, config, out_dir=str(tmp_path), names={"test": ["walk.npz"]}, progress=False)
    saved = json.loads((tmp_path / "results.json").read_text())
    per_method = saved["sequences"]["walk.npz"]
    assert set(per_method) == {"sir", "apf", "mrpf", "gpapf", "latentpf", "glegbpf"}
    for values in per_method.values():
        assert np.isfinite(values["error_mm_mean"]) and values["error_mm_mean"] < 400
        assert len(values["per_frame_error_mm"]) == 6 and len(values["error_mm_per_run"]) == 2
        assert set(values["per_group_error_mm"]) == {"torso", "head", "arms", "legs"}
    table = (tmp_path / "table.md").read_text()
    assert table.startswith("| Sequence | SIR | APF | MRPF | GPAPF | LatentPF | GLE-GbPF |") and "walk.npz" in table
    assert (tmp_path / "error_curves.png").stat().st_size > 1000
    assert list(tmp_path.glob("walk_*.gif"))
    # By default every manifold tracker runs on one GPDM, and the one-layer ones carry a velocity.
    assert results["manifold"]["class"] == "GPDM"
    assert {label: (m["class"], m["latent_dim"]) for label, m in results["manifolds"].items()} == {
        "gpdm-2d": ("GPDM", 2), "gpdm-3d": ("GPDM", 3), "gle-3d": ("SpectralEmbedding", 3)}
    assert results["dynamics"]["gpapf"]["0.class"] == "GPDMLatentDynamics"
    assert set(results["velocity"]) == {"mrpf", "latentpf", "glegbpf"} and results["velocity"]["mrpf"]["entries"] == 6
    # The ground prior is on: its clearance is the validation walk's stance ankle (8 cm) or the
    # first test frame's lowest ankle, whichever is lower.
    ground = saved["ground_prior"]["walk.npz"]
    assert ground["validation_clearance_m"] == pytest.approx(0.08, abs=0.005)
    assert ground["clearance_m"] <= ground["validation_clearance_m"] + 1e-6 and ground["tolerance_m"] == pytest.approx(0.01)


@pytest.mark.slow
def test_experiment_reports_the_pose_residual(sequences, tmp_path):
    """``residual``: the latent trackers carry it (inside their velocity) and the results say its
    scale and fitted steps; SIR, whose state is the pose, does not."""
    train, validation, test = sequences
    config = ExperimentConfig(methods=("sir", "glegbpf"), budget=40, runs=1, frames=3, residual=1.0)
    results = run_experiment(train, validation, test, config, out_dir=str(tmp_path), names={"test": ["walk.npz"]},
                             progress=False, animations=False)
    assert set(results["residual"]) == {"glegbpf"} and results["residual"]["glegbpf"]["scale"] == 1.0
    assert len(results["residual"]["glegbpf"]["step_rad"]) == 26 and min(results["residual"]["glegbpf"]["step_rad"]) > 0
    assert all(np.isfinite(v["error_mm_mean"]) for v in results["sequences"]["walk.npz"].values())


@pytest.mark.slow
def test_experiment_calibrates_the_body_first(sequences, tmp_path):
    """``calibrate_shape``: the radii are fitted on frame 0 of each test sequence, reported, and
    the calibrated body lowers the silhouette cost there."""
    train, validation, test = sequences
    config = ExperimentConfig(methods=("sir",), budget=40, runs=1, frames=3, calibrate_shape=True)
    results = run_experiment(train, validation, test, config, out_dir=str(tmp_path), names={"test": ["walk.npz"]},
                             progress=False, animations=False)
    report = results["shape_calibration"]["walk.npz"]
    assert len(report["radii_after_m"]) == len(report["capsules"]) == 15
    assert report["cost_after"] <= report["cost_before"]
    assert json.loads((tmp_path / "results.json").read_text())["config"]["calibrate_shape"] is True


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_experiment_saves_each_tracker_as_it_goes(sequences, tmp_path, monkeypatch):
    """An experiment that fails part-way keeps, in results.json and table.md, every tracker that
    finished (``complete`` false); the table marks the ones not run."""
    from jaxtrack import tracking

    train, validation, test = sequences
    runs = []
    real_track = tracking.track

    def failing_track(tracker, key, scene, **kwargs):
        runs.append(type(tracker.dynamics).__name__)
        if len(runs) > 1:
            raise RuntimeError("the machine went away")
        return real_track(tracker, key, scene, **kwargs)

    monkeypatch.setattr("jaxtrack.experiment._run.track", failing_track)  # the experiment's own reference
    config = ExperimentConfig(methods=("sir", "apf"), budget=20, layers=2, runs=1, fit_steps=5, frames=3)
    with pytest.raises(RuntimeError, match="went away"):
        run_experiment(train, validation, test, config, out_dir=str(tmp_path), names={"test": ["walk.npz"]}, progress=False)
    saved = json.loads((tmp_path / "results.json").read_text())
    assert saved["complete"] is False and list(saved["sequences"]["walk.npz"]) == ["sir"]
    assert np.isfinite(saved["sequences"]["walk.npz"]["sir"]["error_mm_mean"])
    assert "| walk.npz |" in (tmp_path / "table.md").read_text() and "not run" in (tmp_path / "table.md").read_text()
    assert not list(tmp_path.glob(".*.part"))


@pytest.mark.slow
def test_batched_runs_equal_separate_runs(sequences):
    """``batch_runs`` tracks a tracker's runs in one vmapped call: the same runs as one call each
    (float32 tracking: equal to rounding), so the same table."""
    train, validation, test = sequences
    separate, batched = (run_experiment(train, validation, test, ExperimentConfig(methods=("sir", "gpapf"), budget=40, layers=2, runs=3,
                                                                                   fit_steps=5, frames=4, batch_runs=batch),
                                        names={"test": ["walk"]}, progress=False) for batch in (False, True))
    for method in ("sir", "gpapf"):
        a, b = separate["sequences"]["walk"][method], batched["sequences"]["walk"][method]
        np.testing.assert_allclose(b["error_mm_per_run"], a["error_mm_per_run"], rtol=1e-3, atol=0.05)
        np.testing.assert_allclose(b["per_frame_error_mm_per_run"], a["per_frame_error_mm_per_run"], atol=0.1)
        assert a["compile_s"] is not None and b["compile_s"] is None
        np.testing.assert_allclose(separate["estimates"]["walk"][method][1], batched["estimates"]["walk"][method][1], atol=1e-4)


def test_error_curves_are_drawn_when_every_method_was_refused(tmp_path):
    """A test sequence left without any result (every method refused) still gets its panel."""
    from jaxtrack.experiment import plot_error_curves

    results = {"sequences": {"walk": {}, "jog": {"sir": {"per_frame_error_mm": [10.0, 12.0, 11.0]}}}}
    path = plot_error_curves(results, str(tmp_path / "curves.png"))
    assert (tmp_path / "curves.png").stat().st_size > 1000 and path.endswith("curves.png")


def test_the_experiment_warns_of_a_file_whose_floor_is_tilted(sequences, capsys):
    """The ground prior's floor is level: a file whose joints climb a tilted floor is named in
    ``results["warnings"]`` (with what to do), a level one is not."""
    from jaxtrack.experiment import prepare_inputs
    from jaxtrack.io import fit_floor, levelling_rotation

    train, validation, test = sequences
    config = ExperimentConfig(methods=("sir",), budget=40, runs=1, fit_steps=5, frames=3)
    walk = train[0]
    floor = fit_floor(walk.joints3d, list(walk.joint_names))
    assert floor.seen and not floor.worth_levelling
    climbing = (np.asarray(walk.joints3d) - floor.pivot) @ levelling_rotation([0.0, 0.02]) + floor.pivot  # 1.15 degrees
    for seq, warned in ((walk, False), (walk.replace(joints3d=climbing), True)):
        results = {k: {} for k in ("ik_residual_mm", "likelihoods", "bodies", "ground_prior", "manifolds", "dynamics")}
        results.update(refused={}, manifold=None, start=None)
        prepare_inputs([seq, train[1]], validation, test, config, results, names={"train": ["climb.npz", "jog.npz"]},
                       say=lambda *a: None)
        tilted = [w for w in results.get("warnings", []) if "floor" in w]
        assert bool(tilted) == warned
    assert tilted[0].startswith("climb.npz: the floor tilts") and "--level-floor" in tilted[0]
    assert "warning: climb.npz: the floor tilts" in capsys.readouterr().out
