"""Place names from observations and positions from place names: :mod:`spco.model.prediction`.

The functions read a learnt :class:`~spco.model.parameters.ConceptParameters`, so they live with
the model (the estimators' ``predict_names`` and ``predict_positions`` use them); this module keeps
the path ``spco.prediction`` working.
"""

from spco.model.prediction import (
    LEARNT_SUPPORT,
    NamePrediction,
    PositionPrediction,
    UnknownNameError,
    concept_posterior,
    concept_stand_ins,
    draw_poses,
    gaussian_log_density,
    kl_scores_reference,
    mutual_information_weights,
    name_support,
    predict_names,
    predict_positions,
    query_indices,
    query_name,
    reference_kl_weights,
    region_posterior_for_name,
    validate_poses,
    validate_visual_counts,
    word_posterior,
)

__all__ = [
    "LEARNT_SUPPORT",
    "NamePrediction",
    "PositionPrediction",
    "UnknownNameError",
    "concept_posterior",
    "concept_stand_ins",
    "draw_poses",
    "gaussian_log_density",
    "kl_scores_reference",
    "mutual_information_weights",
    "name_support",
    "predict_names",
    "predict_positions",
    "query_indices",
    "query_name",
    "reference_kl_weights",
    "region_posterior_for_name",
    "validate_poses",
    "validate_visual_counts",
    "word_posterior",
]
