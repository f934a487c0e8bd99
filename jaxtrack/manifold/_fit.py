"""Fitting a manifold model: maximise its objective with L-BFGS, the whole optimisation one
compiled ``lax.while_loop``: no host round-trip per step. Two optimisers: ``"lbfgs"``
(default, ``_lbfgs``: one objective evaluation per loop iteration, the line search a state of
the loop) and ``"optax"`` (optax's L-BFGS with its zoom line search, the fit before issue #15's
compile-time work). The convergence test and the guard against non-finite values run inside
the loop; with a progress bar the loop runs in pieces of ``report_every`` steps, the same run as
one piece, so that no host callback keeps the program out of JAX's persistent cache."""

from __future__ import annotations

import contextlib
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
import threadpoolctl
from jax.flatten_util import ravel_pytree

from ._lbfgs import LBFGS_MEMORY, LBFGSState, lbfgs_advance, lbfgs_init

OPTIMISERS = ("lbfgs", "optax")
# The one default of every fit (``fit_model``, ``tracking.fit_manifold``, ``jaxtrack fit``,
# ``jaxtrack experiment`` and the demo). The tracking tables of docs/trackers.md before
# 2026-11-26 were measured with "optax" (``--fit-optimiser optax`` reproduces them).
DEFAULT_OPTIMISER = "lbfgs"


class FitInfo(NamedTuple):
    """Outcome of a fit.

    Attributes:
        objective: the final objective (to be maximised).
        steps: L-BFGS iterations taken (and kept).
        trace: (steps,) ``trace[i]`` is the objective at the parameters after step ``i``.
        evaluations: objective-and-gradient evaluations, line-search trials included (the count
            GPy's and SciPy's ``max_iters`` / ``maxfun`` limit).
    """

    objective: float
    steps: int
    trace: np.ndarray
    evaluations: int = 0


_OPTIMISER = optax.lbfgs()


def _loss(params, static):
    return -eqx.combine(params, static).objective()


def _all_finite(tree) -> jax.Array:
    leaves = jax.tree_util.tree_leaves(tree)
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(leaf)) for leaf in leaves]))


class _Carry(NamedTuple):
    params: object
    state: object
    step: jax.Array  # steps kept
    evaluations: jax.Array
    value: jax.Array  # the loss at ``params``
    checkpoint: jax.Array  # the loss at the last convergence check
    done: jax.Array
    trace: jax.Array  # (capacity,) loss after each kept step


@eqx.filter_jit
def _optax_start(params, static, capacity: int) -> _Carry:
    """optax's L-BFGS before its first step: the loss and gradient at the start in its state."""
    # The loss and gradient at the start go into the optimiser's state, where its line search
    # leaves them after every step: the loop reads them from there, so the objective's code
    # appears twice in the compiled programs (here and in the line search), not four times (a
    # forward pass for the start, ``value_and_grad_from_state``'s recompute branch, the line search).
    initial, initial_grad = jax.value_and_grad(_loss)(params, static)
    dtype = jnp.result_type(initial)
    state = optax.tree_utils.tree_set(_OPTIMISER.init(params), value=initial, grad=initial_grad)
    # optax's state starts with weakly typed scalars (its line search's counters), which the loop
    # returns strongly typed: without this the second piece of a fit would compile a second loop.
    state = jax.tree.map(lambda leaf: jnp.asarray(leaf, leaf.dtype), state)
    return _Carry(
        params=params, state=state, step=jnp.zeros((), int), evaluations=jnp.ones((), int),  # ``initial`` (with its gradient)
        value=initial, checkpoint=initial, done=~jnp.isfinite(initial), trace=jnp.full((capacity,), jnp.nan, dtype),
    )


