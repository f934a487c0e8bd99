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


def per_point_solve(covariances, delta):
    """The reference distances: one ``np.linalg.solve`` per point and Gaussian (the EM before
    2026-12-02); ``fit_gaussian_mixture`` runs with it in place of ``squared_mahalanobis``."""
    import numpy as np

    return np.sum(delta * np.linalg.solve(covariances[None], delta[..., None])[..., 0], axis=-1)


def per_point_solve_em(X, components, **options):
    """``fit_gaussian_mixture`` with the reference distances."""
    from jaxtrack.manifold import _rbf

    kept = _rbf.squared_mahalanobis
    _rbf.squared_mahalanobis = per_point_solve
    try:
        return _rbf.fit_gaussian_mixture(X, components, **options)
    finally:
        _rbf.squared_mahalanobis = kept


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
