"""What a likelihood gradient costs, in likelihood evaluations: the ``GRADIENT_COST`` that
gradient-refined particles are charged (``jaxtrack.tracking.Budget``).

The silhouette log-likelihood of N particles in 4 views at 80x60 (the demo's jog, frame 3), and
its value and gradient with respect to the poses (one reverse pass), both jitted; compile time
(first call) apart from the steady state (median of ``--repeats`` calls). The reference, run in
the same process, is the evaluation itself: each row carries ``gradient_ms / evaluation_ms``.
Also timed: the same gradient by plain autodiff of the unrolled capsule union (the dense
reference, what ``union_statistics``'s backward pass replaces).

    taskset -c 0,1 python benchmarks/bench_gradient.py --particles 60 100 300 --json gradient.json
"""

from __future__ import annotations

import argparse
import json
import time

from bench_output import pin_threads, write_json


def timed(fn, *args, repeats):
    import jax
    import numpy as np

    start = time.perf_counter()
    jax.block_until_ready(fn(*args))
    compile_s = time.perf_counter() - start
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - start)
    return compile_s, 1000 * float(np.median(times))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--particles", type=int, nargs="+", default=[60, 100, 300])
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--json", help="also write the rows to this JSON file")
    args = parser.parse_args()
    pin_threads(args.threads)
    import jax
    import jax.numpy as jnp

    from jaxtrack.demo import demo_sequences
    from jaxtrack.render import capsule_union, project_capsules
    from jaxtrack.tracking import prepare_test

    key = jax.random.key(0)
    _, _, test, _ = demo_sequences(key, test_frames=10)
    scene = prepare_test(test[1], "S2 jog", key=key, frames=10)
    likelihood, observed = scene.likelihood, scene.observations[3]
    views, height, width = observed.shape

    def value_and_gradient(poses):
        values, pullback = jax.vjp(lambda p: likelihood(p, observed), poses)
        return values, pullback(jnp.ones_like(values))[0]

    def plain_autodiff(poses):
        # Reverse mode through the unrolled union itself, over every pixel (the former gradient path).
        def statistics(p):
            caps = project_capsules(likelihood.body, likelihood.rig, p)
            v, u = jnp.meshgrid(jnp.arange(height, dtype=p.dtype), jnp.arange(width, dtype=p.dtype), indexing="ij")
            sil = capsule_union(caps, u.ravel(), v.ravel(), likelihood.edge_width.astype(p.dtype))
            return jnp.sum(sil) + jnp.sum(sil * observed.reshape(views, -1))

        return jax.grad(statistics)(poses)

    rows = []
    for n in args.particles:
        poses = scene.initial_pose + 0.05 * jax.random.normal(jax.random.fold_in(key, n), (n, scene.initial_pose.shape[0]))
        eval_compile, eval_ms = timed(jax.jit(lambda p: likelihood(p, observed)), poses, repeats=args.repeats)
        grad_compile, grad_ms = timed(jax.jit(value_and_gradient), poses, repeats=args.repeats)
        plain_compile, plain_ms = timed(jax.jit(plain_autodiff), poses, repeats=args.repeats)
        row = {"particles": n, "window": list(likelihood.window), "evaluation_ms": round(eval_ms, 3), "gradient_ms": round(grad_ms, 3),
               "gradient_cost": round(grad_ms / eval_ms, 1), "plain_autodiff_ms": round(plain_ms, 3),
               "plain_autodiff_cost": round(plain_ms / eval_ms, 1), "compile_s": {"evaluation": round(eval_compile, 2),
               "gradient": round(grad_compile, 2), "plain_autodiff": round(plain_compile, 2)}, "threads": args.threads,
               "backend": jax.default_backend()}
        print(json.dumps(row), flush=True)
        rows.append(row)
    write_json(rows, args.json)


if __name__ == "__main__":
    main()
