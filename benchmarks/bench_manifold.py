"""GP-LVM fitting: jaxtrack's jitted L-BFGS (one ``lax.while_loop``, float64) against GPy on the
same objective, data and starting point, and against a plain reference of our own where GPy has
no such model (the GPDM).

    taskset -c 0,1 python benchmarks/bench_manifold.py --json manifold.json

Protocol, per (model, N):
1. The reference fits first: GPy's L-BFGS-B (SciPy) with ``--evaluations`` objective evaluations
   (GPy's ``max_iters``), under the BLAS thread count (1 or ``--threads``) a short fit found
   faster for it on this problem; or, for the GPDM, SciPy's L-BFGS-B on a jitted ``value_and_grad`` of
   jaxtrack's own objective (one host round-trip per evaluation: the plain way to do it).
2. jaxtrack fits from the same start, its JAX caches cleared, until it reaches the reference's
   objective (``fit_model(target=...)``; at most three L-BFGS steps per evaluation the
   reference had): ``jaxtrack_wall_s``, compile included. Its BLAS library runs one thread
   (``fit_model``'s default ``blas_threads=1``: XLA runs its own thread pool).
3. Compile time alone (``jaxtrack_compile_s``): a cold fit of 10 steps less a warm one.
   Every fit (GPy's, the reference's, jaxtrack's) that takes under 15 s is timed three times and
   its median reported (``*_wall_s_runs`` holds each): short fits are what the machine's noise
   moves most.
4. Steps 2 and 3 again with ``optimiser="optax"`` (optax's L-BFGS, zoom line search: the fit
   before the one-evaluation loop), the ``optax_*`` entries: before and after in one process.

Both final objectives are evaluated by jaxtrack's ``objective()`` on the final parameters (GPy's
converted), so they are the same function evaluated the same way: ``ln p(Y|Z) - 1/2 ||Z||^2``
(000 eq. 16) for the GPLVM and the BC-GPLVM, its Titsias bound for the sparse GPLVM, the log
posterior of 001 eq. 11 for the GPDM; higher is better. GPy's BCGPLVM gets the same Gaussian
prior on Z and a kernel back-constraint with a bias (000 eq. 22), as jaxtrack's has.

Also measured in the same process: the float64 matmul rate (``matmul_gflops``), and for the
exact models the rate of the least dense linear algebra an evaluation needs (N^3 flops:
Cholesky, triangular inverse and ``K^-1``, a third each) against it. Data: joint angles of synthetic walks and jogs (subjects S1..S3), 26
dimensions, latent dimension 2 (the GPDM: four sequences).
"""

from __future__ import annotations

import argparse
import os
import time

from bench_output import pin_threads, write_json

EXACT_MODELS = ("gplvm", "bc-gplvm", "gpdm")


