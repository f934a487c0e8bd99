"""004's observation model (sec. 6): a volumetric reconstruction of the person from the views'
silhouettes, summarised by Gaussian blobs, and each particle scored by the relative entropy
between its own blobs and those.

1. **Visual hull** (``visual_hull``): voxels of a box about the particles' mean root are kept
   when every camera that sees them sees foreground at their centre. Coarse to fine, as 004
   does: the coarse voxels are tested against silhouettes dilated by each view's footprint of a
   coarse voxel (a test that never drops a voxel the fine test keeps), and only the
   ``max_coarse`` occupied coarse voxels are split into eight fine ones and tested exactly.
2. **Blobs of a pose** (``pose_blobs``): one Gaussian per capsule of the body, at its axis'
   middle, with a solid cylinder's second moments (``L^2/12`` along the axis, ``r^2/4`` across),
   weighted by the capsule's volume: 004's "Gaussian blobs attached to the bones".
3. **Blobs of the evidence** (``fit_blobs``): the same blobs refitted to the occupied voxels by
   a few EM iterations, started from the blobs of each of a few starting poses, the fit whose
   mixture gives the voxels the highest mean log-density kept (004 sec. 6.1 starts from the last
   estimate and the VLMM's prediction: ``filters.RecoveringSIR`` passes both; scored alone,
   ``log_likelihood`` starts from the particles' mean pose, the dynamics' prediction).
4. **Score** (004 eqs. 6-7): ``D(F || G) ~ sum_i alpha_i (KL(f_i || g_i) + ln alpha_i / beta_i)``
   between the particle's mixture F and the evidence's G, blob i against blob i; the particle's
   weight is inversely proportional to it (004), ``ln p = -power * ln D``.

The blobs carry 3-D position only: the library's silhouette scenes have no colour (004's blobs
also carry colour where images exist).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ..body import BodyModel
from ..camera import CameraRig, image_shape, project_points
from ._base import AbstractEvidenceLikelihood

# The best particle's divergence above which a tracker is deemed lost (004 sec. 6.1): above the
# 95th percentile of the frames a tracker followed within 120 mm, near the median of the frames
# it lost (docs/vlmm.md, "Restarting a lost tracker", experiments/vlmm_restart.py).
LOST_DIVERGENCE = 10.0


def voxel_grid(centre: Float[Array, " 3"], size, voxel: float) -> Float[Array, "n 3"]:
    """Centres of the voxels of edge ``voxel`` filling a box of ``size`` (3,) metres about ``centre``."""
    counts = [max(1, round(s / voxel)) for s in size]
    axes = [(jnp.arange(n) - (n - 1) / 2.0) * voxel for n in counts]
    grid = jnp.stack(jnp.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return grid.astype(centre.dtype) + centre


def _lookup(silhouettes, rig, points, threshold):
    """(N, C) whether each view sees foreground at each point (True where the view cannot see
    the point: a camera carves only what it sees)."""
    height, width = silhouettes.shape[1:]
    uv, _, in_front = project_points(rig, points)
    col, row = jnp.round(uv[..., 0]).astype(jnp.int32), jnp.round(uv[..., 1]).astype(jnp.int32)
    inside = in_front & (col >= 0) & (col < width) & (row >= 0) & (row < height)
    views = jnp.arange(silhouettes.shape[0])[None, :]
    values = silhouettes[views, jnp.clip(row, 0, height - 1), jnp.clip(col, 0, width - 1)]
    return jnp.where(inside, values >= threshold, True)


def carve(silhouettes, rig, points, threshold=0.5) -> Array:
    """(N,) whether each point survives every view's silhouette (the brute-force hull test)."""
    return jnp.all(_lookup(silhouettes, rig, points, threshold), axis=1)


def dilate(silhouettes: Float[Array, "views h w"], radii) -> Float[Array, "views h w"]:
    """Each view's silhouette max-pooled over a (2r+1)^2 window, r = ``radii[view]`` (static)."""
    out = []
    for view, r in enumerate(radii):
        window = (2 * int(r) + 1, 2 * int(r) + 1)
        out.append(jax.lax.reduce_window(silhouettes[view], -jnp.inf, jax.lax.max, window, (1, 1), "SAME"))
    return jnp.stack(out)


def footprint_radii(rig: CameraRig, voxel: float, nearest_depth: float | None = None) -> tuple[int, ...]:
    """Per view, the pixel radius within which the centres of a coarse voxel's eight fine voxels
    (edge ``voxel``) project about the coarse centre: ``f voxel sqrt(3) / 2 / depth`` rounded up,
    plus one pixel for rounding to the nearest pixel, at the nearest depth a person is seen from
    (``nearest_depth``; None: each camera's distance to the world origin less 1.7 m, the reach of
    the reconstruction box, and at least 0.5 m)."""
    focal = np.max(np.abs(np.asarray(rig.K)[:, :2, :2]).reshape(rig.num_views, -1), axis=1)
    if nearest_depth is None:
        depth = np.maximum(np.linalg.norm(np.asarray(rig.centers), axis=1) - 1.7, 0.5)
    else:
        depth = np.full(rig.num_views, float(nearest_depth))
    return tuple(int(np.ceil(f * voxel * np.sqrt(3) / 2 / d)) + 1 for f, d in zip(focal, depth))


