"""Paper 001's image likelihood from edges and the foreground (001 eqs. 12-16, after Deutscher
and Reid): the model's edges should lie on image edges, and its body on the foreground.

For a pose, each capsule k is projected into view c (its axis a -> b, radius r in pixels) and
sampled at ``points`` positions along each of its two outline sides (the hypothesised edges)
and along its axis (inside the part). With ``p_e`` the view's edge-proximity map and ``p_fg`` its
foreground map, read bilinearly at those points,

    Sigma_e  = 1 / (C N_e) sum_c sum_k lambda_kc sum_{outline points} (1 - p_e)^2      (eqs. 14-15)
    lambda_kc = mean over k's outline points of (1 - o)^2                              (eq. 13)
    Sigma_fg = 1 / (C N_fg) sum_c sum_{axis points} (1 - p_fg)^2                       (eq. 16)
    ln p = -scale (Sigma_e + w_fg Sigma_fg)                                            (eq. 19)

where o is the chance that another part covers the outline point: the largest, over the other
capsules nearer the camera, of a soft inside test (a logistic of the radius less the distance to
their projected axis, ``edge_width`` pixels wide). An occluded part's missing edges then cost
little (001's remedy for parts that make no edge). ``visibility="foreground"`` takes o as 001
eq. 13 writes it instead: the foreground map at the outline point, so that an outline lying on
the foreground (a part seen against the body) weighs little. ``scale`` is the temperature (the
experiment's ``--likelihood-scale``); ``foreground_weight`` is w_fg, 1 in 001's eq. 19, which
sums the terms with equal weights (a lower one where the foreground term repeats what another
term already reads: the silhouettes' own likelihood, docs/likelihood.md). Points outside a view read 0 (the worst evidence); a view
behind which the body lies costs the maximum. Smooth in the pose where the maps are, so
gradient-refined moves and the body calibration work with it.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ..body import BodyModel
from ..camera import CameraRig, focal_lengths, project_points
from ..errors import ConfigurationError
from ..image import canny_edges, dilate, edge_proximity, gaussian_blur, sample_bilinear, to_float
from ._base import AbstractLikelihood

DEPTH_SOFTNESS = 0.02  # metres: how sharply "nearer the camera" switches between two parts
VISIBILITY_CHOICES = ("occlusion", "foreground")


def _segment_distance(p, a, b):
    """Distance of points p (..., 2) to segments a -> b (..., 2)."""
    u = b - a
    t = jnp.clip(jnp.sum((p - a) * u, axis=-1) / jnp.maximum(jnp.sum(u * u, axis=-1), 1e-12), 0.0, 1.0)
    return jnp.linalg.norm(p - (a + t[..., None] * u) + 1e-12, axis=-1)


class EdgeForegroundLikelihood(AbstractLikelihood):
    """Attributes:
        body: the capsule body whose outlines and axes are sampled.
        rig: the cameras (C views).
        scale: the temperature, ``ln p = -scale (Sigma_e + Sigma_fg)``.
        points: sample points per outline side and per axis of each capsule.
        edge_width: pixels over which the occlusion test goes from inside to outside.
        use_edges, use_foreground: which of the two terms to score (001 sums both).
        foreground_weight: the foreground term's weight against the edge term's (001: 1).
        visibility: what covers an outline point in eq. 13, "occlusion" (the other capsules) or
            "foreground" (the foreground map, as 001 writes it); module docstring.

    A frame's observation is ``{"edges": (C, H, W), "foreground": (C, H, W)}``, maps in [0, 1]
    (``image.edge_proximity``; a foreground probability or a binary silhouette, blurred).
    """

    body: BodyModel
    rig: CameraRig
    scale: Float[Array, ""]
    points: int = eqx.field(static=True, default=6)
    edge_width: float = eqx.field(static=True, default=1.0)
    use_edges: bool = eqx.field(static=True, default=True)
    use_foreground: bool = eqx.field(static=True, default=True)
    visibility: str = eqx.field(static=True, default="occlusion")
    foreground_weight: float = eqx.field(static=True, default=1.0)

    def __check_init__(self):
        if self.visibility not in VISIBILITY_CHOICES:
            raise ConfigurationError(f"visibility must be one of {VISIBILITY_CHOICES}, got {self.visibility!r}")
        if isinstance(self.foreground_weight, bool) or not (np.isfinite(self.foreground_weight) and self.foreground_weight > 0):
            raise ConfigurationError(f"foreground_weight must be a positive number (foreground=false drops the term), "
                                     f"got {self.foreground_weight!r}")

        if self.points < 2:
            raise ConfigurationError(f"points must be at least 2 per side, got {self.points}")
        if not (np.isfinite(self.edge_width) and self.edge_width > 0):
            raise ConfigurationError(f"edge_width must be a positive number of pixels, got {self.edge_width!r}")
        if not (self.use_edges or self.use_foreground):
            raise ConfigurationError("the edge and foreground likelihood needs at least one of its two terms")

    def costs(self, pose, observation):
        """(Sigma_e, Sigma_fg) of one pose (D,) on one frame's maps."""
        dtype = pose.dtype
        a3, b3 = self.body.capsules(pose)  # (K, 3)
        ua, za, fa = project_points(self.rig, a3)  # (K, C, 2), (K, C)
        ub, zb, fb = project_points(self.rig, b3)
        a, b = jnp.swapaxes(ua, 0, 1), jnp.swapaxes(ub, 0, 1)  # (C, K, 2)
        depth = jnp.maximum(0.5 * (za + zb), 1e-2).T  # (C, K)
        radius = focal_lengths(self.rig).astype(dtype)[:, None] * self.body.radii.astype(dtype)[None, :] / depth
        in_front = jnp.all(fa & fb, axis=0)  # (C,)
        axis = b - a
        length = jnp.linalg.norm(axis + 1e-12, axis=-1, keepdims=True)
        normal = jnp.stack([-axis[..., 1], axis[..., 0]], axis=-1) / length  # (C, K, 2)
        s = jnp.linspace(0.0, 1.0, self.points, dtype=dtype)[:, None]  # (P, 1)
        along = a[:, :, None] + s * axis[:, :, None]  # (C, K, P, 2) points on the axis
        offset = (radius[..., None, None] * normal[:, :, None])  # (C, K, 1, 2)
        outline = jnp.concatenate([along + offset, along - offset], axis=2)  # (C, K, 2P, 2)
        sigma_e = sigma_fg = jnp.zeros((), dtype)
        if self.use_edges:
            edge = jax.vmap(sample_bilinear)(observation["edges"].astype(dtype), outline)  # (C, K, 2P)
            if self.visibility == "foreground":  # 001 eq. 13 as written: the foreground map at the outline points
                covered = jax.vmap(sample_bilinear)(observation["foreground"].astype(dtype), outline)
            else:  # another capsule, nearer this camera, covering the outline point
                distance = _segment_distance(outline[:, :, :, None, :], a[:, None, None], b[:, None, None])  # (C, K, 2P, K')
                inside = jax.nn.sigmoid((radius[:, None, None, :] - distance) / self.edge_width)
                nearer = jax.nn.sigmoid((depth[:, :, None] - depth[:, None, :]) / DEPTH_SOFTNESS)  # (C, K, K'): K' first
                others = 1.0 - jnp.eye(depth.shape[1], dtype=dtype)
                covered = jnp.max(inside * (nearer * others)[:, :, None, :], axis=-1)  # (C, K, 2P)
            visibility = jnp.mean((1.0 - covered) ** 2, axis=-1)  # (C, K): 001 eq. 13
            per_view = jnp.sum(visibility * jnp.sum((1.0 - edge) ** 2, axis=-1), axis=-1) / outline.shape[1] / outline.shape[2]
            sigma_e = jnp.mean(jnp.where(in_front, per_view, 1.0))
        if self.use_foreground:
            fg = jax.vmap(sample_bilinear)(observation["foreground"].astype(dtype), along)  # (C, K, P)
            per_view = jnp.mean((1.0 - fg) ** 2, axis=(-2, -1))
            sigma_fg = jnp.mean(jnp.where(in_front, per_view, 1.0))
        return sigma_e, sigma_fg

    def log_likelihood(self, poses, observation):
        sigma_e, sigma_fg = jax.vmap(lambda p: self.costs(p, observation))(poses)
        return -self.scale.astype(poses.dtype) * (sigma_e + self.foreground_weight * sigma_fg)


