"""Leave-one-subject-out protocols (issue #46): the folds never show a tracker its test
subject's motion, the table's verdicts are computed from the rows, GPmat's trials are read
exactly, and a protocol runs end to end and resumes."""

import dataclasses
import json
import os

import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.errors import ConfigurationError
from jaxtrack.experiment import (
    PROTOCOLS,
    ExperimentConfig,
    ProtocolSubject,
    SubjectProtocol,
    Take,
    centre_subjects,
    drift_ratio,
    fold_takes,
    fold_test_scene,
    protocol_table,
    run_protocol,
)


@pytest.mark.parametrize("name", sorted(PROTOCOLS))
def test_cross_folds_never_train_on_the_test_subject(name):
    protocol = PROTOCOLS[name]
    subjects = [s.name for s in protocol.subjects]
    folds = protocol.folds()
    assert [(f.mode, f.subject) for f in folds] == [(m, s) for s in subjects for m in ("cross", "within")]
    test_takes = {s.test.name for s in protocol.subjects}
    for fold in folds:
        assert fold.test.subject == fold.subject and fold.test.name not in {t.name for t in fold.train + fold.validation}
        assert not test_takes & {t.name for t in fold.train + fold.validation}  # no subject's test take is ever learnt from
        if fold.mode == "cross":
            assert {t.subject for t in fold.train + fold.validation} == set(subjects) - {fold.subject}
        else:
            assert {t.subject for t in fold.train + fold.validation} == {fold.subject}
        assert fold.train and fold.validation


def test_a_subject_without_a_validation_take_says_so():
    def take(subject, name):
        return Take(subject, name, f"{name}.amc", 120.0, "x.asf")

    protocol = SubjectProtocol("p", "two people", (
        ProtocolSubject("a", take("a", "a1"), (take("a", "a2"),)),
        ProtocolSubject("b", take("b", "b1"), (take("b", "b2"), take("b", "b3")), take("b", "b4"))))
    within = protocol.fold("within", "a")
    assert [t.name for t in within.validation] == ["a2"] and "no third take" in within.note
    cross = protocol.fold("cross", "b")  # the only other subject has no validation take: its training take serves
    assert [t.name for t in cross.train] == ["a2"] and [t.name for t in cross.validation] == ["a2"] and cross.note
    assert [t.name for t in protocol.fold("cross", "a").validation] == ["b4"]
    with pytest.raises(ConfigurationError, match="no subject 'c'"):
        protocol.fold("cross", "c")
    with pytest.raises(ConfigurationError, match="fold mode"):
        protocol.fold("sideways", "a")
    nested = PROTOCOLS["walk-loso"].without("cmu07")
    assert [s.name for s in nested.subjects] == ["cmu16", "cmu35"] and nested.name == "walk-loso-without-cmu07"
    assert not any(t.subject == "cmu07" for f in nested.folds() for t in (*f.train, *f.validation, f.test))
    with pytest.raises(ConfigurationError, match="keeps 1 subject"):
        protocol.without("a")
    with pytest.raises(ConfigurationError, match="take name is used twice"):
        SubjectProtocol("q", "", (ProtocolSubject("a", take("a", "x"), (take("a", "y"),)),
                                  ProtocolSubject("b", take("b", "x"), (take("b", "z"),))))


@pytest.mark.slow  # converts two takes: 15 s or more on 2 cores with an empty compilation cache
@pytest.mark.shared_data
def test_the_nearest_training_pose_floor(shared_data, tmp_path):
    from jaxtrack.experiment import convert_takes, nearest_pose_floor_mm

    jog = PROTOCOLS["jog-loso"]
    bd, dg = jog.subject("hdm05-bd"), jog.subject("hdm05-dg")
    sequences = convert_takes([bd.test, dg.test], shared_data, str(tmp_path), say=lambda *a: None)
    own, other = sequences[bd.test.name], sequences[dg.test.name]
    assert nearest_pose_floor_mm([own], own) == pytest.approx(0.0, abs=1e-9)  # every pose is in the training set
    crossed = nearest_pose_floor_mm([other], own)
    assert 10.0 < crossed < 200.0
    # Adding the test take's own frames can only bring the nearest pose closer.
    assert nearest_pose_floor_mm([other, own.cropped(40)], own) < crossed