def training_sequences(n):
    """Four walk/jog sequences (N/4 frames each, 30 Hz), joint angles only."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from jaxtrack.data import generate_motion

    combos = [("walk", "S1"), ("jog", "S2"), ("walk", "S3"), ("jog", "S1")]
    lengths = [n // 4 + (i < n % 4) for i in range(4)]
    return [
        np.asarray(generate_motion(gait, subject, num_frames=length, fps=30.0, key=jax.random.key(i), dtype=jnp.float64).pose[:, 6:])
        for i, ((gait, subject), length) in enumerate(zip(combos, lengths))
    ]


def training_data(n):
    import numpy as np

    return np.concatenate(training_sequences(n))


def make_model(name, n, inducing):
    from jaxtrack.manifold import make_bc_gplvm, make_gpdm, make_gplvm, make_sparse_gplvm

    if name == "gpdm":
        return make_gpdm(training_sequences(n), 2)
    Y = training_data(n)
    if name == "gplvm":
        return make_gplvm(Y, 2)
    if name == "bc-gplvm":
        return make_bc_gplvm(Y, 2)
    return make_sparse_gplvm(Y, 2, num_inducing=min(inducing, n))


SHORT_FIT_S = 15.0  # fits shorter than this are timed three times (the median is reported)

# --------------------------------------------------------------------------- GPy, same objective


def _gpy_kernel(GPy, k):
    return GPy.kern.RBF(2, variance=float(k.beta), lengthscale=float(k.gamma) ** -0.5) + GPy.kern.Bias(2, variance=float(k.beta0))


def _kernel_from_gpy(gp, dtype):
    import jax.numpy as jnp

    from jaxtrack.manifold import RBFBiasKernel

    rbf, bias = gp.kern.parts
    logs = [rbf.variance.item(), rbf.lengthscale.item() ** -2, bias.variance.item(), gp.likelihood.variance.item()]
    return RBFBiasKernel(*[jnp.log(jnp.asarray(v, dtype)) for v in logs])


def gpy_model(GPy, model, name):
    """GPy's model of the same objective from jaxtrack's starting point, and a function that
    converts its fitted parameters back into a jaxtrack model."""
    import equinox as eqx
    import jax.numpy as jnp
    import numpy as np

    k, Y, dtype = model.kernel, np.asarray(model.data), model.data.dtype
    if name == "gplvm":
        gp = GPy.models.GPLVM(Y, 2, X=np.asarray(model.latent), kernel=_gpy_kernel(GPy, k))
        gp.X.set_prior(GPy.priors.Gaussian(0.0, 1.0), warning=False)

        def back(gp):
            return eqx.tree_at(lambda m: (m.latent, m.kernel), model, (jnp.asarray(gp.X.values, dtype), _kernel_from_gpy(gp, dtype)))
    elif name == "bc-gplvm":
        gp = _gpy_bcgplvm(GPy, model)

        def back(gp):
            bc = eqx.tree_at(lambda b: (b.weights, b.bias), model.back, (jnp.asarray(gp.mapping.A.values, dtype),
                                                                          jnp.asarray(gp.mapping.b.values, dtype)))
            return eqx.tree_at(lambda m: (m.back, m.kernel), model, (bc, _kernel_from_gpy(gp, dtype)))
    else:
        gp = GPy.models.SparseGPLVM(Y, 2, X=np.asarray(model.latent), kernel=_gpy_kernel(GPy, k), num_inducing=model.inducing.shape[0])
        gp.Z[:] = np.asarray(model.inducing)
        gp.X.set_prior(GPy.priors.Gaussian(0.0, 1.0), warning=False)

        def back(gp):
            return eqx.tree_at(lambda m: (m.latent, m.inducing, m.kernel), model,
                               (jnp.asarray(gp.X.values, dtype), jnp.asarray(gp.Z.values, dtype), _kernel_from_gpy(gp, dtype)))
    gp.likelihood.variance = float(k.noise)
    return gp, back


def _gpy_bcgplvm(GPy, model):
    """GPy's BCGPLVM with 000 eq. 22's back-constraint ``Z = k_x(Y, Y) A + b`` (GPy's kernel
    mapping has no bias) and the unit Gaussian prior on Z that GPy's BCGPLVM leaves out."""
    import numpy as np
    from GPy.core import Mapping, Param

    class KernelMappingWithBias(Mapping):
        def __init__(self, inputs, gamma_x, weights, bias):
            super().__init__(inputs.shape[1], weights.shape[1], name="kernmap")
            self.kern = GPy.kern.RBF(inputs.shape[1], variance=1.0, lengthscale=gamma_x**-0.5)
            self.inputs = inputs
            self.A = Param("A", weights.copy())
            self.b = Param("b", bias.copy())
            self.link_parameters(self.A, self.b)

        def f(self, X):
            return self.kern.K(X, self.inputs) @ self.A + self.b

        def update_gradients(self, dL_dF, X):
            self.A.gradient = self.kern.K(self.inputs, X) @ dL_dF
            self.b.gradient = dL_dF.sum(0)

    class PriorBCGPLVM(GPy.models.BCGPLVM):
        def log_likelihood(self):
            return super().log_likelihood() - 0.5 * float(np.sum(self.X**2))

        def parameters_changed(self):
            self.X = self.mapping.f(self.Y)
            GPy.core.GP.parameters_changed(self)
            Xgradient = self.kern.gradients_X(self.grad_dict["dL_dK"], self.X, None) - self.X
            self.mapping.update_gradients(Xgradient, self.Y)

    back = model.back
    mapping = KernelMappingWithBias(np.asarray(back.inputs), float(back.gamma_x), np.asarray(back.weights), np.asarray(back.bias))
    return PriorBCGPLVM(np.asarray(model.data), 2, kernel=_gpy_kernel(GPy, model.kernel), mapping=mapping)


