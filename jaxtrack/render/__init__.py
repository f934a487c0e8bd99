"""Soft (differentiable) and hard rendering of the capsule body into silhouettes."""

from ._soft_raster import ProjectedCapsules as ProjectedCapsules
from ._soft_raster import capsule_support as capsule_support
from ._soft_raster import capsule_union as capsule_union
from ._soft_raster import hard_from_capsules as hard_from_capsules
from ._soft_raster import hard_silhouettes as hard_silhouettes
from ._soft_raster import project_capsules as project_capsules
from ._soft_raster import soft_from_capsules as soft_from_capsules
from ._soft_raster import soft_silhouettes as soft_silhouettes
from ._soft_raster import union_statistics as union_statistics
from ._soft_raster import weighted_union_statistics as weighted_union_statistics