def test_centring_takes_each_training_subject_s_posture_out():
    """Each training subject's takes (training and validation) end at the pooled mean posture,
    by one shift per subject; the gait about it, the roots and a single-subject fold are kept."""
    from jaxtrack.body import GLOBAL_DOFS

    from helpers import small_experiment_sequences

    walk, jog = small_experiment_sequences()[0]
    validation = small_experiment_sequences()[1][0]
    takes = {name: Take(subject, name, f"{name}.amc", 120.0) for name, subject in (("a1", "a"), ("a2", "a"), ("b1", "b"))}
    # subject b stands 0.1 rad off in every joint angle: a posture of its own
    b_pose = np.asarray(jog.pose, np.float64).copy()
    b_pose[:, GLOBAL_DOFS:] += 0.1
    b = jog.replace(pose=b_pose, joints3d=None)
    fold = SubjectProtocol("toy", "", (ProtocolSubject("a", takes["a1"], (takes["a1"], takes["a2"])),
                                       ProtocolSubject("b", takes["b1"], (takes["b1"],)),
                                       ProtocolSubject("c", Take("c", "c1", "c1.amc", 120.0), (Take("c", "c2", "c2.amc", 120.0),)))
                           ).fold("cross", "c")
    assert [t.name for t in fold.train] == ["a1", "a2", "b1"] and [t.name for t in fold.validation] == ["a1", "b1"]
    train, val = centre_subjects(fold, [walk, walk, b], [validation, b])

    def angles(x):
        return np.asarray(x.pose, np.float64)[:, GLOBAL_DOFS:]

    pooled = np.concatenate([angles(walk), angles(walk), angles(b)]).mean(0)
    for sequence in train:  # each take here is the whole of its subject's posture
        np.testing.assert_allclose(angles(sequence).mean(0), pooled, atol=1e-12)
    np.testing.assert_allclose(angles(train[0]) - angles(walk), np.broadcast_to(pooled - angles(walk).mean(0), angles(walk).shape),
                               atol=1e-12)
    a_shift = (angles(train[0]) - angles(walk))[0]
    np.testing.assert_allclose(angles(val[0]) - angles(validation), np.broadcast_to(a_shift, angles(validation).shape), atol=1e-12)
    np.testing.assert_allclose(angles(val[1]), angles(train[2]), atol=1e-12)  # b's shift
    for before, after in zip([walk, walk, b, validation, b], [*train, *val]):
        np.testing.assert_array_equal(np.asarray(after.pose)[:, :GLOBAL_DOFS], np.asarray(before.pose)[:, :GLOBAL_DOFS])
        assert after.joints3d is None
    within = SubjectProtocol("toy", "", (ProtocolSubject("a", takes["a1"], (takes["a2"],)),
                                         ProtocolSubject("b", takes["b1"], (Take("b", "b2", "b2.amc", 120.0),)))).fold("within", "a")
    kept, _ = centre_subjects(within, [walk], [walk])
    np.testing.assert_allclose(np.asarray(kept[0].pose), np.asarray(walk.pose), atol=1e-12)