def visual_hull(silhouettes, rig, centre, *, size=(2.4, 2.4, 2.2), voxel=0.05, max_coarse=1024, radii=None, threshold=0.5):
    """Occupied voxels of the box, coarse to fine (module docstring).

    Args:
        silhouettes: (C, H, W) one frame's silhouettes in [0, 1].
        rig: the cameras.
        centre: (3,) the box's centre, metres.
        size: the box's edges, metres; voxel: the fine voxels' edge, metres (coarse: twice it).
        max_coarse: how many occupied coarse voxels are refined (static): the fine voxels
            number ``8 max_coarse``; beyond it the coarse voxels with most views' support win.
        radii: per-view dilation of the coarse test (static; default ``footprint_radii(rig, voxel)``,
            which reads the rig: give it inside jit).
        threshold: a silhouette value at or above it is foreground.

    Returns:
        ``(points (8 max_coarse, 3), occupied (8 max_coarse,) bool)``.
    """
    coarse = voxel_grid(centre, size, 2 * voxel)
    radii = footprint_radii(rig, voxel) if radii is None else radii
    views = silhouettes.shape[0]
    possible = jnp.all(_lookup(dilate(silhouettes, radii), rig, coarse, threshold), axis=1)
    # Those every view may support first; among them, those whose centre most views see as foreground.
    score = possible * (views + 1) + jnp.sum(_lookup(silhouettes, rig, coarse, threshold), axis=1)
    count = min(max_coarse, coarse.shape[0])
    best, chosen = jax.lax.top_k(score.astype(jnp.float32), count)
    keep = best >= views + 1
    offsets = voxel * (jnp.stack(jnp.meshgrid(*[jnp.array([-0.5, 0.5])] * 3, indexing="ij"), -1).reshape(8, 3))
    fine = (coarse[chosen][:, None, :] + offsets.astype(coarse.dtype)).reshape(-1, 3)
    occupied = carve(silhouettes, rig, fine, threshold) & jnp.repeat(keep, 8)
    return fine, occupied


def pose_blobs(body: BodyModel, poses) -> tuple[Float[Array, "*batch k"], Float[Array, "*batch k 3"], Float[Array, "*batch k 3 3"]]:
    """The Gaussian blobs of poses: one per capsule (module docstring); (weights, means, covariances)."""
    a, b = body.capsules(poses)
    axis = b - a
    length2 = jnp.sum(axis * axis, axis=-1)
    direction = axis / jnp.sqrt(jnp.maximum(length2, 1e-12))[..., None]
    r2 = body.radii ** 2
    along = length2 / 12.0 + r2 / 4.0  # the end caps lengthen a capsule a little
    across = r2 / 4.0
    outer = direction[..., :, None] * direction[..., None, :]
    eye = jnp.eye(3, dtype=a.dtype)
    cov = across[..., None, None] * eye + (along - across)[..., None, None] * outer
    volume = jnp.pi * r2 * jnp.sqrt(jnp.maximum(length2, 0.0)) + 4.0 / 3.0 * jnp.pi * body.radii ** 3
    weights = volume / jnp.sum(volume, axis=-1, keepdims=True)
    return weights, 0.5 * (a + b), cov


def _inverse_and_logdet(m):
    """Inverse and log-determinant of symmetric positive-definite 3x3 matrices by the
    adjugate (batched XLA factorisations of many 3x3 matrices are slow on a CPU)."""
    a, b, c = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    d, e, f = m[..., 1, 1], m[..., 1, 2], m[..., 2, 2]
    A, B, C = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * A + b * B + c * C
    D, E, F = a * f - c * c, b * c - a * e, a * d - b * b
    adjugate = jnp.stack([jnp.stack([A, B, C], -1), jnp.stack([B, D, E], -1), jnp.stack([C, E, F], -1)], -2)
    positive = det > 0
    safe = jnp.where(positive, det, 1.0)
    return adjugate / safe[..., None, None], jnp.where(positive, jnp.log(safe), jnp.inf)


def _log_gauss(points, means, covs):
    """(N, K) ln N(points_n; mean_k, cov_k)."""
    inverse, logdet = _inverse_and_logdet(covs)
    diff = points[:, None, :] - means[None]
    return -0.5 * (3 * jnp.log(2 * jnp.pi) + jnp.einsum("nki,kij,nkj->nk", diff, inverse, diff) + logdet[None])