def gpy_blas_threads(GPy, model, name, max_threads, evaluations=20):
    """The BLAS thread count under which GPy is faster on this problem (1 or ``max_threads``),
    from a short fit under each: GPy runs at its best."""
    from threadpoolctl import threadpool_limits

    times = {}
    for threads in sorted({1, max_threads}):
        gp, _ = gpy_model(GPy, model, name)
        with threadpool_limits(threads, user_api="blas"):
            start = time.perf_counter()
            gp.optimize("lbfgsb", max_iters=evaluations, messages=False)
            times[threads] = time.perf_counter() - start
    return min(times, key=times.get)


def median_wall(run, repeats):
    """``run() -> (wall seconds, result)``: the first result and the median wall time, over
    ``repeats`` runs when the first takes under ``SHORT_FIT_S`` seconds (short fits are the
    ones the machine's noise moves most), else the one."""
    import numpy as np

    wall, result = run()
    walls = [wall] + ([run()[0] for _ in range(repeats - 1)] if wall < SHORT_FIT_S else [])
    return float(np.median(walls)), result, walls


def fit_gpy(GPy, model, name, evaluations, max_threads, repeats=3):
    from threadpoolctl import threadpool_limits

    threads = gpy_blas_threads(GPy, model, name, max_threads)

    def run():
        gp, back = gpy_model(GPy, model, name)  # a fresh model, from the same start, every time
        with threadpool_limits(threads, user_api="blas"):
            start = time.perf_counter()
            gp.optimize("lbfgsb", max_iters=evaluations, messages=False)
            wall = time.perf_counter() - start
        return wall, (gp, back)

    fresh, back = gpy_model(GPy, model, name)
    start_objective = float(back(fresh).objective())
    wall, (gp, back), walls = median_wall(run, repeats)
    return {"reference": f"GPy {GPy.__version__} L-BFGS-B", "reference_start_objective": start_objective,
            "reference_blas_threads": threads, "gpy_wall_s": wall, "gpy_wall_s_runs": walls, "gpy_objective": float(back(gp).objective()),
            "gpy_evaluations": evaluations}


# ------------------------------------------------------------- plain reference (SciPy + jax.grad)


def fit_plain(model, evaluations, repeats=3):
    """SciPy's L-BFGS-B on a jitted ``value_and_grad`` of jaxtrack's objective: the plain
    reference, one host round-trip per evaluation (compile included in its wall time)."""
    import equinox as eqx
    import jax
    import numpy as np
    import scipy.optimize
    from jax.flatten_util import ravel_pytree
    from threadpoolctl import threadpool_limits

    params, static = eqx.partition(model, model.trainable())
    flat, unravel = ravel_pytree(params)

    def run():
        jax.clear_caches()
        value_and_grad = jax.jit(jax.value_and_grad(lambda x: -eqx.combine(unravel(x), static).objective()))

        def function(x):
            value, grad = value_and_grad(x)
            return float(value), np.asarray(grad, np.float64)

        with threadpool_limits(1, user_api="blas"):  # as jaxtrack's fit: XLA runs its own threads
            start = time.perf_counter()
            result = scipy.optimize.minimize(function, np.asarray(flat), jac=True, method="L-BFGS-B",
                                             options={"maxfun": evaluations, "maxiter": evaluations})
            return time.perf_counter() - start, result

    wall, result, walls = median_wall(run, repeats)
    fitted = eqx.combine(unravel(result.x), static)
    return {"reference": "SciPy L-BFGS-B on jax.jit(value_and_grad) (plain)", "reference_start_objective": float(model.objective()),
            "reference_blas_threads": 1, "gpy_wall_s": wall, "gpy_wall_s_runs": walls, "gpy_objective": float(fitted.objective()),
            "gpy_evaluations": int(result.nfev)}