def test_a_fold_s_takes_and_scene_are_the_protocol_s():
    """``fold_takes``: the training takes cut to the protocol's training frames, the validation
    takes whole, centred on request as ``centre_subjects`` centres them. ``fold_test_scene``: the
    test take's first ``test_frames`` frames, drawn with the key of its place among the protocol's
    takes, so a subject's cross and within folds see the same silhouettes and another subject's
    test take other ones."""
    from helpers import small_experiment_sequences

    (walk, jog), (validation,), _ = small_experiment_sequences()
    takes = {name: Take(subject, name, f"{name}.amc", 120.0) for name, subject in (("a1", "a"), ("a2", "a"), ("a3", "a"),
                                                                                   ("b1", "b"), ("b2", "b"))}
    sequences = {"a1": walk, "a2": jog, "a3": validation, "b1": jog, "b2": walk}
    protocol = SubjectProtocol("toy", "", (ProtocolSubject("a", takes["a1"], (takes["a2"],), takes["a3"]),
                                           ProtocolSubject("b", takes["b1"], (takes["b2"],))), test_frames=3, train_frames=20)
    cross = protocol.fold("cross", "a")
    assert cross.names == {"train": ["b2"], "validation": ["b2"], "test": ["a1"]}
    train, val = fold_takes(protocol, cross, sequences)
    assert [x.num_frames for x in train] == [20] and val[0].num_frames == walk.num_frames == 30
    np.testing.assert_array_equal(np.asarray(train[0].pose), np.asarray(walk.pose)[:20])
    within = protocol.fold("within", "a")
    train, val = fold_takes(protocol, within, sequences, centre=True)
    expected = centre_subjects(within, [jog.cropped(20)], [validation])
    np.testing.assert_array_equal(np.asarray(train[0].pose), np.asarray(expected[0][0].pose))
    np.testing.assert_array_equal(np.asarray(val[0].pose), np.asarray(expected[1][0].pose))
    options = {"views": 2, "size": (32, 24)}
    a_cross, a_within = (fold_test_scene(protocol, fold, sequences, **options) for fold in (cross, within))
    b_cross = fold_test_scene(protocol, protocol.fold("cross", "b"), sequences, **options)
    assert a_cross.num_frames == 3 and a_cross.capsule_radii is None  # the radii withheld from the tracker
    # the test take's first frames (the scene moves the walk's ground track into the rig's view)
    np.testing.assert_allclose(np.asarray(a_cross.pose)[:, 2:], np.asarray(walk.pose)[:3, 2:], atol=1e-6)
    np.testing.assert_array_equal(np.asarray(a_cross.silhouettes), np.asarray(a_within.silhouettes))
    assert not np.array_equal(np.asarray(a_cross.silhouettes), np.asarray(b_cross.silhouettes))
    other_seed = fold_test_scene(protocol, cross, sequences, seed=1, **options)
    assert not np.array_equal(np.asarray(a_cross.silhouettes), np.asarray(other_seed.silhouettes))  # the noise is the seed's


def _row(mode, subject, errors, budget=500):
    methods = {m: {"error_mm_mean": e, "error_mm_std": 1.0, "last_over_first_quarter": d} for m, (e, d) in errors.items()}
    return {"mode": mode, "subject": subject, "budget": budget, "runs": 5, "views": 3, "size": [80, 60], "renderer": "solid",
            "methods": methods, "refused": {}, "start_error_mm": 0.3}


def test_a_protocol_refuses_an_azimuth_per_camera_of_the_wrong_count(tmp_path):
    config = ExperimentConfig(methods=("sir",), runs=1)
    with pytest.raises(ConfigurationError, match="azimuth gives 2 directions for 3 cameras"):
        run_protocol(PROTOCOLS["jog-loso"], str(tmp_path / "nowhere"), str(tmp_path / "out"), config, views=3,
                     azimuth=[0.0, 90.0])
    assert not (tmp_path / "out").exists()


