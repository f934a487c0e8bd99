"""Shared helpers: tolerant tree comparison and tiny synthetic problems."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.camera import default_rig
from jaxtrack.data import NO_NOISE, SilhouetteNoise, build_scene, generate_motion


def tree_allclose(x, y, rtol=1e-5, atol=1e-8) -> bool:
    leaves_x, tree_x = jax.tree.flatten(x)
    leaves_y, tree_y = jax.tree.flatten(y)
    if tree_x != tree_y:
        return False
    return all(np.allclose(np.asarray(a), np.asarray(b), rtol=rtol, atol=atol) for a, b in zip(leaves_x, leaves_y))


def finite_difference_check(f, x, direction, *, eps=1e-6, rtol=1e-4, atol=1e-7):
    """Compare the derivative of scalar-or-array ``f`` at ``x`` along ``direction`` with a central
    difference, through a fixed random projection ``u`` of the output: ``<u, J d>`` from one
    reverse pass (the mode the library differentiates in: the rasteriser's statistics define a
    custom VJP and no JVP) against ``<u, (f(x + eps d) - f(x - eps d)) / 2 eps>``."""
    f = jax.jit(f)
    out = f(x)
    u = jnp.asarray(np.random.default_rng(0).standard_normal(np.shape(out)), jnp.result_type(out))
    gradient = jax.jit(jax.grad(lambda x: jnp.sum(u * f(x))))(x)
    derivative = jnp.sum(gradient * direction)
    fd = jnp.sum(u * (f(x + eps * direction) - f(x - eps * direction))) / (2 * eps)
    np.testing.assert_allclose(np.asarray(derivative), np.asarray(fd), rtol=rtol, atol=atol * max(1, np.size(out)))
    assert np.all(np.isfinite(np.asarray(gradient)))


@functools.lru_cache(maxsize=4)
def small_scene(num_frames: int = 8, width: int = 40, height: int = 30, noisy: bool = True, seed: int = 0):
    """A short noisy walk (subject S1) in 4 views at a low resolution, float64 body."""
    key = jax.random.key(seed)
    motion = generate_motion("walk", "S1", num_frames=num_frames, fps=30.0, key=key, dtype=jnp.float64)
    rig = default_rig(width, height, dtype=jnp.float64)
    noise = SilhouetteNoise() if noisy else NO_NOISE
    scene = build_scene(jax.random.fold_in(key, 1), motion, rig, noise)
    return motion, rig, scene


@functools.lru_cache(maxsize=1)
def small_experiment_sequences():
    """Training (a walk and a jog, 30 frames), validation (a walk, 20 frames) and test (the
    ``small_scene`` walk) sequences of subject S1 for quick experiment runs."""
    from jaxtrack.data import motion_sequence

    def motion(gait, frames, seed):
        return motion_sequence(generate_motion(gait, "S1", num_frames=frames, fps=30.0, key=jax.random.key(seed)))

    train = [motion("walk", 30, 0), motion("jog", 30, 1)]
    return train, [motion("walk", 20, 7)], [small_scene()[2]]


def small_tracking_inputs(frames: int):
    """``small_experiment_sequences`` ready to track: the test walk's prepared scene (its first
    ``frames`` frames) and the training and validation poses, all with key 0."""
    from jaxtrack.tracking import prepare_test, sequence_poses

    train, validation, test = small_experiment_sequences()
    key = jax.random.key(0)
    scene = prepare_test(test[0], "walk", key=key, frames=frames)
    return (scene, [sequence_poses(s, "train", key=key) for s in train],
            [sequence_poses(s, "validation", key=key) for s in validation])


def walk_and_gpdm_prior():
    """A 60-frame synthetic walk (poses (60, 32), float64) and a 2-D GPDM prior on its first 45
    frames, PCA-initialised and unfitted (the maps are what the dynamics tests test)."""
    from jaxtrack.manifold import make_gpdm, make_manifold_prior

    motion = generate_motion("walk", "S1", num_frames=60, fps=30.0, key=jax.random.key(5), dtype=jnp.float64)
    walk = np.asarray(motion.pose)
    return walk, make_manifold_prior(make_gpdm([walk[:25, 6:], walk[25:45, 6:]], 2), walk.shape[1])


def check_refinement_keeps_transition(dynamics, pose, getkey, *, particles: int = 20000):
    """``log_transition`` is the density ``propose`` draws from: MALA moves targeting it alone
    keep a sample of the transition a sample of it (means within 0.06 sd, sds within 6 %)."""
    from jaxtrack.filters import LangevinRefinement

    start = dynamics.init(getkey(), pose, particles)
    previous = dynamics.propose(getkey(), start)[0]  # distinct previous states
    drawn = dynamics.propose(getkey(), previous)[0]
    target = functools.partial(dynamics.log_transition, previous)
    moved, info = LangevinRefinement(num_steps=4)(getkey(), drawn, target, dynamics.noise_scales())
    a, b = np.asarray(drawn - previous), np.asarray(moved - previous)
    scale = a.std(0) + 1e-12
    assert np.abs((a.mean(0) - b.mean(0)) / scale).max() < 0.06, type(dynamics).__name__
    np.testing.assert_allclose(b.std(0), a.std(0), rtol=0.06, atol=1e-9, err_msg=type(dynamics).__name__)
    assert float(np.asarray(info.acceptance).mean()) > 0.3


# Small motion files: a two-bone ASF skeleton with its AMC writer, and a two-joint BVH.
ASF = """# a two-bone test skeleton
:version 1.10
:name test
:units
  mass 1.0
  length 1.0
  angle deg
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name up
     direction 0 1 0
     length 2.0
     axis 0 0 0 XYZ
    dof rx ry rz
    limits (-180 180)
           (-180 180)
           (-180 180)
  end
  begin
     id 2
     name side
     direction 1 0 0
     length 1.0
     axis 0 0 90 XYZ
    dof rx
  end
:hierarchy
  begin
    root up
    up side
  end
"""


def write_amc(path, frames):
    lines = [":FULLY-SPECIFIED", ":DEGREES"]
    for i, (root, up, side) in enumerate(frames, start=1):
        lines += [str(i), "root " + " ".join(map(str, root)), "up " + " ".join(map(str, up)), "side " + " ".join(map(str, side))]
    path.write_text("\n".join(lines) + "\n")


def write_bvh(path, frames, frame_time=0.04):
    """A root with 6 channels, a child with 3 rotation channels (ZXY) and an end site, centimetres."""
    text = """HIERARCHY
ROOT hips
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT spine
\t{
\t\tOFFSET 0 50 0
\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 40 0
\t\t}
\t}
}
MOTION
"""
    text += f"Frames: {len(frames)}\nFrame Time: {frame_time}\n"
    text += "\n".join(" ".join(f"{v:g}" for v in row) for row in frames) + "\n"
    path.write_text(text)


def interrupt_the_second_chunk(monkeypatch) -> list:
    """Patch the filters' chunk scan so that its second call raises ``KeyboardInterrupt`` (as a
    Ctrl-C in ``track --chunk-frames``); returns the list its calls are counted in."""
    import sys

    real_scan = sys.modules["jaxtrack.filters._run"]._scan  # the chunk scan, patched by name
    calls = []

    def dies_on_the_second_chunk(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real_scan(*a, **k)

    monkeypatch.setattr("jaxtrack.filters._run._scan", dies_on_the_second_chunk)
    return calls
