"""Observation likelihoods: the bidirectional silhouette likelihood of paper 000 eq. 12."""

from ._silhouette import SilhouetteLikelihood as SilhouetteLikelihood
from ._silhouette import bidirectional_silhouette_cost as bidirectional_silhouette_cost
from ._silhouette import check_silhouettes as check_silhouettes
from ._silhouette import make_silhouette_likelihood as make_silhouette_likelihood
from ._silhouette import silhouette_statistics_dense as silhouette_statistics_dense
from ._silhouette import silhouette_statistics_windowed as silhouette_statistics_windowed
from ._silhouette import suggest_window as suggest_window