def test_the_table_verdicts_are_computed_from_the_rows():
    rows = [
        _row("cross", "a", {"sir": (100, 1.0), "apf": (90, 1.0), "mrpf": (60, 1.0), "glegbpf": (80, 1.0)}),
        _row("within", "a", {"sir": (95, 1.0), "apf": (85, 1.0), "mrpf": (40, 1.0), "glegbpf": (50, 1.0)}),
        _row("cross", "b", {"sir": (100, 1.0), "apf": (70, 1.0), "mrpf": (75, 1.0), "glegbpf": (72, 1.4)}),
        _row("within", "b", {"sir": (100, 1.0), "apf": (70, 1.0), "mrpf": (50, 1.0), "glegbpf": (60, 1.0)}),
    ]
    table = protocol_table(rows, title="t")
    assert "| a (b500) | others | 0.3 | - | 100.0 (1.0) d1.00 |" in table
    assert "GLE-GbPF beats SIR and APF on 1 of 2 left-out subjects (a)" in table
    assert "the best manifold tracker beats SIR and APF on 1 of 2 left-out subjects" in table
    # a: the best manifold tracker across people is MRPF, 60 mm, 1.50x its own 40 mm
    assert ("a: cross / within: sir 1.05, apf 1.06, mrpf 1.50, glegbpf 1.60; best manifold tracker across people mrpf 60.0 mm, "
            "1.50x its within-subject error (1.50x the best within-subject one, mrpf 40.0 mm)") in table
    # b: GLE-GbPF is the best across people (72 mm), MRPF within (50 mm): 72 / 60 and 72 / 50
    assert "best manifold tracker across people glegbpf 72.0 mm, 1.20x its within-subject error (1.44x the best" in table
    assert "drift over 1.3: b cross glegbpf 1.40" in table
    assert drift_ratio([1, 1, 1, 1, 2, 2, 2, 3]) == pytest.approx(2.5)  # last two frames over the first two
    assert "3 views, 80x60" in table  # rows from before the azimuth was recorded: the default rig's 45 degrees
    turned = protocol_table([dict(r, azimuth=0.0) for r in rows], title="t")
    assert "3 views (the first at 0 degrees), 80x60" in turned
    listed = protocol_table([dict(r, azimuth=[45.0, 135.0, 225.0]) for r in rows], title="t")
    assert "3 views (at 45, 135, 225 degrees), 80x60" in listed
    assert "posture taken out" not in table
    assert "5 runs, each training subject's posture taken out; mean" in protocol_table([dict(r, centre_subjects=True) for r in rows])
    assert "no ground truth" not in table
    assert "5 runs, the start found from the first frame's silhouettes" in protocol_table([dict(r, start="auto") for r in rows])
    assert "5 runs, each take levelled onto its floor; mean" in protocol_table([dict(r, level_floor=True) for r in rows])


@pytest.mark.shared_data
def test_gpmat_trials_are_every_fourth_frame_of_the_raw_take(shared_data):
    from jaxtrack.io import load_asf_amc, read_gpmat_trials

    cmu = os.path.join(shared_data, "cmu35")
    trials = read_gpmat_trials(os.path.join(cmu, "cmu35WalkJog.mat"), os.path.join(cmu, "35.asf"), ["35_01", "35_18"])
    raw = load_asf_amc(os.path.join(cmu, "35.asf"), os.path.join(cmu, "35_01.amc"), fps=120.0)
    first = trials["35_01"]
    assert first.fps == 30.0 and trials["35_18"].num_frames == 44
    np.testing.assert_allclose(first.positions, raw.positions[: 4 * first.num_frames : 4], atol=1e-6)
    with pytest.raises(ValueError, match="holds no trial 35_99"):
        read_gpmat_trials(os.path.join(cmu, "cmu35WalkJog.mat"), os.path.join(cmu, "35.asf"), ["35_99"])


def test_protocol_command_refuses_an_unknown_subject_and_a_missing_folder(tmp_path, capsys):
    assert main(["protocol", "walk-loso", "--subjects", "cmu99", "--out", str(tmp_path / "o")]) == 2
    assert "no subject 'cmu99'" in capsys.readouterr().err
    assert main(["protocol", "jog-loso", "--data", str(tmp_path / "none"), "--out", str(tmp_path / "o")]) == 2
    assert "no such folder" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["protocol", "jog-loso", "--image-size", "80by60"])
    assert "WIDTHxHEIGHT" in capsys.readouterr().err


