"""The Gaussian mixture EM under 002's RBF networks (``manifold.fit_gaussian_mixture``, run twice
by every GLE, LE or TLE fit: once on the latent points, once on the joint angles) against the
same EM with one linear solve per point and Gaussian (the version before 2026-12-02), in the
same process, on the same data and seed: the median seconds of each, their ratio, and how far
the fitted means and covariances lie apart (relative to their largest entry).

    taskset -c 0,1 python benchmarks/bench_gmm.py --repeats 5 --json gmm.json

Data: what the demo's GLE (3-D) fits its two mixtures on: the training motion's standardised
joint angles (4 synthetic walks and jogs, 320 frames, 26 angles; the inverse network's inputs)
and the GLE's latent points (the forward network's), with 30 Gaussians, the default.
"""

from __future__ import annotations

import argparse

from bench_output import add_output_arguments, median_seconds, pin_threads, write_json


def per_point_solve_em(X, components, *, seed=0, iterations=200, ridge=1e-3, tolerance=1e-8):
    """The reference: ``fit_gaussian_mixture`` with the Mahalanobis distances by one
    ``np.linalg.solve`` per point and Gaussian."""
    import numpy as np

    X = np.asarray(X, np.float64)
    n, d = X.shape
    rng = np.random.default_rng(seed)
    floor = ridge * float(np.mean(X.var(axis=0))) + 1e-12
    centres = [X[rng.integers(n)]]
    for _ in range(components - 1):
        gap = np.min(np.sum((X[:, None] - np.asarray(centres)[None]) ** 2, axis=-1), axis=1)
        centres.append(X[rng.choice(n, p=gap / gap.sum())] if gap.sum() > 0 else X[rng.integers(n)])
    means = np.asarray(centres)
    responsibility = np.eye(components)[np.argmin(np.sum((X[:, None] - means[None]) ** 2, axis=-1), axis=1)]
    previous = -np.inf
    for _ in range(iterations):
        counts = responsibility.sum(axis=0) + 1e-12
        weights = counts / n
        means = responsibility.T @ X / counts[:, None]
        delta = X[:, None, :] - means[None]
        covariances = np.einsum("ng,ngi,ngj->gij", responsibility, delta, delta) / counts[:, None, None] + floor * np.eye(d)
        _, logdet = np.linalg.slogdet(covariances)
        solved = np.linalg.solve(covariances[None], delta[..., None])[..., 0]
        log_density = -0.5 * (np.sum(delta * solved, axis=-1) + logdet[None] + d * np.log(2 * np.pi)) + np.log(weights)[None]
        top = log_density.max(axis=1, keepdims=True)
        log_total = top[:, 0] + np.log(np.exp(log_density - top).sum(axis=1))
        responsibility = np.exp(log_density - log_total[:, None])
        likelihood = float(log_total.mean())
        if likelihood - previous < tolerance * max(1.0, abs(likelihood)):
            break
        previous = likelihood
    return means, covariances, weights


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--components", type=int, default=30, help="Gaussians (the spectral manifolds' default)")
    add_output_arguments(parser)
    args = parser.parse_args()
    pin_threads(args.threads)
    import json

    import jax
    import numpy as np

    from jaxtrack.body import joint_angles
    from jaxtrack.demo import demo_sequences
    from jaxtrack.manifold import fit_gaussian_mixture
    from jaxtrack.tracking import fit_manifold, sequence_poses

    key = jax.random.key(0)
    train, _, _, _ = demo_sequences(key)
    poses = [sequence_poses(s, "train", key=key) for s in train]
    angles = np.concatenate([np.asarray(joint_angles(p)) for p in poses])
    model, _, _ = fit_manifold(poses, 3, 0, kind="gle", key=key)
    latent = np.asarray(model.latent, np.float64)
    scale = angles.std(0)
    standardised = (angles - angles.mean(0)) / np.where(scale > 1e-8, scale, 1.0)  # as ``fit_spectral`` does
    rows = []
    for name, X in (("standardised joint angles", standardised), ("GLE latent points", latent)):
        ours = fit_gaussian_mixture(X, args.components, ridge=0.05)
        reference = per_point_solve_em(X, args.components, ridge=0.05)
        apart = max(float(np.abs(a - b).max() / np.abs(b).max()) for a, b in zip(ours, reference))
        ours_s = median_seconds(lambda X=X: fit_gaussian_mixture(X, args.components, ridge=0.05), args.repeats)
        reference_s = median_seconds(lambda X=X: per_point_solve_em(X, args.components, ridge=0.05), args.repeats)
        row = {"data": name, "points": int(X.shape[0]), "dims": int(X.shape[1]), "components": args.components,
               "repeats": args.repeats, "seconds": ours_s, "per_point_solve_seconds": reference_s,
               "speedup": reference_s / ours_s, "relative_difference": apart}
        print(json.dumps(row))
        rows.append(row)
    write_json(rows, args.json)


if __name__ == "__main__":
    main()