# ------------------------------------------------------------------------------------ jaxtrack


MEMORY = {}  # fit_model's ``memory`` for the default optimiser (``--memory``; empty: its default)


def fit_jaxtrack(model, steps, target=None, optimiser="lbfgs"):
    """A cold fit (JAX's caches cleared first): wall seconds, compile included."""
    import jax

    from jaxtrack.manifold import fit_model

    jax.clear_caches()
    start = time.perf_counter()
    options = MEMORY if optimiser == "lbfgs" else {}
    fitted, info = fit_model(model, max_steps=steps, tolerance=0.0, target=target, optimiser=optimiser, **options)
    return time.perf_counter() - start, fitted, info


def compile_seconds(model, steps=10, optimiser="lbfgs"):
    """Compile time: a cold fit of a few steps less the same fit with the compilation cached
    (the step count is traced, so every fit of this model shares the compilation)."""
    from jaxtrack.manifold import fit_model

    cold, _, _ = fit_jaxtrack(model, steps, optimiser=optimiser)
    start = time.perf_counter()
    fit_model(model, max_steps=steps, tolerance=0.0, optimiser=optimiser, **(MEMORY if optimiser == "lbfgs" else {}))
    return max(cold - (time.perf_counter() - start), 0.0)


def compare(model, name, reference, repeats=3):
    """Steps 2 to 4 of the protocol: jaxtrack's time to the reference's objective."""
    budget = reference["gpy_evaluations"]

    def cold(optimiser):
        def run():
            wall, fitted, info = fit_jaxtrack(model, 3 * budget, target=reference["gpy_objective"], optimiser=optimiser)
            return wall, (fitted, info)

        wall, (fitted, info), walls = median_wall(run, repeats)
        return wall, fitted, info, walls

    wall, fitted, info, walls = cold("lbfgs")
    compile_s = compile_seconds(model)
    # before: optax's L-BFGS (zoom line search), the fit until issue #15's one-evaluation loop
    optax_wall, optax_fitted, optax_info, optax_walls = cold("optax")
    optax_compile_s = compile_seconds(model, optimiser="optax")
    return {
        "model": name, "N": int(model.data.shape[0]),
        **reference,
        "jaxtrack_start_objective": float(model.objective()),
        "jaxtrack_wall_s": wall, "jaxtrack_wall_s_runs": walls, "jaxtrack_compile_s": compile_s,
        "jaxtrack_objective": float(fitted.objective()), "jaxtrack_steps": info.steps, "jaxtrack_evaluations": info.evaluations,
        "jaxtrack_reached_reference": bool(info.objective >= reference["gpy_objective"]),
        "speedup": reference["gpy_wall_s"] / wall,
        "gpy_s_per_evaluation": reference["gpy_wall_s"] / max(budget, 1),
        "jaxtrack_s_per_evaluation": (wall - compile_s) / max(info.evaluations, 1),
        "optax_wall_s": optax_wall, "optax_wall_s_runs": optax_walls, "optax_compile_s": optax_compile_s,
        "optax_objective": float(optax_fitted.objective()),
        "optax_steps": optax_info.steps, "optax_evaluations": optax_info.evaluations,
        "optax_speedup": reference["gpy_wall_s"] / optax_wall,
    }


