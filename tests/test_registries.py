"""The likelihood and manifold-kind registries: a new likelihood or manifold kind is one module
and one registration, read by ``jaxtrack fit``, ``jaxtrack experiment`` and ``jaxtrack track``
(``--plugin``); ``jaxtrack fit`` and ``jaxtrack experiment`` fit the same model."""

import json

import jax
import numpy as np
import pytest

from jaxtrack.likelihood import (
    DEFAULT_LIKELIHOOD,
    LikelihoodRecipe,
    SceneInputs,
    available_likelihoods,
    get_likelihood,
    register_likelihood,
    unregister_likelihood,
)
from jaxtrack.manifold import ManifoldKind, get_manifold_kind, make_gplvm, manifold_kinds, register_manifold_kind, unregister_manifold_kind
from jaxtrack.tracking import get_tracker

from helpers import small_experiment_sequences

# A plugin as a user writes it, outside the package: a likelihood of its own (the silhouettes'
# at a fraction of their temperature) and a manifold kind of its own (a BC-GPLVM on every other
# frame), each one registration.
PLUGIN = '''
import numpy as np

from jaxtrack.likelihood import AbstractLikelihood, LikelihoodRecipe, make_silhouette_likelihood, register_likelihood
from jaxtrack.manifold import ManifoldKind, make_bc_gplvm, register_manifold_kind


class TemperedSilhouettes(AbstractLikelihood):
    inner: AbstractLikelihood
    weight: float

    def log_likelihood(self, poses, observation):
        return self.weight * self.inner.log_likelihood(poses, observation)


def build(inputs, *, weight):
    inner = make_silhouette_likelihood(inputs.body, inputs.rig, scale=inputs.scale, window=inputs.window,
                                       silhouettes=inputs.silhouettes)
    return TemperedSilhouettes(inner, weight)


register_likelihood(LikelihoodRecipe("toy-tempered", "the silhouettes at a fraction of their temperature", build,
                                     {"weight": 0.5}), replace=True)
register_manifold_kind(ManifoldKind("toy-gplvm", "a back-constrained GPLVM on every other frame",
                                    lambda sequences, latent_dim, *, key=None: make_bc_gplvm(np.concatenate(sequences)[::2], latent_dim),
                                    min_frames=2), replace=True)
'''


def test_the_built_in_kinds_and_likelihood_are_registered():
    assert set(manifold_kinds(trackable=True)) == {"bc-gplvm", "gpdm", "bc-gpdm", "gle", "tle", "le", "sparse-bc-gplvm"}
    assert set(manifold_kinds()) - set(manifold_kinds(trackable=True)) == {"gplvm", "bc-gplvm-mlp", "sparse-gplvm", "active-set-gplvm"}
    assert manifold_kinds(family="spectral") == ("gle", "tle", "le")
    assert get_manifold_kind("gle").latent_dim == 3 and get_manifold_kind("gpdm").latent_dim == 2
    assert DEFAULT_LIKELIHOOD == "silhouette" and "silhouette" in available_likelihoods()
    with pytest.raises(ValueError, match="unknown manifold kind 'pca'; registered manifold kinds: bc-gplvm"):
        get_manifold_kind("pca")
    with pytest.raises(ValueError, match="unknown likelihood 'edges'; registered likelihoods: silhouette"):
        get_likelihood("edges")


def test_a_kinds_preconditions_are_checked_before_fitting():
    gpdm, le = get_manifold_kind("gpdm"), get_manifold_kind("le")
    assert gpdm.problem([30, 1], 2) == "a gpdm needs 2 or more frames in every training sequence (one has 1)"
    assert le.problem([6, 4], 3) == "a le needs at least 11 training frames, got 10"
    assert gpdm.problem([2, 1], 3) == "3 training frames are too few for a 3-D latent space (need more than 4)"
    assert gpdm.problem([30, 20], 2) is None
    with pytest.raises(ValueError, match="takes no option 'num_inducing'"):
        gpdm.build([np.zeros((10, 3))], 2, num_inducing=3)
    with pytest.raises(ValueError, match="needs 2 or more frames"):
        gpdm.build([np.zeros((10, 3)), np.zeros((1, 3))], 2)


