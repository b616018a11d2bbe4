"""Data layer: environments, corpora, language, loaders, the cache and synthetic homes."""

from spco.data.environment import Corpus, Environment, GroundTruth, TrainingData, make_ground_truth
from spco.data.language import DEFAULT_WORD_INCREMENT, Vocabulary, normalize_name, tokenize
from spco.data.loading import load
from spco.data.plain import features_to_counts
from spco.data.regions import PlaceRegions, load_region_file
from spco.data.synthetic import SyntheticConfig, generate_home, generate_homes

__all__ = [
    "DEFAULT_WORD_INCREMENT",
    "Corpus",
    "Environment",
    "GroundTruth",
    "PlaceRegions",
    "SyntheticConfig",
    "TrainingData",
    "Vocabulary",
    "features_to_counts",
    "generate_home",
    "generate_homes",
    "load",
    "load_region_file",
    "make_ground_truth",
    "normalize_name",
    "tokenize",
]
