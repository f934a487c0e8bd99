"""GPLVM fitting time: jaxtrack (L-BFGS, jitted, float64), compile and steady state separated,
and GPy on the same data and kernel when it is installed (optional; skipped otherwise).

    taskset -c 0,1 python benchmarks/bench_manifold.py --frames 350 1000 --steps 200

Data: joint angles of synthetic walks and jogs (subject S1..S3), 26 dimensions, latent dim 2.
Prints one JSON line per (implementation, N).
"""

from __future__ import annotations

import argparse
import json
import os
import time


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, nargs="+", default=[350, 1000])
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--threads", type=int, default=os.cpu_count())
    args = parser.parse_args()
    os.environ.setdefault("XLA_FLAGS", f"--xla_cpu_multi_thread_eigen=true intra_op_parallelism_threads={args.threads}")
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack.data import generate_motion
    from jaxtrack.manifold import fit_model, make_gplvm

    for n in args.frames:
        parts = []
        for i, (gait, subject) in enumerate([("walk", "S1"), ("jog", "S2"), ("walk", "S3"), ("jog", "S1")]):
            m = generate_motion(gait, subject, num_frames=n // 4 + 1, fps=30.0, key=jax.random.key(i), dtype=jnp.float64)
            parts.append(m.pose[:, 6:])
        Y = np.concatenate(parts)[:n]
        model = make_gplvm(Y, 2)
        start = time.perf_counter()
        fit_model(model, max_steps=50, chunk=50)  # compiles
        first = time.perf_counter() - start
        start = time.perf_counter()
        fitted, info = fit_model(model, max_steps=args.steps, chunk=50, tolerance=0.0)
        steady = time.perf_counter() - start
        print(json.dumps({"impl": "jaxtrack", "N": n, "steps": info.steps, "first_call_s (compile + 50 steps)": round(first, 2),
                          "fit_s": round(steady, 2), "s_per_step": round(steady / info.steps, 4), "objective": round(info.objective, 2)}))
        try:
            import GPy
        except Exception as err:  # GPy is optional and often fails to build
            print(json.dumps({"impl": "GPy", "N": n, "skipped": f"GPy not importable: {type(err).__name__}"}))
            continue
        Yn = np.asarray(model.data)
        kernel = GPy.kern.RBF(2) + GPy.kern.Bias(2)
        gp = GPy.models.GPLVM(Yn, 2, X=np.asarray(model.latent), kernel=kernel)
        start = time.perf_counter()
        gp.optimize(max_iters=args.steps, messages=False)
        print(json.dumps({"impl": "GPy", "N": n, "fit_s": round(time.perf_counter() - start, 2), "objective": round(float(-gp.objective_function() - 0.5 * np.sum(gp.X.values ** 2)), 2)}))


if __name__ == "__main__":
    main()