def fit_blobs(points, mask, weights, means, covs, *, iterations: int = 5, floor: float = 1e-4):
    """EM of a K-blob mixture on the masked points, from (weights, means, covs); a blob that
    loses every point keeps its start. Returns the fitted (weights, means, covs)."""
    m = mask.astype(points.dtype)
    eye = jnp.eye(3, dtype=points.dtype)

    def step(_, carry):
        w, mu, s = carry
        log_r = jnp.log(jnp.maximum(w, 1e-30))[None] + _log_gauss(points, mu, s)
        r = jax.nn.softmax(log_r, axis=1) * m[:, None]
        r = jnp.where(jnp.isfinite(r), r, 0.0)
        nk = jnp.sum(r, axis=0)
        alive = nk > 1e-3
        new_mu = (r.T @ points) / jnp.maximum(nk, 1e-12)[:, None]
        diff = points[:, None, :] - new_mu[None]
        new_s = jnp.einsum("nk,nki,nkj->kij", r, diff, diff) / jnp.maximum(nk, 1e-12)[:, None, None] + floor * eye
        mu = jnp.where(alive[:, None], new_mu, mu)
        s = jnp.where(alive[:, None, None], new_s, s)
        w = jnp.where(alive, nk, 0.0) / jnp.maximum(jnp.sum(nk), 1e-12)
        return w, mu, s

    return jax.lax.fori_loop(0, iterations, step, (weights, means, covs))


def gaussian_kl(mean_f, cov_f, mean_g, cov_g):
    """KL(N(mean_f, cov_f) || N(mean_g, cov_g)) of 3-D Gaussians (004 eq. 7), batched over leading axes."""
    d = mean_f.shape[-1]
    if d != 3:
        raise ValueError(f"gaussian_kl works on 3-D blobs, got {d}-D")
    inv_g, logdet_g = _inverse_and_logdet(cov_g)
    _, logdet_f = _inverse_and_logdet(cov_f)
    diff = mean_g - mean_f
    trace = jnp.sum(inv_g * cov_f, axis=(-2, -1))
    return 0.5 * (logdet_g - logdet_f - d + trace + jnp.einsum("...i,...ij,...j->...", diff, inv_g, diff))


def mixture_kl(alpha, mean_f, cov_f, beta, mean_g, cov_g):
    """004 eq. 6: ``sum_i alpha_i (KL(f_i || g_i) + ln alpha_i / beta_i)``, component i matched
    with component i (Goldberger et al.'s approximation for non-overlapping components)."""
    ratio = jnp.log(jnp.maximum(alpha, 1e-30)) - jnp.log(jnp.maximum(beta, 1e-30))
    return jnp.sum(alpha * (gaussian_kl(mean_f, cov_f, mean_g, cov_g) + ratio), axis=-1)


def mixture_log_density(points, mask, weights, means, covs) -> Float[Array, ""]:
    """Mean over the masked points of ``ln sum_k w_k N(point; mean_k, cov_k)`` (nats): how well a
    blob mixture explains the occupied voxels, EM's own objective."""
    log_r = jnp.log(jnp.maximum(weights, 1e-30))[None] + _log_gauss(points, means, covs)
    per_point = jax.scipy.special.logsumexp(log_r, axis=1)
    m = mask.astype(points.dtype)
    return jnp.sum(jnp.where(mask, per_point, 0.0)) / jnp.maximum(jnp.sum(m), 1.0)


class BlobEvidence(eqx.Module):
    """A frame's evidence (module docstring, step 3): the blobs fitted from each of S starts.

    Attributes:
        weights, means, covariances: (S, K), (S, K, 3), (S, K, 3, 3) the blobs fitted to the
            voxels from each start.
        fit: (S,) the mean log-density of the occupied voxels under each (nats,
            ``mixture_log_density``).
        occupied: how many voxels the hull kept.
    """

    weights: Float[Array, "s k"]
    means: Float[Array, "s k 3"]
    covariances: Float[Array, "s k 3 3"]
    fit: Float[Array, " s"]
    occupied: Array


