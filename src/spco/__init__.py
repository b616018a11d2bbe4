"""spco: spatial concepts for home robots, learnt across homes and transferred to new ones.

The package reads top-down (each floor imports only the floors below it; the contract is
``[tool.importlinter]`` in pyproject.toml, checked by the tests):

- :mod:`spco.errors`, :mod:`spco.features` (image extractors) and :mod:`spco.data` — environments
  (homes), corpora, the tokenizer and vocabulary, loaders for the authors' SIGVerse layout, a plain
  per-home format and ROS bags, a single-file cache, synthetic homes and ground-truth place regions;
- :mod:`spco.model` — the hierarchical Bayesian model of Hagiwara et al. (2021) and the SpCoA
  baselines, learnt by blocked Gibbs sampling over home shards (:mod:`spco.model.driver`), the
  shard of one new home with the shared part fixed (:mod:`spco.model.home_shard`) and prediction
  (:mod:`spco.model.prediction`): place names from observations,
  positions from place names;
- :mod:`spco.engines` — where the shards of a fit run (this process, Ray);
- :mod:`spco.knowledge` — knowledge learnt once, adapted to a new home, taught; its files;
- :mod:`spco.evaluation` and :mod:`spco.plots` — the accuracies A_n and A_p, the paper's
  experiments and their figures;
- :mod:`spco.cli` — the ``spco`` command.
"""

import os

# Numba's OpenMP workers spin-wait between parallel regions by default; on a shared or busy machine
# that makes small sweeps ~10x slower. Passive waiting costs nothing measurable when idle.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from spco.errors import ConfigurationError, DataFormatError, SpcoError

__version__ = "0.2.0"

__all__ = ["ConfigurationError", "DataFormatError", "SpcoError", "__version__"]