def make_edge_foreground_likelihood(body: BodyModel, rig: CameraRig, *, scale: float = 100.0, points: int = 6,
                                    edge_width: float = 1.0, use_edges: bool = True, use_foreground: bool = True,
                                    visibility: str = "occlusion", foreground_weight: float = 1.0,
                                    dtype=jnp.float32) -> EdgeForegroundLikelihood:
    """An ``EdgeForegroundLikelihood`` (module docstring)."""
    if not (np.isfinite(scale) and scale > 0):
        raise ConfigurationError(f"scale must be a positive number, got {scale!r}")
    if isinstance(foreground_weight, bool) or not isinstance(foreground_weight, (int, float, np.number)):
        raise ConfigurationError(f"foreground_weight must be a positive number, got {foreground_weight!r}")
    return EdgeForegroundLikelihood(body, rig, jnp.asarray(scale, dtype), int(points), float(edge_width), bool(use_edges),
                                    bool(use_foreground), visibility, float(foreground_weight))


EDGE_MAP_SCALE = 2.0  # pixels: the edge-proximity map's fall-off (image.edge_proximity)
FOREGROUND_BLUR = 1.0  # pixels: a binary silhouette blurred into a foreground map with a gradient


def maps_from_silhouettes(silhouettes, *, edge_scale: float = EDGE_MAP_SCALE, blur: float = FOREGROUND_BLUR):
    """(edges, foreground), each (..., H, W) float32 in [0, 1], from binary silhouettes
    (..., H, W): the edge-proximity map of the silhouettes' Canny outline, and the silhouettes
    blurred by ``blur`` pixels (001's foreground pixel map, given a slope at its border)."""
    masks = (jnp.asarray(silhouettes) > 0).astype(jnp.float32)
    return edge_proximity(canny_edges(masks, sigma=1.0), edge_scale), gaussian_blur(masks, blur)


def maps_from_images(images, silhouettes, *, edge_scale: float = EDGE_MAP_SCALE, blur: float = FOREGROUND_BLUR,
                     colour: bool = False, near: int = 0):
    """(edges, foreground) from RGB frames (..., H, W, 3), whose Canny edges give the edge map
    (internal edges included), and their silhouettes, the foreground map. The edges are the grey
    frames' (``image.canny_edges``), or with ``colour`` the colour frames'
    (``image.colour_canny_edges``); with ``near`` > 0 only those within ``near`` pixels of the
    silhouettes, thresholded against the largest gradient there (the person's edges, not the
    background's clutter)."""
    from ..image import colour_canny_edges, rgb_to_grey

    if isinstance(near, bool) or not isinstance(near, int) or near < 0:
        raise ConfigurationError(f"near must be a whole number of pixels >= 0, got {near!r}")
    masks = jnp.asarray(silhouettes) > 0
    region = dilate(masks, near) if near else None
    frames = to_float(images)
    edges = (colour_canny_edges(frames, sigma=1.0, region=region) if colour
             else canny_edges(rgb_to_grey(frames), sigma=1.0, region=region))
    return edge_proximity(edges, edge_scale), gaussian_blur(masks.astype(jnp.float32), blur)
