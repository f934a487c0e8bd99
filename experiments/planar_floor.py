"""Why paper 003's latent tracker loses the gestures (docs/planar.md): how close the SPM manifold
comes to the test poses, and how the tracker does with a likelihood that cannot be fooled.

    taskset -c 0,1 python experiments/planar_floor.py MODEL.eqx [--test-body default] [--oracle]

For each test view of ``planar.TEST_VIEWS`` (and, with ``--views-at-training-distance``, the
same motion seen from training-sphere cameras) it prints the arm markers' mean error (pixels,
every 5th frame) of three reconstructions of the true markers:

- ``manifold``: encoded onto the manifold and decoded (the best ``latentpf2d`` can show);
- ``nearest``: the training pose nearest in the manifold's feature space (what the training
  data hold, without the GP);
- the scale of each searched as ``planar.start_state`` does.

``--oracle`` then runs 003's Condensation (200 particles, the model's ``nu``) with the template
likelihood replaced by a Gaussian on the true markers (``--sigma`` pixels): what the manifold and
its random walk allow when the likelihood is perfect. Motion only: no video is rendered.
"""

import argparse

import jax
import jax.numpy as jnp
import numpy as np

import jaxtrack.planar as planar
from jaxtrack.body import HUMANEVA_JOINTS
from jaxtrack.filters import systematic, weighted_mean
from jaxtrack.planar import centred_joints, project_markers, start_state

ARM_MARKERS = [planar.SPM_MARKERS.index(m) for m in ("lelbow", "lwrist", "relbow", "rwrist")]
SCALE_SHARES = (1.0, 0.95, 0.9, 0.85, 0.8, 0.75, 0.7)


def test_markers(v, view, body, frames=150, distance=2.2, target_height=1.45, centred=False):
    from planar_tracking import test_motion

    motion = test_motion(v, frames, body)
    rig = planar.view_sphere_rig((view[0],), (view[1],), distance=distance, target_height=target_height, dtype=np.float64)
    joints = centred_joints(motion.joints3d) if centred else motion.joints3d
    markers, _ = project_markers(rig, joints, HUMANEVA_JOINTS)
    return jnp.asarray(markers[0])


def floors(model, markers):
    """Arm errors (px) of the manifold's and the nearest training pose's reconstructions."""
    manifold = model.manifold
    training = jnp.asarray(manifold.mean + manifold.scale * manifold.data)
    spine = planar.spine_to_neck(markers)
    scales = spine[:, None] / (planar.SPM_REFERENCE_LENGTHS[0] * jnp.asarray(SCALE_SHARES)[None])
    states = jax.vmap(lambda m, s: jax.vmap(lambda x: planar.spm_from_markers(m, x))(s))(markers, scales)
    flat = states.reshape(-1, planar.SPM_STATE_DIM)
    features = planar.spm_features(flat)
    nearest = jnp.concatenate([jnp.argmin(jnp.sum((features[i:i + 64, None] - training[None]) ** 2, -1), 1)
                               for i in range(0, features.shape[0], 64)])
    decoded, _ = manifold.predictor()(manifold.encode(features))
    out = []
    for f in (decoded, training[nearest]):
        got = planar.spm_forward(planar.spm_state(f, flat[:, :2], flat[:, 2])).reshape(states.shape[:2] + (9, 2))
        distance = jnp.linalg.norm(got - markers[:, None], axis=-1)
        best = jnp.argmin(distance.mean(-1), axis=1)
        chosen = np.asarray(jnp.take_along_axis(distance, best[:, None, None], axis=1)[:, 0])
        out.append(float(chosen[:, ARM_MARKERS].mean()))
    return out


def oracle_run(model, truth, key, sigma, particles=200):
    """003's Condensation with ``ln p = -|markers - truth|^2 / (2 sigma^2 9)``; returns the
    arm errors (px) of the latent-mean and marker-mean estimates, frames 1..T-1."""
    predictor = model.manifold.predictor()
    q = model.manifold.latent_dim
    height = float(planar.spine_to_neck(truth[0]))
    step_sd = jnp.concatenate([model.step_sd, jnp.asarray([0.03 * height] * 2 + [0.01])])

    def markers_of(states):
        features, _ = predictor(states[:, :q])
        return planar.spm_forward(planar.spm_state(features, states[:, q:q + 2], states[:, q + 2]))

    def step(carry, inputs):
        states, log_weights = carry
        target, k = inputs
        k_resample, k_walk = jax.random.split(k)
        states = states[systematic(k_resample, log_weights)]
        states = states + step_sd * jax.random.normal(k_walk, states.shape)
        markers = markers_of(states)
        log_weights = -jnp.sum((markers - target) ** 2, axis=(-1, -2)) / (2 * sigma**2 * 9)
        return (states, log_weights), (markers_of(weighted_mean(log_weights, states)[None])[0], weighted_mean(log_weights, markers))

    start = jnp.tile(jnp.asarray(start_state(model, truth[0])), (particles, 1))
    _, (latent_mean, marker_mean) = jax.jit(lambda k: jax.lax.scan(step, (start, jnp.zeros(particles)),
                                                                      (truth[1:], jax.random.split(k, truth.shape[0] - 1))))(key)
    return [np.asarray(jnp.linalg.norm(e - truth[1:], axis=-1)[:, ARM_MARKERS].mean(-1)) for e in (latent_mean, marker_mean)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("model")
    parser.add_argument("--test-body", choices=("test", "default"), default="test")
    parser.add_argument("--views-at-training-distance", action="store_true")
    parser.add_argument("--oracle", action="store_true")
    parser.add_argument("--sigma", type=float, default=8.0)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)
    model = planar.load_spm_model(args.model)
    print(f"{args.model}: {model.manifold.latent.shape[0]} training poses, active set {model.manifold.active.shape[0]}, "
          f"latent dimension {model.manifold.latent_dim}")
    for v, view in enumerate(planar.TEST_VIEWS):
        truth = test_markers(v, view, args.test_body)
        manifold, nearest = floors(model, truth[::5])
        line = f"az {view[0]:g} el {view[1]:g}, 2.2 m: arms manifold {manifold:.1f} px, nearest training pose {nearest:.1f} px"
        if args.views_at_training_distance:
            at_sphere = floors(model, test_markers(v, view, args.test_body, distance=4.0, target_height=1.2, centred=True)[::5])
            line += f"; at 4 m: manifold {at_sphere[0]:.1f}, nearest {at_sphere[1]:.1f}"
        if args.oracle:
            threshold = 0.25 * np.asarray(planar.spine_to_neck(truth[1:]))
            runs = [oracle_run(model, truth, jax.random.key(r), args.sigma) for r in range(args.runs)]
            for name, i in (("latent-mean", 0), ("marker-mean", 1)):
                errors = np.stack([run[i] for run in runs])
                line += f"; oracle {name}: arms {errors.mean():.1f} px, tracked {100 * np.mean(errors < threshold):.0f} %"
        print(line, flush=True)


if __name__ == "__main__":
    main()
