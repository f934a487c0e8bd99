"""004's observation model (sec. 6): a volumetric reconstruction of the person from the views'
silhouettes, summarised by Gaussian blobs, and each particle scored by the relative entropy
between its own blobs and those.

1. **Visual hull** (``visual_hull``): voxels of a box about the particles' mean root are kept
   when every camera that sees them sees foreground at their centre. Coarse to fine, as 004
   does: the coarse voxels are tested against silhouettes dilated by each view's footprint of a
   coarse voxel (a test that never drops a voxel the fine test keeps), and only the
   ``max_coarse`` occupied coarse voxels are split into eight fine ones and tested exactly.
   Of those, at most ``max_points`` occupied ones go on to the blob fit (``compact_voxels``:
   all of them where they are fewer, an even spread otherwise): a person fills 800-1,200 fine
   voxels of the 8,192 tested, and the fit's cost is per voxel.
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

5. **Colour** (``colour=True``, where the views' images exist; 004 sec. 6.1: "each Gaussian blob
   defines a distribution over 3D position and colour"): each voxel takes the per-channel median
   of the pixels its centre projects to in the views that see it (``voxel_colours``; no
   occlusion test: with three or more views the median outvotes a view where another part
   lies in front); each blob is a Gaussian over position and an independent one over RGB, so
   the evidence's EM reads both (an arm's skin is not the shirt it crosses). The particles'
   blob colours are the person's appearance, measured once at a known pose on one frame
   (``with_reference``: the start pose on the first frame, as 001's histograms and 003's
   templates are; ``blob_colours`` of the pose's blobs).
   Eq. 7 on 004's 6-D blobs is the sum of a position and a colour term; the colour term is
   scored only with ``colour_in_score=True`` (by default colour guides the fit alone: see
   ``BlobLikelihood``).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ..body import BodyModel
from ..camera import CameraRig, image_shape, project_points
from ..errors import TrackingError
from ._base import AbstractEvidenceLikelihood

# The best particle's divergence above which a tracker is deemed lost (004 sec. 6.1): above the
# 95th percentile of the frames a tracker followed within 120 mm, near the median of the frames
# it lost (docs/vlmm.md, "Restarting a lost tracker", experiments/vlmm_restart.py).
LOST_DIVERGENCE = 10.0

# The least variance of a blob's colour in each RGB channel (channels in [0, 1]): (8 levels of
# 255)^2, above a camera's sensor noise (2 levels) and a video codec's smeared chroma, so a blob
# of one flat colour keeps a density a few levels wide.
COLOUR_FLOOR = (8.0 / 255.0) ** 2


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


def voxel_colours(images: Float[Array, "views h w 3"], rig: CameraRig, points: Float[Array, "n 3"]
                  ) -> tuple[Float[Array, "n 3"], Array]:
    """Each point's colour (N, 3): per channel the median of the pixels (rounded) its centre
    projects to in the views that see it in front and inside the image; mid-grey where no view
    does. Returns ``(colours, seen (N,) bool)``."""
    height, width = images.shape[1:3]
    uv, _, in_front = project_points(rig, points)
    col, row = jnp.round(uv[..., 0]).astype(jnp.int32), jnp.round(uv[..., 1]).astype(jnp.int32)
    inside = in_front & (col >= 0) & (col < width) & (row >= 0) & (row < height)
    views = jnp.arange(images.shape[0])[None, :]
    values = images[views, jnp.clip(row, 0, height - 1), jnp.clip(col, 0, width - 1)]  # (N, C, 3)
    seen = jnp.any(inside, axis=1)
    median = jnp.nanmedian(jnp.where(inside[..., None], values, jnp.nan), axis=1)
    return jnp.where(seen[:, None], median, 0.5).astype(points.dtype), seen


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


def compact_voxels(points: Float[Array, "n 3"], occupied, size: int) -> tuple[Float[Array, "size 3"], Array]:
    """At most ``size`` (static) of the occupied points and their mask: every one of them where
    they number ``size`` or fewer; else ``size`` of them spread evenly over the list (each
    voxel ranked by a fixed low-discrepancy priority, ``frac(0.618 i)``), so no region is cut."""
    n = points.shape[0]
    if size >= n:
        return points, occupied
    spread = jnp.mod(jnp.arange(n, dtype=jnp.float32) * 0.6180339887, 1.0)
    _, chosen = jax.lax.top_k(jnp.where(occupied, 1.0 + spread, 0.0), size)
    return points[chosen], occupied[chosen]


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


def fit_blobs(points, mask, weights, means, covs, *, iterations: int = 5, floor: float = 1e-4, colours=None,
              colour_means=None, colour_covs=None, colour_floor: float = COLOUR_FLOOR):
    """EM of a K-blob mixture on the masked points, from (weights, means, covs); a blob that
    loses every point keeps its start. Returns the fitted (weights, means, covs).

    With ``colours`` (N, 3) each blob is also a Gaussian over colour (``colour_means`` (K, 3),
    ``colour_covs`` (K, 3, 3)) independent of its position: the responsibilities read both and
    both are refitted; returns (weights, means, covs, colour_means, colour_covs)."""
    blocks = [(points, floor)] + ([] if colours is None else [(colours, colour_floor)])
    start = (weights, means, covs) + (() if colours is None else (colour_means, colour_covs))
    m = mask.astype(points.dtype)
    eye = jnp.eye(3, dtype=points.dtype)

    def step(_, carry):
        w, pairs = carry[0], [carry[1 + 2 * b : 3 + 2 * b] for b in range(len(blocks))]
        log_r = jnp.log(jnp.maximum(w, 1e-30))[None]
        for (x, _), (mu, s) in zip(blocks, pairs):
            log_r = log_r + _log_gauss(x, mu, s)
        r = jax.nn.softmax(log_r, axis=1) * m[:, None]
        r = jnp.where(jnp.isfinite(r), r, 0.0)
        nk = jnp.sum(r, axis=0)
        alive = nk > 1e-3
        fitted = []
        for (x, least), (mu, s) in zip(blocks, pairs):
            new_mu = (r.T @ x) / jnp.maximum(nk, 1e-12)[:, None]
            diff = x[:, None, :] - new_mu[None]
            new_s = jnp.einsum("nk,nki,nkj->kij", r, diff, diff) / jnp.maximum(nk, 1e-12)[:, None, None] + least * eye
            fitted += [jnp.where(alive[:, None], new_mu, mu), jnp.where(alive[:, None, None], new_s, s)]
        w = jnp.where(alive, nk, 0.0) / jnp.maximum(jnp.sum(nk), 1e-12)
        return (w, *fitted)

    return jax.lax.fori_loop(0, iterations, step, start)


def blob_colours(points, mask, colours, weights, means, covs, *, floor: float = COLOUR_FLOOR):
    """Each blob's colour Gaussian where the blobs' positions are known (a pose's blobs): the
    voxels' responsibilities from position alone, the colours' weighted mean and covariance
    (plus ``floor``). A blob that no voxel supports gets mid-grey and a covariance spanning the
    colour cube, which says little. Returns ``(colour_means (K, 3), colour_covs (K, 3, 3))``."""
    log_r = jnp.log(jnp.maximum(weights, 1e-30))[None] + _log_gauss(points, means, covs)
    r = jax.nn.softmax(log_r, axis=1) * mask.astype(points.dtype)[:, None]
    r = jnp.where(jnp.isfinite(r), r, 0.0)
    nk = jnp.sum(r, axis=0)
    alive = (nk > 1.0)[:, None]
    mean = (r.T @ colours) / jnp.maximum(nk, 1e-12)[:, None]
    diff = colours[:, None, :] - mean[None]
    eye = jnp.eye(3, dtype=points.dtype)
    cov = jnp.einsum("nk,nki,nkj->kij", r, diff, diff) / jnp.maximum(nk, 1e-12)[:, None, None] + floor * eye
    return jnp.where(alive, mean, 0.5), jnp.where(alive[..., None], cov, 0.25 * eye)


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


def mixture_kl(alpha, mean_f, cov_f, beta, mean_g, cov_g, colour=None):
    """004 eq. 6: ``sum_i alpha_i (KL(f_i || g_i) + ln alpha_i / beta_i)``, component i matched
    with component i (Goldberger et al.'s approximation for non-overlapping components).
    ``colour``: ``(colour_mean_f, colour_cov_f, colour_mean_g, colour_cov_g)`` of blobs whose
    colour is independent of their position: their 6-D KL is the two 3-D ones summed."""
    ratio = jnp.log(jnp.maximum(alpha, 1e-30)) - jnp.log(jnp.maximum(beta, 1e-30))
    divergence = gaussian_kl(mean_f, cov_f, mean_g, cov_g)
    if colour is not None:
        divergence = divergence + gaussian_kl(*colour)
    return jnp.sum(alpha * (divergence + ratio), axis=-1)


def mixture_log_density(points, mask, weights, means, covs, colours=None, colour_means=None, colour_covs=None) -> Float[Array, ""]:
    """Mean over the masked points of ``ln sum_k w_k N(point; mean_k, cov_k)`` (nats): how well a
    blob mixture explains the occupied voxels, EM's own objective (with ``colours``, times each
    blob's colour density, as ``fit_blobs``)."""
    log_r = jnp.log(jnp.maximum(weights, 1e-30))[None] + _log_gauss(points, means, covs)
    if colours is not None:
        log_r = log_r + _log_gauss(colours, colour_means, colour_covs)
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
        colour_means, colour_covariances: (S, K, 3), (S, K, 3, 3) the blobs' colours (None
            without colour).
    """

    weights: Float[Array, "s k"]
    means: Float[Array, "s k 3"]
    covariances: Float[Array, "s k 3 3"]
    fit: Float[Array, " s"]
    occupied: Array
    colour_means: Float[Array, "s k 3"] | None = None
    colour_covariances: Float[Array, "s k 3 3"] | None = None


class BlobLikelihood(AbstractEvidenceLikelihood):
    """004 sec. 6's likelihood (module docstring).

    Attributes:
        body: the capsule body whose blobs are scored.
        rig: the cameras.
        power: ``ln p = -power * ln D(F || G)`` (004: weights inversely proportional to D, 1).
        voxel: the fine voxels' edge, metres (static).
        size: the reconstruction box's edges, metres (static).
        max_coarse: coarse voxels refined per frame (static).
        max_points: occupied fine voxels the blobs are fitted to, at most (static; ``compact_voxels``).
        radii: per-view dilation of the coarse test, pixels (static).
        iterations: EM iterations of the evidence's blobs (static).
        select: which of several starts' fits scores the poses: "fit" (the one that explains
            the voxels best) or "particles" (the one the best pose scores highest on) (static).
        lost_divergence: the best particle's ``D(F || G)`` above which a filter that can restart
            deems itself lost (static; None: never; ``lost_below``).
        colour: whether the blobs carry colour (static; module docstring, step 5): a frame's
            observation is then ``{"silhouettes": (C, H, W), "images": (C, H, W, 3)}``, RGB in [0, 1].
        colour_means, colour_covariances: (K, 3), (K, 3, 3) the person's blob colours, the
            particles' (``with_reference``; before it mid-grey and wide).
        colour_in_score: with colour, whether the divergence adds the colour term (static): True
            is 004's 6-D blobs; False (the default) lets colour guide the evidence's fit alone,
            which tracked better (docs/vlmm.md, "Colour in the blobs"): the particles' colours are
            the person's whatever their pose, so the colour term only adds to every particle's
            divergence and flattens the weights.
    """

    body: BodyModel
    rig: CameraRig
    power: Float[Array, ""]
    voxel: float = eqx.field(static=True)
    size: tuple[float, float, float] = eqx.field(static=True)
    max_coarse: int = eqx.field(static=True)
    max_points: int = eqx.field(static=True)
    radii: tuple[int, ...] = eqx.field(static=True)
    iterations: int = eqx.field(static=True)
    lost_divergence: float | None = eqx.field(static=True, default=None)
    select: str = eqx.field(static=True, default="fit")
    colour: bool = eqx.field(static=True, default=False)
    colour_means: Float[Array, "k 3"] | None = None
    colour_covariances: Float[Array, "k 3 3"] | None = None
    colour_in_score: bool = eqx.field(static=True, default=False)

    def __check_init__(self):
        if self.colour and (self.colour_means is None or self.colour_covariances is None):
            raise ValueError("a BlobLikelihood with colour needs colour_means and colour_covariances (make_blob_likelihood)")

    @property
    def lost_below(self) -> float | None:
        """``-power ln lost_divergence``: the log-likelihood of a particle at that divergence."""
        return None if self.lost_divergence is None else float(-self.power * np.log(self.lost_divergence))

    def evidence(self, observed, centre):
        """The visual hull's voxels about ``centre`` (3,), at most ``max_points`` of them:
        ``(points (max_points, 3), occupied)``."""
        points, occupied = visual_hull(observed, self.rig, centre, size=self.size, voxel=self.voxel, max_coarse=self.max_coarse,
                                       radii=self.radii)
        return compact_voxels(points, occupied, self.max_points)

    def _split(self, observed):
        """``(silhouettes (C, H, W), images (C, H, W, 3) or None)`` of one frame's observation."""
        if not self.colour:
            return observed, None
        if not (isinstance(observed, dict) and "silhouettes" in observed and "images" in observed):
            raise TrackingError("a BlobLikelihood with colour reads frames {'silhouettes': (C, H, W), 'images': (C, H, W, 3)}, "
                                f"got {type(observed).__name__}")
        return observed["silhouettes"], observed["images"]

    def fit_evidence(self, observed, starts) -> BlobEvidence:
        """The hull about the starts' mean root, and the blobs fitted to it from the blobs of each
        start pose (S, D) (with colour: from the person's blob colours, the voxels coloured)."""
        dtype = starts.dtype
        silhouettes, images = self._split(observed)
        points, occupied = self.evidence(silhouettes, jnp.mean(starts[:, :3], axis=0))
        points = points.astype(dtype)
        starts_blobs = pose_blobs(self.body, starts)
        if images is None:
            fits = jax.vmap(lambda w, mu, s: fit_blobs(points, occupied, w, mu, s, iterations=self.iterations))(*starts_blobs)
            quality = jax.vmap(lambda w, mu, s: mixture_log_density(points, occupied, w, mu, s))(*fits)
        else:
            colours, _ = voxel_colours(images.astype(dtype), self.rig, points)
            cm, cc = self.colour_means.astype(dtype), self.colour_covariances.astype(dtype)
            fits = jax.vmap(lambda w, mu, s: fit_blobs(points, occupied, w, mu, s, iterations=self.iterations, colours=colours,
                                                       colour_means=cm, colour_covs=cc))(*starts_blobs)
            quality = jax.vmap(lambda w, mu, s, m, c: mixture_log_density(points, occupied, w, mu, s, colours, m, c))(*fits)
        return BlobEvidence(*fits[:3], jnp.where(jnp.isfinite(quality), quality, -jnp.inf), jnp.sum(occupied), *fits[3:])

    def with_reference(self, pose, observation) -> BlobLikelihood:
        """The person's blob colours measured at ``pose`` (D,) on one frame's observation
        (``blob_colours`` on the hull about the pose's root); without colour, itself."""
        if not self.colour:
            return self
        silhouettes, images = self._split(observation)
        pose = jnp.asarray(pose)
        means, covs = eqx.filter_jit(_reference_colours)(self, pose, jnp.asarray(silhouettes), jnp.asarray(images, pose.dtype))
        return eqx.tree_at(lambda l: (l.colour_means, l.colour_covariances), self,
                           (means.astype(self.colour_means.dtype), covs.astype(self.colour_covariances.dtype)))

    def score(self, poses, evidence: BlobEvidence):
        """Each pose against the kept fit: with ``select="fit"`` the fit that explains the voxels
        best (the highest ``fit``), with ``"particles"`` the one the best pose scores highest on."""
        alpha, mean_f, cov_f = pose_blobs(self.body, poses)

        def against(beta, mean_g, cov_g, colour_g=None):
            colour = None
            if colour_g is not None:
                cm, cc = self.colour_means.astype(mean_f.dtype), self.colour_covariances.astype(mean_f.dtype)
                colour = (cm[None], cc[None], colour_g[0][None], colour_g[1][None])
            divergence = mixture_kl(alpha, mean_f, cov_f, beta[None], mean_g[None], cov_g[None], colour)
            return -self.power * jnp.log(jnp.maximum(divergence, 1e-6))

        if evidence.colour_means is None or not self.colour_in_score:
            values = jax.vmap(against)(evidence.weights, evidence.means, evidence.covariances)  # (S, N)
        else:
            values = jax.vmap(lambda b, m, c, cm, cc: against(b, m, c, (cm, cc)))(
                evidence.weights, evidence.means, evidence.covariances, evidence.colour_means, evidence.colour_covariances)
        if self.select == "fit":
            best = jnp.argmax(evidence.fit)
        else:
            best = jnp.argmax(jnp.max(jnp.where(jnp.isfinite(values), values, -jnp.inf), axis=1))
        value = values[best]
        has_evidence = evidence.occupied >= 8
        return jnp.where(has_evidence & jnp.isfinite(value), value, jnp.where(has_evidence, -jnp.inf, 0.0))


