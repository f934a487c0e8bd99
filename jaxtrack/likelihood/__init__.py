"""Observation likelihoods behind one interface (``AbstractLikelihood``): the bidirectional
silhouette likelihood of paper 000 eq. 12 (dense, windowed, on sampled pixels, or at a coarser
resolution), the robust reprojection likelihood of 2-D keypoint detections, sums of
likelihoods, plain functions, and the ground plane as a pose prior that multiplies any of them.
``LikelihoodRecipe`` and its registry name the likelihoods a test scene can be tracked with (``available_likelihoods()``)."""

from ._base import AbstractLikelihood as AbstractLikelihood
from ._base import FunctionLikelihood as FunctionLikelihood
from ._base import ObservationPart as ObservationPart
from ._base import SumLikelihood as SumLikelihood
from ._base import as_likelihood as as_likelihood
from ._base import set_references as set_references
from ._body_calibration import BodyCalibration as BodyCalibration
from ._body_calibration import body_of as body_of
from ._body_calibration import calibrate_body as calibrate_body
from ._body_calibration import with_body as with_body
from ._calibration import ShapeCalibration as ShapeCalibration
from ._calibration import calibrate_shape as calibrate_shape
from ._coarse import CoarseSilhouetteLikelihood as CoarseSilhouetteLikelihood
from ._coarse import block_downsample as block_downsample
from ._coarse import coarsen_likelihood as coarsen_likelihood
from ._edges import EDGE_MAP_SCALE as EDGE_MAP_SCALE
from ._edges import EdgeForegroundLikelihood as EdgeForegroundLikelihood
from ._edges import make_edge_foreground_likelihood as make_edge_foreground_likelihood
from ._edges import maps_from_images as maps_from_images
from ._edges import maps_from_silhouettes as maps_from_silhouettes
from ._ground import GroundPlanePrior as GroundPlanePrior
from ._ground import ground_clearance as ground_clearance
from ._ground import make_ground_prior as make_ground_prior
from ._histogram import ColourHistogramLikelihood as ColourHistogramLikelihood
from ._histogram import bhattacharyya_distance as bhattacharyya_distance
from ._histogram import make_histogram_likelihood as make_histogram_likelihood
from ._histogram import soft_histogram as soft_histogram
from ._keypoints import KeypointLikelihood as KeypointLikelihood
from ._keypoints import joint_sigmas as joint_sigmas
from ._keypoints import make_keypoint_likelihood as make_keypoint_likelihood
from ._registry import DEFAULT_LIKELIHOOD as DEFAULT_LIKELIHOOD
from ._registry import OBSERVATION_KINDS as OBSERVATION_KINDS
from ._registry import LikelihoodRecipe as LikelihoodRecipe
from ._registry import SceneInputs as SceneInputs
from ._registry import available_likelihoods as available_likelihoods
from ._registry import get_likelihood as get_likelihood
from ._registry import register_likelihood as register_likelihood
from ._registry import unregister_likelihood as unregister_likelihood
from ._sampled import PixelSample as PixelSample
from ._sampled import SampledSilhouetteLikelihood as SampledSilhouetteLikelihood
from ._sampled import default_band as default_band
from ._sampled import default_near as default_near
from ._sampled import default_pixel_samples as default_pixel_samples
from ._sampled import pixel_strata as pixel_strata
from ._sampled import sample_frames as sample_frames
from ._sampled import sample_pixels as sample_pixels
from ._silhouette import SilhouetteLikelihood as SilhouetteLikelihood
from ._silhouette import bidirectional_silhouette_cost as bidirectional_silhouette_cost
from ._silhouette import check_silhouettes as check_silhouettes
from ._silhouette import make_silhouette_likelihood as make_silhouette_likelihood
from ._silhouette import silhouette_statistics_dense as silhouette_statistics_dense
from ._silhouette import silhouette_statistics_windowed as silhouette_statistics_windowed
from ._silhouette import suggest_window as suggest_window
from ._template import TemplateLikelihood as TemplateLikelihood
from ._template import make_template_likelihood as make_template_likelihood
from ._template import normalised_correlation as normalised_correlation
