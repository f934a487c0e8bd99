"""Fitting a manifold model: maximise its objective with L-BFGS (optax), the whole update step
jitted and run in chunks of a ``lax.scan`` so that progress can be shown between chunks."""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import numpy as np
import optax


class FitInfo(NamedTuple):
    """Outcome of a fit: the final objective (to be maximised), steps taken, and the trace."""

    objective: float
    steps: int
    trace: np.ndarray


_OPTIMISER = optax.lbfgs()


def _loss(params, static):
    return -eqx.combine(params, static).objective()


@eqx.filter_jit
def _run_chunk(params, state, static, chunk: int):
    """``chunk`` L-BFGS steps in one ``lax.scan``; module level, so repeated fits of the same
    model class and shapes reuse the compilation (data and hyperparameters are traced)."""

    def loss(p):
        return _loss(p, static)

    value_and_grad = optax.value_and_grad_from_state(loss)

    def step(carry, _):
        p, state = carry
        value, grad = value_and_grad(p, state=state)
        updates, state = _OPTIMISER.update(grad, state, p, value=value, grad=grad, value_fn=loss)
        return (optax.apply_updates(p, updates), state), value

    return jax.lax.scan(step, (params, state), None, length=chunk)


def _finite(tree) -> bool:
    return all(bool(np.all(np.isfinite(np.asarray(leaf)))) for leaf in jax.tree_util.tree_leaves(tree))


def fit_model(model, *, max_steps: int = 500, chunk: int = 50, tolerance: float = 1e-7, progress: bool = False):
    """Maximise ``model.objective()`` over the leaves ``model.trainable()`` marks.

    Args:
        max_steps: L-BFGS iterations at most (exactly this many unless it converges first).
        chunk: iterations per jitted ``lax.scan`` (progress is reported between chunks).
        tolerance: stop when a chunk improves the objective by less than this (relative).

    Returns:
        ``(fitted_model, FitInfo)``. Float64 is recommended (tests and defaults use it); in
        float32 the Cholesky's adaptive jitter keeps the objective finite. Should a chunk's
        objective or parameters turn non-finite anyway, the fit stops at the parameters before
        that chunk (``FitInfo.steps`` counts the steps kept).
    """
    for name, value in (("max_steps", max_steps), ("chunk", chunk)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"fit_model: {name} must be a positive integer, got {value!r}")
    params, static = eqx.partition(model, model.trainable())
    state = _OPTIMISER.init(params)
    trace, steps = [], 0
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=max_steps, desc=f"fitting {type(model).__name__}", unit="step")
    previous = None
    while steps < max_steps:
        length = min(chunk, max_steps - steps)  # exactly max_steps in all
        (candidate, candidate_state), values = _run_chunk(params, state, static, length)
        values = np.asarray(values)
        if not np.all(np.isfinite(values)) or not _finite(candidate):
            break  # keep the last chunk's finite parameters: a fit never returns NaNs
        params, state = candidate, candidate_state
        trace.append(-values)
        steps += length
        if bar is not None:
            bar.update(length)
            bar.set_postfix(objective=f"{-values[-1]:.4g}")
        current = float(values[-1])
        if previous is not None and abs(previous - current) <= tolerance * max(1.0, abs(current)):
            break
        previous = current
    if bar is not None:
        bar.close()
    fitted = eqx.combine(params, static)
    objective = float(fitted.objective())
    return fitted, FitInfo(objective=objective, steps=steps, trace=np.concatenate(trace) if trace else np.array([objective]))
