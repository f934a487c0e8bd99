"""The narrow interfaces: the tracking spec every entry point reads, filters that take new
dynamics and refinement through their own constructors, refinable dynamics as a subclass, and
the manifold's model, tracking prior and file format apart."""

import dataclasses
import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.dynamics import (
    AbstractDynamics,
    AbstractRefinableDynamics,
    PoseRandomWalk,
    PoseResidual,
    StateVelocity,
    is_refinable,
)
from jaxtrack.errors import ConfigurationError
from jaxtrack.experiment import ExperimentConfig
from jaxtrack.filters import APF, SIR, AbstractComposedFilter, LangevinRefinement, run_filter
from jaxtrack.likelihood import as_likelihood
from jaxtrack.manifold import AbstractManifold, AbstractSaveableManifold, ManifoldPrior, make_bc_gplvm, to_prior
from jaxtrack.tracking import TrackingSpec


def _gaussian(poses, observation):
    return -0.5 * jnp.sum((poses - observation) ** 2, axis=-1) / 0.1**2


class Opaque(AbstractDynamics):
    """Dynamics without a transition density (like a graph walk)."""

    def init(self, key, pose, num_particles):
        return jnp.broadcast_to(pose, (num_particles,) + pose.shape)

    def to_pose(self, states):
        return states

    def propose(self, key, previous):
        return previous + 0.1 * jax.random.normal(key, previous.shape), jnp.zeros(previous.shape[0])

    def perturb(self, key, states, factor):
        return states


def test_refinable_dynamics_are_a_subclass_and_wrappers_follow_their_inner_dynamics():
    walk = PoseRandomWalk(jnp.full(6, 0.1))
    assert isinstance(walk, AbstractRefinableDynamics) and is_refinable(walk)
    assert not is_refinable(Opaque())
    velocity = StateVelocity(walk, jnp.full(6, 0.01), jnp.full(6, 0.02))
    assert is_refinable(velocity)
    assert not is_refinable(StateVelocity(Opaque(), jnp.full(6, 0.01), jnp.full(6, 0.02), displacement_noise=jnp.full(6, 0.1)))
    assert not is_refinable(PoseResidual(Opaque(), jnp.full(2, 0.1)))
    with pytest.raises(ValueError, match="defines no noise scales"):
        StateVelocity(Opaque(), jnp.full(6, 0.01), jnp.full(6, 0.02))


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-27)
def test_filters_take_new_dynamics_and_refinement_through_their_constructor():
    likelihood = as_likelihood(_gaussian)
    walk, wider = PoseRandomWalk(jnp.full(3, 0.1)), PoseRandomWalk(jnp.full(3, 0.2))
    for tracker in (SIR(walk, likelihood, 32), APF(walk, likelihood, 16, 2)):
        assert isinstance(tracker, AbstractComposedFilter)
        moved = tracker.with_dynamics(wider)
        assert type(moved) is type(tracker) and moved.dynamics is wider and tracker.dynamics is walk
        assert moved.num_particles == tracker.num_particles
        refined = tracker.with_refinement(LangevinRefinement(2))
        assert refined.refine.num_steps == 2 and tracker.refine is None
        # the same key gives the same run whether the filter was built directly or by with_dynamics
        direct = dataclasses.replace(tracker, dynamics=wider)
        ys = jnp.zeros((4, 3))
        a = run_filter(moved, jax.random.key(0), jnp.zeros(3), ys)[1].estimate
        b = run_filter(direct, jax.random.key(0), jnp.zeros(3), ys)[1].estimate
        np.testing.assert_array_equal(a, b)
        # the constructor's checks run: refinement on dynamics without a density is refused
        with pytest.raises(ValueError, match="defines no transition density"):
            tracker.with_dynamics(Opaque()).with_refinement(LangevinRefinement(1))
        with pytest.raises(ValueError, match="defines no transition density"):
            tracker.with_refinement(LangevinRefinement(1)).with_dynamics(Opaque())


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-27)
def test_the_manifold_model_prior_and_file_format_are_apart():
    assert not {"header", "template", "prior"} & set(dir(AbstractManifold))
    assert {"header", "template"} <= set(dir(AbstractSaveableManifold))
    rng = np.random.default_rng(0)
    with jax.enable_x64(True):
        model = make_bc_gplvm(rng.normal(size=(20, 4)), 2)
        prior = to_prior(model, 6)
        assert isinstance(model, AbstractSaveableManifold) and isinstance(prior, ManifoldPrior)
        assert prior.global_dims == 6 and prior.pose_dim == 10
        poses = jnp.asarray(rng.normal(size=(3, 4)))
        np.testing.assert_allclose(model.encode(poses), prior.encode(poses), rtol=1e-12)
    with pytest.raises(TypeError, match="AbstractManifold"):
        to_prior(object(), 0)


def test_the_tracking_spec_is_validated_once_and_read_by_the_experiment():
    spec = TrackingSpec(budget=300, velocity=False, pixel_samples=None)
    assert spec.tracking_budget.particles == 300 and spec.velocity_of("mrpf") is False
    assert spec.scene_options()["pixel_samples"] is None
    config = ExperimentConfig(methods=("sir", "mrpf"), runs=2, **spec.tracking_fields())
    assert isinstance(config, TrackingSpec) and config.spec == spec
    assert config.manifold_specs == (("gpdm", 2),)
    for bad, match in (({"budget": 0}, "positive integer"), ({"pixel_samples": 2}, "pixel_samples"),
                       ({"body": "mine"}, "body must be one of"), ({"body_prior": "mine"}, "body_prior must be one of"),
                       ({"height": 9.0}, "height"),
                       ({"likelihood": "nope"}, "nope"), ({"likelihood_options": {"colour": 1}}, "takes no option"),
                       ({"manifold": "pca"}, "manifold must be one of"), ({"residual": -1.0}, "residual"),
                       ({"fit_optimiser": "adam"}, "fit_optimiser"), ({"resolution": (80, 0)}, "resolution")):
        with pytest.raises(ConfigurationError, match=match):
            TrackingSpec(**bad)
    # The second body pass: only a calibrated body; by default where the start is given, not where it is found.
    calibrated, given = types.SimpleNamespace(body_calibration=object()), types.SimpleNamespace(body_calibration=None)
    assert TrackingSpec().refines_body(calibrated) and not TrackingSpec(start="auto").refines_body(calibrated)
    assert TrackingSpec(start="auto", refine_body=True).refines_body(calibrated)
    assert not TrackingSpec(refine_body=False).refines_body(calibrated)
    assert not any(TrackingSpec(refine_body=r).refines_body(given) for r in (None, True, False))
    with pytest.raises(ValueError, match="equal annealing layers"):
        TrackingSpec(budget=301).check_method("apf")
    with pytest.raises(ValueError, match="sir"):
        TrackingSpec().check_method("no-such-tracker")
