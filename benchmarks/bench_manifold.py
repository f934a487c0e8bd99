"""GPLVM fitting time: jaxtrack (L-BFGS, jitted, float64), compile and steady state separated,
against GPy on the same data, kernel (RBF + bias + Gaussian noise), initial latent points and
prior (a unit Gaussian on Z, as 000 eq. 16), when GPy is installed (``pip install -e ".[bench]"``;
skipped otherwise); and the sparse GPLVM (inducing points, Titsias bound) at larger N.

    taskset -c 0,1 python benchmarks/bench_manifold.py --frames 350 1000 3000 --sparse-frames 3000 10000

Data: joint angles of synthetic walks and jogs (subjects S1..S3), 26 dimensions, latent dim 2.
Prints one JSON line per (implementation, N). Objectives are ``ln p(Y|Z) - 1/2 ||Z||^2``
(the sparse one a lower bound of it), higher is better.
"""

from __future__ import annotations

import argparse
import json
import os
import time


def training_data(n):
    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack.data import generate_motion

    combos = [("walk", "S1"), ("jog", "S2"), ("walk", "S3"), ("jog", "S1")]
    parts = []
    for i, (gait, subject) in enumerate(combos):
        m = generate_motion(gait, subject, num_frames=n // len(combos) + 1, fps=30.0, key=jax.random.key(i), dtype=jnp.float64)
        parts.append(np.asarray(m.pose[:, 6:]))
    return np.concatenate(parts)[:n]


def time_fit(model, steps, chunk):
    from jaxtrack.manifold import fit_model

    start = time.perf_counter()
    fit_model(model, max_steps=chunk, chunk=chunk)  # compiles, and runs one chunk
    first = time.perf_counter() - start
    start = time.perf_counter()
    _, info = fit_model(model, max_steps=steps, chunk=chunk, tolerance=0.0)
    steady = time.perf_counter() - start
    return first, steady, info


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, nargs="*", default=[350, 1000, 3000], help="N for the exact GPLVM and GPy")
    parser.add_argument("--sparse-frames", type=int, nargs="*", default=[3000, 10000], help="N for the sparse GPLVM")
    parser.add_argument("--inducing", type=int, default=150)
    parser.add_argument("--steps", type=int, default=100, help="optimiser iterations (both libraries)")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, str(args.threads))
    os.environ.setdefault("XLA_FLAGS", f"--xla_cpu_multi_thread_eigen=true intra_op_parallelism_threads={args.threads}")
    import jax

    jax.config.update("jax_enable_x64", True)
    import numpy as np

    from jaxtrack.manifold import make_gplvm, make_sparse_gplvm

    chunk = 25
    for n in args.frames:
        Y = training_data(n)
        model = make_gplvm(Y, 2)
        first, steady, info = time_fit(model, args.steps, chunk)
        print(json.dumps({"impl": "jaxtrack GPLVM", "N": n, "steps": info.steps, "compile_plus_first_chunk_s": round(first, 2),
                          "fit_s": round(steady, 2), "s_per_step": round(steady / info.steps, 4),
                          "objective": round(info.objective, 2)}), flush=True)
        try:
            import GPy
        except Exception as err:  # noqa: BLE001  GPy is optional; any failure to import it (a build error included) skips it
            print(json.dumps({"impl": "GPy GPLVM", "N": n, "skipped": f"GPy not importable: {type(err).__name__}"}), flush=True)
            continue
        k = model.kernel
        kernel = GPy.kern.RBF(2, variance=float(k.beta), lengthscale=float(k.gamma) ** -0.5) + GPy.kern.Bias(2, variance=float(k.beta0))
        gp = GPy.models.GPLVM(np.asarray(model.data), 2, X=np.asarray(model.latent), kernel=kernel)
        gp.likelihood.variance = float(k.noise)
        gp.X.set_prior(GPy.priors.Gaussian(0.0, 1.0), warning=False)
        start = time.perf_counter()
        gp.optimize("lbfgsb", max_iters=args.steps, messages=False)
        elapsed = time.perf_counter() - start
        # GPy's objective includes the Gaussian prior's normalising constant; remove it to compare.
        objective = -float(gp.objective_function()) + 0.5 * gp.X.size * np.log(2 * np.pi)
        print(json.dumps({"impl": "GPy GPLVM", "N": n, "max_iters": args.steps, "fit_s": round(elapsed, 2),
                          "objective": round(objective, 2)}), flush=True)
    for n in args.sparse_frames:
        Y = training_data(n)
        model = make_sparse_gplvm(Y, 2, num_inducing=min(args.inducing, n))
        first, steady, info = time_fit(model, args.steps, chunk)
        print(json.dumps({"impl": f"jaxtrack SparseGPLVM (M={model.inducing.shape[0]})", "N": n, "steps": info.steps,
                          "compile_plus_first_chunk_s": round(first, 2), "fit_s": round(steady, 2),
                          "s_per_step": round(steady / info.steps, 4), "objective (bound)": round(info.objective, 2)}), flush=True)


if __name__ == "__main__":
    main()