def test_a_registered_kind_joins_its_family_and_leaves_cleanly():
    kind = ManifoldKind("every-other", "a GPLVM on every other frame",
                        lambda sequences, latent_dim, *, key=None: make_gplvm(np.concatenate(sequences)[::2], latent_dim))
    register_manifold_kind(kind)
    try:
        with pytest.raises(ValueError, match="already registered"):
            register_manifold_kind(kind)
        mrpf, glegbpf = get_tracker("mrpf"), get_tracker("glegbpf")
        assert "every-other" in mrpf.runs_on and "every-other" not in glegbpf.runs_on
        assert mrpf.manifold_for("every-other") == "every-other"
        assert glegbpf.manifold_for("every-other") == "gle"  # the other family keeps its own
        model = kind.build([np.random.default_rng(0).standard_normal((20, 4))], None)
        assert model.data.shape == (10, 4) and model.latent_dim == 2
    finally:
        unregister_manifold_kind("every-other")
    assert "every-other" not in mrpf.runs_on
    with pytest.raises(ValueError, match="family must be one of"):
        ManifoldKind("odd", "", lambda s, d, *, key=None: None, family="graph")


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-27)
def test_a_likelihood_recipe_checks_its_options_and_what_it_builds():
    from jaxtrack.likelihood import SilhouetteLikelihood

    test = small_experiment_sequences()[2][0]
    inputs = SceneInputs(body=test.body(), rig=test.rig(), silhouettes=np.asarray(test.silhouettes, np.float32), scale=100.0)
    silhouette = get_likelihood("silhouette")
    built = silhouette.make(inputs, edge_width=2.0)
    assert isinstance(built, SilhouetteLikelihood) and built.edge_width == 2.0 and built.scale == 100.0
    with pytest.raises(ValueError, match="likelihood 'silhouette' takes no option 'sigma' \\(it takes: edge_width\\)"):
        silhouette.make(inputs, sigma=1.0)
    register_likelihood(LikelihoodRecipe("not-one", "returns a number", lambda inputs: 3.0))
    try:
        with pytest.raises(TypeError, match="its builder returned a float, not an AbstractLikelihood"):
            get_likelihood("not-one").make(inputs)
    finally:
        unregister_likelihood("not-one")


def test_option_strings_are_parsed_as_their_defaults_types():
    from jaxtrack.cli import _options

    assert _options(["weight=0.25", "n=3", "flag=yes", "name=x"], {"weight": 1.0, "n": 1, "flag": False, "name": ""}, "t") == {
        "weight": 0.25, "n": 3, "flag": True, "name": "x"}
    with pytest.raises(ValueError, match="option n of t must be a int, got 'three'"):
        _options(["n=three"], {"n": 1}, "t")
    with pytest.raises(ValueError, match="t takes no option 'm' \\(it takes: n\\)"):
        _options(["m=1"], {"n": 1}, "t")
    with pytest.raises(ValueError, match="an option is KEY=VALUE"):
        _options(["n"], {"n": 1}, "t")


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_fit_and_experiment_fit_the_same_model(tmp_path):
    """``jaxtrack fit`` and the experiment's ``tracking.fit_manifold`` are one fit: the same
    maker, optimiser, steps and key give the same parameters."""
    from jaxtrack.cli import main
    from jaxtrack.io import save_sequence
    from jaxtrack.manifold import load_model
    from jaxtrack.tracking import fit_manifold, sequence_poses

    train = small_experiment_sequences()[0]
    paths = []
    for index, seq in enumerate(train):
        paths.append(str(tmp_path / f"train{index}.npz"))
        save_sequence(paths[-1], seq)
    assert main(["fit", *paths, "--model", "gpdm", "--steps", "4", "--out", str(tmp_path / "m.eqx")]) == 0
    with jax.enable_x64(True):
        from_cli, _ = load_model(str(tmp_path / "m.eqx"))
        poses = [sequence_poses(seq, f"train{i}", key=jax.random.key(0)) for i, seq in enumerate(train)]
        in_process, _, _ = fit_manifold(poses, None, 4, kind="gpdm", key=jax.random.key(0))
    for a, b in zip(jax.tree.leaves(from_cli), jax.tree.leaves(in_process)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-9, atol=1e-12)


