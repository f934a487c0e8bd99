"""L-BFGS with one objective evaluation per iteration of one ``lax.while_loop``.

Each iteration evaluates the loss and its gradient once, at the trial point ``x + alpha d``,
and then either accepts it (the weak Wolfe conditions, Nocedal and Wright eqs. 3.6), stores
the curvature pair and computes the next direction by the two-loop recursion (N&W Alg. 7.4,
initial Hessian ``s'y / y'y``, eq. 7.20), or moves ``alpha`` and tries again: back by
safeguarded quadratic interpolation (N&W eq. 3.57) from a step too long, forward by doubling
from one too short, by bisection once both are known. The line search is a state of the loop, not a
loop of its own, so the objective's code appears once in the compiled program: a GP fit
compiles in about half the time of optax's L-BFGS with its zoom line search, whose initial
evaluation and search each hold a copy (docs/manifolds.md, "Fitting a manifold").

A pair with too little curvature (``s'y <= 1e-10 |s| |y|``, possible only when a search ends
on its fallback) is not stored; a direction that is not downhill is replaced by steepest
descent. The memory keeps ``memory`` pairs (default 100, minFunc's default: a pair costs O(n)
beside an evaluation's O(N^3)). The steps a fit takes to a given objective depend chaotically
on the path: against optax's L-BFGS (10 pairs, zoom line search) this loop with 100 took fewer
on seven of the eight fits of ``benchmarks/bench_manifold.py`` (a BC-GPLVM of 350 frames: 316
against 805) and more on one (a GPDM of 1000 frames: 1990 against 758; 840 with 10 pairs).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp

from .._custom_types import Array, Float

LBFGS_MEMORY = 100
ARMIJO = 1e-4  # sufficient-decrease constant c1
WOLFE = 0.9  # curvature constant c2 (weak Wolfe), the usual one for quasi-Newton directions
MAX_TRIALS = 20  # trials after which a search takes its longest sufficient decrease
MAX_BACKTRACKS = 40  # trials of one search without any sufficient decrease before the fit stops
CURVATURE_FLOOR = 1e-10


class LBFGSResult(NamedTuple):
    """End of a run: the best (last accepted) point, its loss, the accepted steps, the
    evaluations (trials included) and the loss after each accepted step (NaN beyond)."""

    x: Float[Array, " n"]
    loss: Float[Array, ""]
    steps: Array
    evaluations: Array
    trace: Float[Array, " capacity"]


class LBFGSState(NamedTuple):
    """The loop's whole state, carried from one ``lbfgs_advance`` to the next."""

    x: Array  # last accepted point
    loss: Array
    grad: Array
    direction: Array
    alpha: Array  # the step of the next trial
    low: Array  # the longest trial of this search that met Armijo but not the curvature condition (0: none)
    high: Array  # the shortest trial of this search that failed Armijo (inf: none)
    low_loss: Array  # the loss and gradient at ``low``
    low_grad: Array
    s: Array  # (m, n) memory of steps
    y: Array  # (m, n) memory of gradient changes
    rho: Array  # (m,) 1 / s'y
    filled: Array  # pairs stored (at most m)
    head: Array  # the slot the next pair goes to
    started: Array  # the start point has been evaluated
    steps: Array
    evaluations: Array
    trials: Array  # trials of the current line search
    checkpoint: Array  # the loss at the last convergence check
    done: Array
    trace: Array

    def result(self) -> LBFGSResult:
        """The run's outcome so far."""
        return LBFGSResult(self.x, self.loss, self.steps, self.evaluations, self.trace)


def two_loop_direction(grad, s, y, rho, filled, head):
    """``-H grad`` by the two-loop recursion over the stored pairs (newest first)."""
    m = s.shape[0]
    order = (head - 1 - jnp.arange(m)) % m
    valid = jnp.arange(m) < filled

    def newest_to_oldest(q, i):
        j = order[i]
        a = jnp.where(valid[i], rho[j] * jnp.dot(s[j], q), 0.0)
        return q - a * y[j], a

    q, alphas = jax.lax.scan(newest_to_oldest, grad, jnp.arange(m))
    newest = order[0]
    gamma = jnp.where(filled > 0, jnp.dot(s[newest], y[newest]) / jnp.maximum(jnp.dot(y[newest], y[newest]), 1e-300), 1.0)

    def oldest_to_newest(r, i):
        j = order[m - 1 - i]
        b = rho[j] * jnp.dot(y[j], r)
        return r + jnp.where(valid[m - 1 - i], alphas[m - 1 - i] - b, 0.0) * s[j], None

    r, _ = jax.lax.scan(oldest_to_newest, gamma * q, jnp.arange(m))
    return -r