def matmul_gflops(n=1000, repeats=20):
    """Float64 matmul rate of this process (median of ``repeats``), GFLOP/s."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    a = jax.random.normal(jax.random.key(0), (n, n), jnp.float64)
    f = jax.jit(lambda x: x @ x)
    f(a).block_until_ready()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        f(a).block_until_ready()
        times.append(time.perf_counter() - start)
    return 2 * n**3 / float(np.median(times)) / 1e9


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--models", nargs="*", default=list(EXACT_MODELS), choices=EXACT_MODELS)
    parser.add_argument("--frames", type=int, nargs="*", default=[350, 1000], help="N for the exact models")
    parser.add_argument("--sparse-frames", type=int, nargs="*", default=[3000, 10000], help="N for the sparse GPLVM")
    parser.add_argument("--inducing", type=int, default=100, help="M, the sparse GPLVM's inducing points")
    parser.add_argument("--evaluations", type=int, default=1000, help="the reference's objective evaluations (exact models)")
    parser.add_argument("--sparse-evaluations", type=int, default=300, help="the same for the sparse GPLVM")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--memory", type=int, help="curvature pairs of jaxtrack's own L-BFGS (default: fit_model's, 100)")
    parser.add_argument("--json", metavar="PATH", help="also write the rows to this JSON file")
    args = parser.parse_args()
    if args.memory is not None:
        MEMORY["memory"] = args.memory
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, str(args.threads))
    pin_threads(args.threads)
    import jax

    from jaxtrack.manifold import LBFGS_MEMORY

    jax.config.update("jax_enable_x64", True)
    try:
        import GPy
    except Exception as err:  # noqa: BLE001  GPy is optional; any failure to import it (a build error included) skips it
        GPy = None
        print(f"GPy not importable ({type(err).__name__}): pip install -e '.[bench]'; only the GPDM is compared")

    rows = []
    rate = matmul_gflops()
    print(f"float64 matmul rate in this process: {rate:.1f} GFLOP/s", flush=True)
    jobs = [(name, n) for name in args.models for n in args.frames] + [("sparse-gplvm", n) for n in args.sparse_frames]
    for name, n in jobs:
        model = make_model(name, n, args.inducing)
        if name == "gpdm":
            reference = fit_plain(model, args.evaluations)
        elif GPy is None:
            continue
        else:
            evaluations = args.sparse_evaluations if name == "sparse-gplvm" else args.evaluations
            reference = fit_gpy(GPy, model, name, evaluations, args.threads)
        row = compare(model, name, reference)
        row["matmul_gflops"] = rate
        row["jaxtrack_memory"] = MEMORY.get("memory", LBFGS_MEMORY)
        if name != "sparse-gplvm":  # an exact evaluation needs at least N^3 flops of dense linear algebra
            row["jaxtrack_gflops"] = row["N"] ** 3 / row["jaxtrack_s_per_evaluation"] / 1e9
            row["jaxtrack_fraction_of_matmul_rate"] = row["jaxtrack_gflops"] / rate
        rows.append(row)
        print(f"{name:>12} N={row['N']:>5}  {row['reference'][:24]:<24} {row['gpy_wall_s']:7.2f} s  objective {row['gpy_objective']:10.1f}"
              f"  | jaxtrack {row['jaxtrack_wall_s']:6.2f} s (compile {row['jaxtrack_compile_s']:.2f})"
              f"  objective {row['jaxtrack_objective']:10.1f} in {row['jaxtrack_steps']} steps"
              f"  | {row['speedup']:.1f}x  (optax L-BFGS: {row['optax_wall_s']:.2f} s, compile {row['optax_compile_s']:.2f}, "
              f"{row['optax_steps']} steps, {row['optax_speedup']:.1f}x)", flush=True)
        write_json(rows, args.json)


if __name__ == "__main__":
    main()