@pytest.mark.slow  # an end-to-end experiment
def test_a_plugin_likelihood_and_manifold_kind_run_through_the_command_line(tmp_path, capsys):
    from jaxtrack.cli import main
    from jaxtrack.io import save_sequence

    train, validation, test = small_experiment_sequences()
    paths = {}
    for name, seq in (("train0", train[0]), ("train1", train[1]), ("validation", validation[0]), ("test", test[0])):
        paths[name] = str(tmp_path / f"{name}.npz")
        save_sequence(paths[name], seq)
    plugin = tmp_path / "toy_plugin.py"
    plugin.write_text(PLUGIN)
    out = tmp_path / "out"
    try:
        assert main(["fit", "--plugin", str(plugin), paths["train0"], "--model", "toy-gplvm", "--steps", "3",
                     "--out", str(tmp_path / "toy.eqx")]) == 0
        assert "BCGPLVM, 30 frames" in capsys.readouterr().out
        code = main(["experiment", "--plugin", str(plugin), "--train", paths["train0"], paths["train1"],
                     "--validation", paths["validation"], "--test", paths["test"], "--methods", "mrpf", "sir",
                     "--manifold", "toy-gplvm", "--likelihood", "toy-tempered", "--likelihood-option", "weight=0.25",
                     "--budget", "40", "--runs", "1", "--frames", "3", "--fit-steps", "5", "--no-animation", "--out", str(out)])
        assert code == 0, capsys.readouterr().err
        results = json.loads((out / "results.json").read_text())
        assert results["config"]["likelihood"] == "toy-tempered"
        assert results["likelihoods"]["test.npz"] == {"name": "toy-tempered", "options": {"weight": 0.25},
                                                      "class": "TemperedSilhouettes", "pixel_samples": None}
        assert [m["kind"] for m in results["manifolds"].values()] == ["toy-gplvm"]
        assert results["manifolds"]["toy-gplvm-2d"]["frames"] == 30  # every other frame of 60
        for method in ("mrpf", "sir"):
            assert np.isfinite(results["sequences"]["test.npz"][method]["error_mm_mean"])
        assert main(["experiment", "--plugin", str(plugin), "--train", paths["train0"], "--validation", paths["validation"],
                     "--test", paths["test"], "--likelihood", "toy-tempered", "--likelihood-option", "sigma=1",
                     "--out", str(tmp_path / "bad")]) == 2
        assert "likelihood 'toy-tempered' takes no option 'sigma' (it takes: weight)" in capsys.readouterr().err
    finally:
        if "toy-tempered" in available_likelihoods():
            unregister_likelihood("toy-tempered")
        if "toy-gplvm" in manifold_kinds():
            unregister_manifold_kind("toy-gplvm")


def test_a_trackers_keys_follow_its_name_not_its_place_in_the_registry():
    import zlib

    from jaxtrack.dynamics import fit_pose_random_walk
    from jaxtrack.filters import SIR
    from jaxtrack.tracking import TrackerRecipe, register_tracker, tracker_keys, tracker_stream, unregister_tracker

    before = [jax.random.key_data(k) for k in tracker_keys(0, "mrpf")]
    assert tracker_stream("mrpf") == zlib.crc32(b"mrpf") & 0x7FFFFFFF
    register_tracker(TrackerRecipe("aaa-first", "AAA", "a tracker registered for this test",
                                   fit=lambda key, motion: fit_pose_random_walk(list(motion.validation)),
                                   build=lambda dynamics, likelihood, budget: SIR(dynamics, likelihood, budget.evaluations)))
    try:
        after = [jax.random.key_data(k) for k in tracker_keys(0, "mrpf")]
        assert all(np.array_equal(a, b) for a, b in zip(before, after))
        assert not np.array_equal(jax.random.key_data(tracker_keys(0, "aaa-first")[1]), before[1])
    finally:
        unregister_tracker("aaa-first")