@eqx.filter_jit
def _optax_advance(start: _Carry, static, max_steps, tolerance, target, check_every) -> _Carry:
    """optax's L-BFGS from ``start`` in one ``lax.while_loop`` until ``max_steps`` steps in all.
    ``max_steps``, ``tolerance`` and ``check_every`` are traced, so fits of one model class and
    shapes share one compilation whatever their step counts (the trace buffer's length is the
    next power of two of the steps asked for).

    Stops after ``max_steps`` steps; when the loss improves by less than ``tolerance``
    (relative) over ``check_every`` steps; when it reaches ``target`` (a loss); or before a
    step whose loss or parameters are not finite (those are discarded)."""

    def loss(p):
        return _loss(p, static)

    def cond(c: _Carry):
        return (c.step < max_steps) & ~c.done

    def body(c: _Carry):
        value, grad = optax.tree_utils.tree_get(c.state, "value"), optax.tree_utils.tree_get(c.state, "grad")
        updates, state = _OPTIMISER.update(grad, c.state, c.params, value=value, grad=grad, value_fn=loss)
        params = optax.apply_updates(c.params, updates)
        new_value = optax.tree_utils.tree_get(state, "value")
        trials = optax.tree_utils.tree_get(state, "num_linesearch_steps")
        finite = jnp.isfinite(new_value) & _all_finite(params)
        step = c.step + finite.astype(c.step.dtype)
        check = finite & (step % check_every == 0)
        stalled = check & (tolerance > 0) & (jnp.abs(c.checkpoint - new_value) <= tolerance * jnp.maximum(1.0, jnp.abs(new_value)))
        keep = lambda new, old: jax.tree.map(lambda a, b: jnp.where(finite, a, b), new, old)  # noqa: E731
        return _Carry(
            params=keep(params, c.params),
            state=keep(state, c.state),
            step=step,
            evaluations=c.evaluations + trials,
            value=jnp.where(finite, new_value, c.value),
            checkpoint=jnp.where(check, new_value, c.checkpoint),
            done=~finite | stalled | (new_value <= target),
            trace=c.trace.at[c.step].set(jnp.where(finite, new_value, jnp.nan)),
        )

    return jax.lax.while_loop(cond, body, start)


@eqx.filter_jit
def _lbfgs_start(params, capacity: int, memory: int) -> LBFGSState:
    """``lbfgs_init`` on the flattened trainable leaves."""
    x0, _ = ravel_pytree(params)
    return lbfgs_init(x0, capacity=capacity, memory=memory)


@eqx.filter_jit
def _lbfgs_advance(state: LBFGSState, params, static, max_steps, tolerance, target, check_every):
    """``lbfgs_advance`` on the flattened trainable leaves (``params`` gives their layout);
    returns the new state and its point as parameters."""
    _, unravel = ravel_pytree(params)
    state = lbfgs_advance(jax.value_and_grad(lambda x: _loss(unravel(x), static)), state, max_steps=max_steps,
                          tolerance=tolerance, target=target, check_every=check_every)
    return state, unravel(state.x)