def _reference_colours(likelihood: BlobLikelihood, pose, silhouettes, images):
    """``blob_colours`` of ``pose``'s blobs on the hull about its root, the voxels coloured by
    ``images`` (the blobs refitted to the voxels first measured no better: docs/vlmm.md)."""
    points, occupied = likelihood.evidence(silhouettes, pose[:3])
    points = points.astype(pose.dtype)
    colours, _ = voxel_colours(images, likelihood.rig, points)
    return blob_colours(points, occupied, colours, *pose_blobs(likelihood.body, pose))


def make_blob_likelihood(body: BodyModel, rig: CameraRig, *, power: float = 1.0, voxel: float = 0.05,
                         size=(2.4, 2.4, 2.2), max_coarse: int = 1024, max_points: int = 2048, iterations: int = 5,
                         nearest_depth: float | None = None,
                         lost_divergence: float | None = LOST_DIVERGENCE, select: str = "fit", colour: bool = False,
                         colour_in_score: bool = False, dtype=jnp.float32) -> BlobLikelihood:
    """004's blob likelihood (module docstring); ``nearest_depth``: the closest a camera comes to
    the person (metres; None: from the rig), which sizes the coarse test's dilation;
    ``lost_divergence``, ``select``, ``colour`` and ``colour_in_score`` as ``BlobLikelihood``'s (with colour the blobs
    start mid-grey and wide: set the person's colours with ``with_reference``)."""
    if not (power > 0 and voxel > 0 and (nearest_depth is None or nearest_depth > 0) and max_coarse >= 1 and max_points >= 1
            and iterations >= 1):
        raise ValueError("power, voxel, nearest_depth, max_coarse, max_points and iterations must be positive")
    if lost_divergence is not None and not lost_divergence > 0:
        raise ValueError(f"lost_divergence must be positive or None, got {lost_divergence}")
    if select not in ("fit", "particles"):
        raise ValueError(f"select must be 'fit' or 'particles', got {select!r}")
    if len(tuple(size)) != 3 or min(size) <= 2 * voxel:
        raise ValueError(f"size must be three box edges over two voxels long, got {size}")
    image_shape(rig)
    parts = int(np.shape(body.radii)[-1])
    return BlobLikelihood(body=body, rig=rig, power=jnp.asarray(power, dtype), voxel=float(voxel),
                          size=tuple(float(s) for s in size), max_coarse=int(max_coarse), max_points=int(max_points),
                          radii=footprint_radii(rig, voxel, nearest_depth), iterations=int(iterations),
                          lost_divergence=None if lost_divergence is None else float(lost_divergence), select=select,
                          colour=bool(colour), colour_means=jnp.full((parts, 3), 0.5, dtype) if colour else None,
                          colour_covariances=jnp.broadcast_to(0.25 * jnp.eye(3, dtype=dtype), (parts, 3, 3)) if colour else None,
                          colour_in_score=bool(colour_in_score))
