"""The sampler's numerical kernels, one module per thing they draw or compute.

Dependencies run one way: :mod:`.rng` (random streams) ← :mod:`.normal` ← :mod:`.gamma` ←
:mod:`.dirichlet`, :mod:`.crt`, :mod:`.niw`; :mod:`.special` (log, exp, digamma) and
:mod:`.dispatch` (threads, vectoriser, dtypes) are leaves, as are :mod:`.channels` (the word
channels' per-token sums) and :mod:`.fractional` (the power target's φ^v acceptance weights).
Every random draw takes a :class:`numpy.random.Generator`, from which a
compiled kernel takes one seed for its counter-seeded streams, so results do not depend on the
number of threads.
"""