def lbfgs_init(x0: Float[Array, " n"], *, capacity: int, memory: int = LBFGS_MEMORY) -> LBFGSState:
    """The state before the first evaluation: ``lbfgs_advance`` evaluates ``x0`` first.

    Args:
        x0: (n,) the start point.
        capacity: length of the trace buffer (static, at least the steps the run will take).
        memory: curvature pairs kept.
    """
    n, dtype = x0.shape[0], x0.dtype
    zeros = jnp.zeros(n, dtype)
    # The counters are strongly typed, as the loop returns them: a weakly typed start would make
    # the second piece of a fit (``fit_model(..., progress=True)``) a new program to compile.
    count = lambda: jnp.zeros((), int)  # noqa: E731
    return LBFGSState(
        x=x0, loss=jnp.asarray(jnp.inf, dtype), grad=zeros, direction=zeros, alpha=jnp.asarray(0.0, dtype),
        low=jnp.asarray(0.0, dtype), high=jnp.asarray(jnp.inf, dtype), low_loss=jnp.asarray(jnp.inf, dtype), low_grad=zeros,
        s=jnp.zeros((memory, n), dtype), y=jnp.zeros((memory, n), dtype), rho=jnp.zeros(memory, dtype),
        filled=count(), head=count(), started=jnp.asarray(False), steps=count(),
        evaluations=count(), trials=count(), checkpoint=jnp.asarray(jnp.inf, dtype),
        done=jnp.asarray(False), trace=jnp.full((capacity,), jnp.nan, dtype),
    )