def test_protocol_command_passes_its_start_and_its_floor_to_every_fold(tmp_path, monkeypatch):
    """``--start auto`` reaches the experiment's config (``truth`` by default); the takes are
    levelled onto their floors unless ``--no-level-floor``."""
    seen = []
    monkeypatch.setattr("jaxtrack.experiment.run_protocol",
                        lambda protocol, data, out, config, **kw: seen.append((config, kw["level_floor"])) or [])
    (tmp_path / "data").mkdir()
    for extra in ([], ["--start", "auto"], ["--no-level-floor"]):
        assert main(["protocol", "walk-loso", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "o"), *extra]) == 0
    assert [(c.start, level) for c, level in seen] == [("truth", True), ("auto", True), ("truth", False)]


@pytest.mark.slow  # converts four takes and fits two manifolds: about a minute on 2 cores
@pytest.mark.shared_data
def test_a_protocol_runs_end_to_end_and_resumes(shared_data, tmp_path):
    jog = PROTOCOLS["jog-loso"]
    small = dataclasses.replace(jog, name="two-actors", subjects=tuple(s for s in jog.subjects if s.name in ("hdm05-bd", "hdm05-dg")),
                                test_frames=12, train_frames=60)
    config = ExperimentConfig(methods=("sir", "glegbpf"), runs=1, budget=60, fit_steps=20)
    said = []
    rows = run_protocol(small, shared_data, str(tmp_path), config, subjects=["hdm05-bd"], say=said.append)
    assert [(r["mode"], r["subject"]) for r in rows] == [("cross", "hdm05-bd"), ("within", "hdm05-bd")]
    assert rows[0]["train"] == ["HDM_dg_jogLeftCircle4StepsRstart_009_120"]
    assert rows[1]["train"] == ["HDM_bd_jogLeftCircle4StepsRstart_002_120"]
    for row in rows:
        assert set(row["methods"]) == {"sir", "glegbpf"} and row["start_error_mm"] < 5.0  # the file's own skeleton: IK residual
        assert all(np.isfinite(m["error_mm_mean"]) and len(m["per_frame_error_mm"]) == 12 for m in row["methods"].values())
        assert 0.0 < row["nearest_training_pose_mm"] < 200.0
    stored = json.loads((tmp_path / "protocol.json").read_text())
    assert stored["rows"] == json.loads(json.dumps(rows))
    assert "two-actors" in (tmp_path / "table.md").read_text()
    # The silhouettes are the same scene in both folds; the converted files carry the subject.
    from jaxtrack.io import load_sequence

    assert load_sequence(str(tmp_path / "converted-levelled" / "HDM_bd_jogLeftCircle4StepsRstart_001_120.npz")).subject == "hdm05-bd"
    said.clear()
    again = run_protocol(small, shared_data, str(tmp_path), config, subjects=["hdm05-bd"], say=said.append)
    assert again == json.loads(json.dumps(rows)) and sum("already" in s for s in said) == 2
    # A protocol.json written before the rig's azimuth was recorded holds the default rig's folds.
    assert all(r["azimuth"] == 45.0 for r in rows)
    stored["rows"] = [{k: v for k, v in r.items() if k not in ("azimuth", "start")} for r in stored["rows"]]
    (tmp_path / "protocol.json").write_text(json.dumps(stored))
    said.clear()
    run_protocol(small, shared_data, str(tmp_path), config, subjects=["hdm05-bd"], say=said.append)
    assert sum("already" in s for s in said) == 2
    # Started automatically, the folds are new ones: the start found on each fold's manifold, not the truth.
    found = run_protocol(small, shared_data, str(tmp_path), dataclasses.replace(config, start="auto"), subjects=["hdm05-bd"],
                         modes=("cross",), say=said.append)
    auto = [r for r in found if r.get("start") == "auto"]
    assert len(auto) == 1 and auto[0]["start_found_on"] == "gle-3d" and auto[0]["start_error_mm"] > 5.0