class BlobLikelihood(AbstractEvidenceLikelihood):
    """004 sec. 6's likelihood (module docstring).

    Attributes:
        body: the capsule body whose blobs are scored.
        rig: the cameras.
        power: ``ln p = -power * ln D(F || G)`` (004: weights inversely proportional to D, 1).
        voxel: the fine voxels' edge, metres (static).
        size: the reconstruction box's edges, metres (static).
        max_coarse: coarse voxels refined per frame (static).
        radii: per-view dilation of the coarse test, pixels (static).
        iterations: EM iterations of the evidence's blobs (static).
        select: which of several starts' fits scores the poses: "fit" (the one that explains
            the voxels best) or "particles" (the one the best pose scores highest on) (static).
        lost_divergence: the best particle's ``D(F || G)`` above which a filter that can restart
            deems itself lost (static; None: never; ``lost_below``).
    """

    body: BodyModel
    rig: CameraRig
    power: Float[Array, ""]
    voxel: float = eqx.field(static=True)
    size: tuple[float, float, float] = eqx.field(static=True)
    max_coarse: int = eqx.field(static=True)
    radii: tuple[int, ...] = eqx.field(static=True)
    iterations: int = eqx.field(static=True)
    lost_divergence: float | None = eqx.field(static=True, default=None)
    select: str = eqx.field(static=True, default="fit")

    @property
    def lost_below(self) -> float | None:
        """``-power ln lost_divergence``: the log-likelihood of a particle at that divergence."""
        return None if self.lost_divergence is None else float(-self.power * np.log(self.lost_divergence))

    def evidence(self, observed, centre):
        """The visual hull's voxels about ``centre`` (3,): ``(points, occupied)``."""
        return visual_hull(observed, self.rig, centre, size=self.size, voxel=self.voxel, max_coarse=self.max_coarse,
                           radii=self.radii)

    def fit_evidence(self, observed, starts) -> BlobEvidence:
        """The hull about the starts' mean root, and the blobs fitted to it from the blobs of each
        start pose (S, D)."""
        dtype = starts.dtype
        points, occupied = self.evidence(observed, jnp.mean(starts[:, :3], axis=0))
        points = points.astype(dtype)
        fits = jax.vmap(lambda w, mu, s: fit_blobs(points, occupied, w, mu, s, iterations=self.iterations))(
            *pose_blobs(self.body, starts))
        quality = jax.vmap(lambda w, mu, s: mixture_log_density(points, occupied, w, mu, s))(*fits)
        return BlobEvidence(*fits, jnp.where(jnp.isfinite(quality), quality, -jnp.inf), jnp.sum(occupied))

    def score(self, poses, evidence: BlobEvidence):
        """Each pose against the kept fit: with ``select="fit"`` the fit that explains the voxels
        best (the highest ``fit``), with ``"particles"`` the one the best pose scores highest on."""
        alpha, mean_f, cov_f = pose_blobs(self.body, poses)

        def against(beta, mean_g, cov_g):
            divergence = mixture_kl(alpha, mean_f, cov_f, beta[None], mean_g[None], cov_g[None])
            return -self.power * jnp.log(jnp.maximum(divergence, 1e-6))

        values = jax.vmap(against)(evidence.weights, evidence.means, evidence.covariances)  # (S, N)
        if self.select == "fit":
            best = jnp.argmax(evidence.fit)
        else:
            best = jnp.argmax(jnp.max(jnp.where(jnp.isfinite(values), values, -jnp.inf), axis=1))
        value = values[best]
        has_evidence = evidence.occupied >= 8
        return jnp.where(has_evidence & jnp.isfinite(value), value, jnp.where(has_evidence, -jnp.inf, 0.0))


def make_blob_likelihood(body: BodyModel, rig: CameraRig, *, power: float = 1.0, voxel: float = 0.05,
                         size=(2.4, 2.4, 2.2), max_coarse: int = 1024, iterations: int = 5, nearest_depth: float | None = None,
                         lost_divergence: float | None = LOST_DIVERGENCE, select: str = "fit", dtype=jnp.float32) -> BlobLikelihood:
    """004's blob likelihood (module docstring); ``nearest_depth``: the closest a camera comes to
    the person (metres; None: from the rig), which sizes the coarse test's dilation;
    ``lost_divergence`` and ``select`` as ``BlobLikelihood``'s."""
    if not (power > 0 and voxel > 0 and (nearest_depth is None or nearest_depth > 0) and max_coarse >= 1 and iterations >= 1):
        raise ValueError("power, voxel, nearest_depth, max_coarse and iterations must be positive")
    if lost_divergence is not None and not lost_divergence > 0:
        raise ValueError(f"lost_divergence must be positive or None, got {lost_divergence}")
    if select not in ("fit", "particles"):
        raise ValueError(f"select must be 'fit' or 'particles', got {select!r}")
    if len(tuple(size)) != 3 or min(size) <= 2 * voxel:
        raise ValueError(f"size must be three box edges over two voxels long, got {size}")
    image_shape(rig)
    return BlobLikelihood(body=body, rig=rig, power=jnp.asarray(power, dtype), voxel=float(voxel),
                          size=tuple(float(s) for s in size), max_coarse=int(max_coarse),
                          radii=footprint_radii(rig, voxel, nearest_depth), iterations=int(iterations),
                          lost_divergence=None if lost_divergence is None else float(lost_divergence), select=select)
