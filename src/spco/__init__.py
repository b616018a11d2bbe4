"""spco: spatial concepts for home robots, learnt across homes and transferred to new ones.

The package reads top-down:

- :mod:`spco.data` — environments (homes), corpora, the tokenizer and vocabulary, loaders for the
  authors' SIGVerse layout and for a plain per-home format, a single-file cache, synthetic homes and
  ground-truth place regions;
- :mod:`spco.model` — the hierarchical Bayesian model of Hagiwara et al. (2021) and the SpCoA
  baselines, learnt by blocked Gibbs sampling;
- :mod:`spco.prediction` — place names from observations, positions from place names;
- :mod:`spco.evaluation` — the accuracies A_n and A_p and the paper's experiments;
- :mod:`spco.cli` and :mod:`spco.plots` — the ``spco`` command and its figures.
"""

import os

# Numba's OpenMP workers spin-wait between parallel regions by default; on a shared or busy machine
# that makes small sweeps ~10x slower. Passive waiting costs nothing measurable when idle.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from spco.errors import ConfigurationError, DataFormatError, SpcoError

__version__ = "0.1.0"

__all__ = ["ConfigurationError", "DataFormatError", "SpcoError", "__version__"]
