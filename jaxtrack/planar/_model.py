"""What ``jaxtrack fit --model spm-gplvm`` learns for paper 003's trackers, in one file:

- the active-set GPLVM of SPM poses (``spm_features``) seen from the view sphere (003 sec. 4);
- the latent random walk's standard deviations ``nu`` (003 eq. 6: "the variance of all the
  distances between pose transitions" of the training sequences projected into the latent
  space), one per latent dimension;
- the baselines' second-order autoregressive model on the 6-state shoulder-anchored arm chain
  (003 sec. 5.2), fitted by least squares on the same training sequences (``ArmAR``).
"""

from __future__ import annotations

import itertools

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ..manifold import ActiveSetGPLVM, load_model, make_active_set_gplvm, read_header, save_model
from ._arm_chain import arm_states_from_features
from ._spm import SPM_FEATURE_DIM, spm_features
from ._training import spm_training_set, view_sphere_rig

MODEL_VERSION = 1


class ArmAR(eqx.Module):
    """``x_t = mean + A1 (x_{t-1} - mean) + A2 (x_{t-2} - mean) + e``, ``e ~ N(0, diag(noise^2))``,
    per arm-chain dimension (diagonal A1, A2: (6,) each)."""

    a1: Float[Array, " k"]
    a2: Float[Array, " k"]
    mean: Float[Array, " k"]
    noise: Float[Array, " k"]

    def predict(self, previous, before):
        """The AR's mean at t from x_{t-1} and x_{t-2}."""
        return self.mean + self.a1 * (previous - self.mean) + self.a2 * (before - self.mean)


def fit_arm_ar(sequences, every: int = 1) -> ArmAR:
    """Least squares AR(2) per dimension over sequences of arm-chain states ((T_i, 6) each,
    angles unwrapped along each sequence); the noise is the residuals' standard deviation.
    Sequences that keep every ``every``-th frame of a motion are first interpolated linearly
    back to every frame, so the model predicts one frame ahead."""
    every = max(1, int(every))

    def per_frame(s):
        s = np.unwrap(np.asarray(s, np.float64), axis=0)
        if every == 1 or len(s) < 2:
            return s
        t = np.arange((len(s) - 1) * every + 1) / every
        return np.stack([np.interp(t, np.arange(len(s)), s[:, i]) for i in range(s.shape[1])], axis=1)

    rows = [(s[2:], s[1:-1], s[:-2]) for s in map(per_frame, sequences) if len(s) >= 3]
    if not rows:
        raise ValueError("the AR(2) model needs a training sequence of at least 3 frames")
    now, prev, before = (np.concatenate(part) for part in zip(*rows))
    k = now.shape[1]
    a1, a2, mean, noise = (np.zeros(k) for _ in range(4))
    for i in range(k):
        design = np.stack([prev[:, i], before[:, i], np.ones(len(now))], axis=1)
        (c1, c2, c0), *_ = np.linalg.lstsq(design, now[:, i], rcond=None)
        residual = now[:, i] - design @ np.array([c1, c2, c0])
        a1[i], a2[i] = c1, c2
        mean[i] = c0 / (1 - c1 - c2) if abs(1 - c1 - c2) > 1e-6 else np.mean(now[:, i])
        noise[i] = max(float(np.std(residual)), 1e-4)
    return ArmAR(*(jnp.asarray(v) for v in (a1, a2, mean, noise)))


class SPMModel(eqx.Module):
    """Paper 003's learned model (module docstring).

    Attributes:
        manifold: the active-set GPLVM of SPM features.
        step_sd: (q,) the latent random walk's standard deviation per dimension (003 eq. 6).
        arm_ar: the baselines' AR(2) on the arm chain.
    """

    manifold: ActiveSetGPLVM
    step_sd: Float[Array, " q"]
    arm_ar: ArmAR


def _starts(lengths):
    return np.concatenate([[0], np.cumsum(lengths)]).astype(int)


