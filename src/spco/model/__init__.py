"""The spatial-concept models and their Gibbs samplers.

- :mod:`spco.model.hyperparameters` — the paper's hyperparameters and their validation;
- :mod:`spco.model.kernels` — the compiled kernels, one module each: random streams, normals,
  gamma and Dirichlet, CRT, NIW, Gaussian densities, likelihoods;
- :mod:`spco.model.allocation` — concepts (HDP over homes) and regions (per concept);
- :mod:`spco.model.observations` — positions (Gaussian–NIW), words and vision (hierarchical
  Dirichlet–multinomial);
- :mod:`spco.model.pruning` — mutual-information word pruning;
- :mod:`spco.model.state` — the sampler's data, state and settings, and the parameters all homes share;
- :mod:`spco.model.gibbs` — initialisation, sweeps (exact, reference, SpCoA), word pruning and the log
  joint; a sweep's steps: :mod:`spco.model.assignments` (the local step),
  :mod:`spco.model.sweep_statistics` (its statistics), :mod:`spco.model.parameter_steps` (the global
  and home steps);
- :mod:`spco.model.shard` — a sweep as map (home shards' local steps) → reduce (summed
  statistics) → global step; the engines of :mod:`spco.engines` run the shards in process or on Ray;
- :mod:`spco.model.numba_cache` — where the compiled kernels are cached;
- :mod:`spco.model.precompile` — the kernels compiled ahead of a fit (``spco demo`` on a cold cache);
- :mod:`spco.model.transfer` — the estimators :class:`SpCoTransfer` and :class:`SpCoA`;
- :mod:`spco.model.io` — loading fitted models (and their file format; a model saves itself:
  :func:`spco.model.transfer.save_model`);
- :mod:`spco.model.archive` — the archive every spco file is (``.npz``, JSON header, checksums).
"""

import spco.model.numba_cache  # noqa: F401 - first: where Numba caches the kernels
from spco.model.hyperparameters import SpCoAHyperparameters, TransferHyperparameters
from spco.model.io import load_model
from spco.model.parameters import ConceptParameters
from spco.model.transfer import SpatialConceptModel, SpCoA, SpCoTransfer, save_model

__all__ = [
    "ConceptParameters",
    "SpCoA",
    "SpCoAHyperparameters",
    "SpCoTransfer",
    "SpatialConceptModel",
    "TransferHyperparameters",
    "load_model",
    "save_model",
]
