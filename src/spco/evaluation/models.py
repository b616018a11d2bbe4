"""The models an experiment can compare (:data:`MODELS`): how to build and score each."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

from spco.model.hyperparameters import TransferHyperparameters
from spco.model.transfer import SpatialConceptModel, SpCoA, SpCoTransfer


# ------------------------------------------------------------------------------------ models
@dataclass(frozen=True)
class ModelSpec:
    """How to build and score one model of the comparison.

    Attributes
    ----------
    description: one line for help texts.
    build: ``build(n_iterations, random_state, hyperparameters, record_log_joint)`` -> an unfitted
        model; ``hyperparameters`` (``None``: the model's defaults) applies to transfer models.
    single_home: fitted on the new home alone (SpCoA) instead of all homes of the setting.
    """

    description: str
    build: Callable[[int, int, TransferHyperparameters | None, bool], SpatialConceptModel]
    single_home: bool = False

    @property
    def weighting(self) -> Literal["mi", "none", "reference"]:
        """The name weighting of the model's answers (its
        :meth:`~spco.model.transfer.SpatialConceptModel.name_weighting`: for the transfer models the
        robot's, :func:`spco.model.confidence.answer_weighting` — ``"none"`` with the naming rule,
        ``"mi"`` without, the authors' ``"reference"``; ``"mi"`` for SpCoA)."""
        return self.build(1, 0, None, False).name_weighting()  # type: ignore[return-value]

    def hyperparameters(self, hyper: TransferHyperparameters | None) -> TransferHyperparameters:
        """The hyperparameters the model will use."""
        model = self.build(1, 0, hyper, False)
        used = model.hyperparameters
        return used if used is not None else model._default_hyperparameters()


def _transfer(variant: str, prune: bool) -> Callable[..., SpatialConceptModel]:
    def build(n_iterations: int, random_state: int, hyper: TransferHyperparameters | None,
              record_log_joint: bool) -> SpatialConceptModel:
        return SpCoTransfer(hyper, variant=variant, prune_words=prune, n_iterations=n_iterations,
                            random_state=random_state, record_log_joint=record_log_joint)
    return build


def _spcoa(prune: bool) -> Callable[..., SpatialConceptModel]:
    def build(n_iterations: int, random_state: int, hyper: TransferHyperparameters | None,
              record_log_joint: bool) -> SpatialConceptModel:
        # SpCoA keeps its own hyperparameters (SpCoAHyperparameters); the transfer ones do not apply
        return SpCoA(prune_words=prune, n_iterations=n_iterations, random_state=random_state,
                     record_log_joint=record_log_joint)
    return build


#: The models an experiment can compare, by name. Add an entry to extend the comparison.
MODELS: dict[str, ModelSpec] = {
    "spcotransfer": ModelSpec("SpCoTransfer, exact sampler", _transfer("exact", False)),
    "spcotransfer+mi": ModelSpec("SpCoTransfer + MI word pruning", _transfer("exact", True)),
    "spcotransfer-ref": ModelSpec("SpCoTransfer, the authors' sampler and KL name scoring",
                                  _transfer("reference", False)),
    "spcotransfer-ref+mi": ModelSpec("SpCoTransfer + word pruning, the authors' sampler and KL "
                                     "name scoring", _transfer("reference", True)),
    "spcoa": ModelSpec("SpCoA on the new home alone", _spcoa(False), single_home=True),
    "spcoa+mi": ModelSpec("SpCoA + MI word pruning on the new home alone", _spcoa(True),
                          single_home=True),
}



def _fmt(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


def describe_models() -> str:
    """One line per model of the registry, for help texts."""
    return "\n".join(f"{name}: {spec.description}" for name, spec in MODELS.items())