def lbfgs_advance(
    value_and_grad: Callable[[Array], tuple[Array, Array]], state: LBFGSState, *, max_steps, tolerance, target, check_every,
    report: Callable | None = None,
) -> LBFGSState:
    """Run the loop from ``state`` until ``max_steps`` steps in all are accepted or the run is
    done (converged, stalled, or not finite at the start); traceable, to be called under jit.
    A run advanced to 50 steps and then to 100 is the run advanced to 100 at once: the loop
    stops between two iterations and carries everything on in ``state``.

    Args:
        value_and_grad: ``x -> (loss, grad)``.
        state: from ``lbfgs_init`` or an earlier ``lbfgs_advance``.
        max_steps: accepted steps in all at which to stop (traced).
        tolerance: stop when ``check_every`` accepted steps improve the loss by less than this
            (relative); 0 never stops for it (traced).
        target: stop once the loss is at or below this (traced; -inf: never).
        check_every: accepted steps between convergence checks and reports (traced).
        report: ``(steps, loss) -> None`` called (inside jit) at every check and at the end.
    """
    memory, dtype = state.s.shape[0], state.x.dtype

    def cond(c: LBFGSState):
        return (c.steps < max_steps) & ~c.done

    def body(c: LBFGSState):
        trial = c.x + c.alpha * c.direction
        loss, grad = value_and_grad(trial)
        finite = jnp.isfinite(loss) & jnp.all(jnp.isfinite(grad))
        slope = jnp.dot(c.grad, c.direction)
        armijo = finite & (loss <= c.loss + ARMIJO * c.alpha * slope)
        wolfe = jnp.dot(grad, c.direction) >= WOLFE * slope
        # accept a trial that meets both weak Wolfe conditions; after MAX_TRIALS, the longest
        # trial that met the first (``low``)
        take_trial = c.started & armijo & wolfe
        take_low = c.started & ~take_trial & (c.trials + 1 >= MAX_TRIALS) & (c.low > 0)
        accepted = take_trial | take_low
        point = jnp.where(take_low, c.x + c.low * c.direction, trial)
        point_loss = jnp.where(take_low, c.low_loss, loss)
        point_grad = jnp.where(take_low, c.low_grad, grad)
        moved = accepted | ~c.started  # the first evaluation is the start point
        step, change = point - c.x, point_grad - c.grad
        curvature = jnp.dot(step, change)
        store = accepted & (curvature > CURVATURE_FLOOR * jnp.linalg.norm(step) * jnp.linalg.norm(change))
        # one row written in place (the row itself when nothing is stored), not a select of the memory
        s = c.s.at[c.head].set(jnp.where(store, step, c.s[c.head]))
        y = c.y.at[c.head].set(jnp.where(store, change, c.y[c.head]))
        rho = c.rho.at[c.head].set(jnp.where(store, 1.0 / jnp.where(store, curvature, 1.0), c.rho[c.head]))
        head = jnp.where(store, (c.head + 1) % memory, c.head)
        filled = jnp.where(store, jnp.minimum(c.filled + 1, memory), c.filled)
        x = jnp.where(moved, point, c.x)
        new_loss = jnp.where(moved, point_loss, c.loss)
        new_grad = jnp.where(moved, point_grad, c.grad)
        direction = two_loop_direction(new_grad, s, y, rho, filled, head)
        downhill = jnp.dot(direction, new_grad) < 0
        direction = jnp.where(downhill, direction, -new_grad)
        # a fresh search tries the quasi-Newton step; steepest descent a step of length 1 at most
        fresh = jnp.where((filled > 0) & downhill, 1.0, jnp.minimum(1.0, 1.0 / jnp.maximum(jnp.linalg.norm(new_grad), 1e-300)))
        # the search goes on: a trial too long for Armijo bounds the step above, one too short
        # for the curvature condition bounds it below (N&W sec. 3.5, by bisection); with no
        # lower bound yet, backtrack to the minimiser of the quadratic through (0, loss, slope)
        # and the trial, within [0.1, 0.5] of it (N&W eq. 3.57), halving where it is not
        # finite; with no upper bound, double
        short = armijo & ~wolfe
        low = jnp.where(short, c.alpha, c.low)
        high = jnp.where(armijo, c.high, c.alpha)
        quadratic = -slope * c.alpha**2 / (2.0 * (loss - c.loss - slope * c.alpha))
        shrunk = jnp.where(finite & (quadratic > 0.1 * c.alpha) & (quadratic < 0.5 * c.alpha), quadratic, 0.5 * c.alpha)
        searched = jnp.where(jnp.isfinite(high), jnp.where(low > 0, 0.5 * (low + high), shrunk), 2.0 * c.alpha)
        steps = c.steps + accepted.astype(c.steps.dtype)
        trials = jnp.where(moved, 0, c.trials + 1)
        check = accepted & (steps % check_every == 0)
        stalled = check & (tolerance > 0) & (jnp.abs(c.checkpoint - new_loss) <= tolerance * jnp.maximum(1.0, jnp.abs(new_loss)))
        done = stalled | (trials > MAX_BACKTRACKS) | (accepted & (new_loss <= target)) | (~c.started & ~finite)
        if report is not None:
            jax.lax.cond(check | (accepted & (done | (steps == max_steps))), lambda: report(steps, new_loss), lambda: None)
        return LBFGSState(
            x=x, loss=new_loss, grad=new_grad, direction=jnp.where(moved, direction, c.direction),
            alpha=jnp.where(moved, fresh, searched).astype(dtype), low=jnp.where(moved, 0.0, low).astype(dtype),
            high=jnp.where(moved, jnp.inf, high).astype(dtype), low_loss=jnp.where(short, loss, c.low_loss),
            low_grad=jnp.where(short, grad, c.low_grad), s=s, y=y, rho=rho, filled=filled, head=head,
            started=jnp.asarray(True), steps=steps, evaluations=c.evaluations + 1, trials=trials,
            checkpoint=jnp.where(check | ~c.started, new_loss, c.checkpoint), done=done,
            trace=c.trace.at[c.steps].set(jnp.where(accepted, new_loss, c.trace[c.steps])),
        )

    return jax.lax.while_loop(cond, body, state)


def lbfgs_minimise(
    value_and_grad: Callable[[Array], tuple[Array, Array]], x0: Float[Array, " n"], *, max_steps, tolerance, target,
    check_every, capacity: int, memory: int = LBFGS_MEMORY, report: Callable | None = None,
) -> LBFGSResult:
    """Minimise a loss from ``x0`` (a flat vector); traceable, to be called under jit:
    ``lbfgs_init`` then ``lbfgs_advance`` to ``max_steps`` (their arguments).

    Returns:
        an ``LBFGSResult``. A trial whose loss or gradient is not finite is never accepted (the
        step shrinks); a non-finite loss at ``x0`` ends the run at once.
    """
    end = lbfgs_advance(value_and_grad, lbfgs_init(x0, capacity=capacity, memory=memory), max_steps=max_steps,
                        tolerance=tolerance, target=target, check_every=check_every, report=report)
    return end.result()
