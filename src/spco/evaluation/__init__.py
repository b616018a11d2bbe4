"""Evaluation: the paper's name accuracy A_n and position accuracy A_p, per home."""

from spco.evaluation.metrics import (
    HomeScores,
    evaluate_answers,
    evaluate_home,
    mean_over_places,
    name_accuracy,
    name_chance,
    position_accuracy,
    position_chance,
)

__all__ = [
    "HomeScores",
    "evaluate_answers",
    "evaluate_home",
    "mean_over_places",
    "name_accuracy",
    "name_chance",
    "position_accuracy",
    "position_chance",
]