def fit_model(model, *, max_steps: int = 500, tolerance: float = 1e-7, target: float | None = None, progress: bool = False,
              report_every: int = 50, blas_threads: int | None = 1, chunk: int | None = None, optimiser: str = DEFAULT_OPTIMISER,
              memory: int = LBFGS_MEMORY):
    """Maximise ``model.objective()`` over the leaves ``model.trainable()`` marks.

    Args:
        max_steps: L-BFGS iterations at most (exactly this many unless it converges first).
        tolerance: stop when ``report_every`` steps improve the objective by less than this
            (relative); 0 runs all ``max_steps``.
        target: stop as soon as the objective reaches this value (None: no target), e.g. to time
            how long a fit takes to reach another optimiser's result.
        progress: show a progress bar, updated by a host callback every ``report_every`` steps.
        report_every: steps between progress reports and convergence checks.
        blas_threads: threads the BLAS library under XLA's LAPACK calls (SciPy's OpenBLAS) may
            use during the fit (``threadpoolctl``); None leaves it as it is. XLA runs its own
            thread pool, and a LAPACK call inside it that starts one more per core
            oversubscribes the cores: on 2 cores one BLAS thread made an N = 350 GP-LVM
            gradient 2.6x faster and an N = 1000 one 1.5x.
        chunk: the former name of ``report_every`` (the steps between checks).
        optimiser: "lbfgs" (``DEFAULT_OPTIMISER``: one objective evaluation per loop iteration,
            ``_lbfgs``; compiles in about half the time) or "optax" (optax's L-BFGS with its
            zoom line search and 10 pairs, the fit the older tracking tables of docs/trackers.md
            were measured with).
        memory: curvature pairs of "lbfgs" (default 100).

    Returns:
        ``(fitted_model, FitInfo)``. Float64 is recommended (tests and defaults use it); in
        float32 the Cholesky's adaptive jitter keeps the objective finite. A step whose
        objective or parameters are not finite ends the fit at the parameters before it: a fit
        never returns NaNs.
    """
    report_every = report_every if chunk is None else chunk
    checked = [("max_steps", max_steps), ("report_every", report_every)]
    checked += [] if blas_threads is None else [("blas_threads", blas_threads)]
    for name, value in checked:
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"fit_model: {name} must be a positive integer, got {value!r}")
    if not (np.isfinite(tolerance) and tolerance >= 0):
        raise ValueError(f"fit_model: tolerance must be a finite number >= 0, got {tolerance!r}")
    if target is not None and not np.isfinite(target):
        raise ValueError(f"fit_model: target must be a finite number or None, got {target!r}")
    if optimiser not in OPTIMISERS:
        raise ValueError(f"fit_model: optimiser must be one of {OPTIMISERS}, got {optimiser!r}")
    if isinstance(memory, bool) or not isinstance(memory, int) or memory < 1:
        raise ValueError(f"fit_model: memory must be a positive integer, got {memory!r}")
    params, static = eqx.partition(model, model.trainable())
    capacity = 1 << (max_steps - 1).bit_length()
    # With a progress bar the loop runs in pieces of ``report_every`` steps, the bar moved between
    # them; the same run as one piece (``lbfgs_advance``). Not a host callback inside the loop: JAX
    # never keeps a program with one in its persistent cache, so every call compiled the fit again.
    stops = [*range(report_every, max_steps, report_every), max_steps] if progress else [max_steps]
    checks = (jnp.asarray(tolerance, float), jnp.asarray(-np.inf if target is None else -target, float), jnp.asarray(report_every))
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=max_steps, desc=f"fitting {type(model).__name__}", unit="step")
    limits = contextlib.nullcontext() if blas_threads is None else threadpoolctl.threadpool_limits(blas_threads, user_api="blas")
    try:
        with limits:
            if optimiser == "lbfgs":
                state, trained = _lbfgs_start(params, capacity, memory), params
            else:
                state = _optax_start(params, static, capacity)
            for stop in stops:
                if optimiser == "lbfgs":
                    state, trained = _lbfgs_advance(state, params, static, jnp.asarray(stop), *checks)
                    loss, steps = state.loss, int(state.steps)  # waits for the piece, inside the limits
                else:
                    state = _optax_advance(state, static, jnp.asarray(stop), *checks)
                    trained, loss, steps = state.params, state.value, int(state.step)
                if bar is not None:
                    bar.update(steps - bar.n)
                    bar.set_postfix(objective=f"{-float(loss):.6g}")
                if bool(state.done) or steps < stop:
                    break
    finally:
        if bar is not None:
            bar.close()
    params, value, evaluations, trace = trained, loss, state.evaluations, state.trace
    fitted = eqx.combine(params, static)
    objective = -float(value)
    trace = -np.asarray(trace)[:steps]
    return fitted, FitInfo(objective=objective, steps=steps, trace=trace if steps else np.array([objective]),
                           evaluations=int(evaluations))