def latent_step_sd(latent, starts, every: int = 1) -> np.ndarray:
    """003 eq. 6's ``nu``: the root mean square of the latent steps within each training
    sequence (``starts``: first frame of each, ending with N), per dimension, per frame of the
    motion when the sequences keep every ``every``-th frame (a smooth motion's step grows with
    the time it spans)."""
    latent = np.asarray(latent)
    steps = np.concatenate([np.diff(latent[a:b], axis=0) for a, b in itertools.pairwise(starts) if b - a > 1])
    return np.sqrt(np.mean(steps**2, axis=0)) / max(1, int(every))


def fit_spm_model(joint_sequences, *, latent_dim: int = 3, active: int = 200, every: int = 3, rig=None,
                  iterations: int = 3, max_steps: int = 200, progress: bool = False) -> tuple[SPMModel, np.ndarray]:
    """003's training (sec. 4, Algorithm 1) on 3-D joint sequences ((T_i, 15, 3) HumanEva joints,
    metres): each seen from the view sphere (``rig``, default ``view_sphere_rig()``) every
    ``every``-th frame, as SPM features; the active-set GPLVM fitted; ``nu`` and the arm
    chain's AR(2) from the same sequences. Returns ``(model, sequence_starts)``."""
    states = spm_training_set(joint_sequences, view_sphere_rig() if rig is None else rig, every=every)
    features = [np.asarray(spm_features(jnp.asarray(s))) for s in states]
    data = np.concatenate(features)
    manifold = make_active_set_gplvm(data, latent_dim, active=min(int(active), data.shape[0]))
    manifold, _info = manifold.fit(iterations=iterations, max_steps=max_steps, progress=progress)
    starts = _starts([len(f) for f in features])
    arm = fit_arm_ar([np.asarray(arm_states_from_features(jnp.asarray(f))) for f in features], every)
    return SPMModel(manifold, jnp.asarray(latent_step_sd(manifold.latent, starts, every)), arm), starts


def save_spm_model(path, model: SPMModel, sequence_starts) -> None:
    """One model file: the manifold (``manifold.save_model``) with ``nu`` and the AR in its
    header's ``extra["spm"]``."""
    extra = {"spm": {"version": MODEL_VERSION, "step_sd": np.asarray(model.step_sd).tolist(),
                     "arm_ar": {k: np.asarray(getattr(model.arm_ar, k)).tolist() for k in ("a1", "a2", "mean", "noise")}}}
    save_model(path, model.manifold, sequence_starts=sequence_starts, extra=extra)


def load_spm_model(path) -> SPMModel:
    """Read ``save_spm_model``'s file; refuses a model that is not an SPM model, naming the file."""
    header = read_header(path)
    spm = header.get("extra", {}).get("spm") if isinstance(header.get("extra"), dict) else None
    if header.get("class") != "ActiveSetGPLVM" or not isinstance(spm, dict) or header.get("dims") != SPM_FEATURE_DIM:
        raise ValueError(f"{path}: not an SPM model (make one with `jaxtrack fit MOTION ... --model spm-gplvm`)")
    if spm.get("version") != MODEL_VERSION:
        raise ValueError(f"{path}: SPM model version {spm.get('version')!r}, this jaxtrack reads version {MODEL_VERSION}")
    manifold, _header = load_model(path, expected_class="ActiveSetGPLVM")
    step_sd = np.asarray(spm["step_sd"], np.float64)
    ar = {k: np.asarray(spm["arm_ar"][k], np.float64) for k in ("a1", "a2", "mean", "noise")}
    if step_sd.shape != (manifold.latent_dim,) or any(v.shape != (6,) for v in ar.values()):
        raise ValueError(f"{path}: the SPM model's step_sd or arm_ar has the wrong shape")
    if not (np.all(np.isfinite(step_sd)) and all(np.all(np.isfinite(v)) for v in ar.values())):
        raise ValueError(f"{path}: the SPM model's step_sd or arm_ar is not finite")
    return SPMModel(manifold, jnp.asarray(step_sd), ArmAR(*(jnp.asarray(ar[k]) for k in ("a1", "a2", "mean", "noise"))))
