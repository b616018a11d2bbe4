"""The sampler's numerical kernels, re-exported from :mod:`spco.model.kernels` (where they live).

Kept so that ``from spco.model.random import log_dirichlet`` and the like keep working; new code
imports from the kernel modules themselves:

- :mod:`~spco.model.kernels.rng` — the random streams (xorshift64*, splitmix64 seeds);
- :mod:`~spco.model.kernels.normal` — ziggurat normals;
- :mod:`~spco.model.kernels.gamma` — gamma variates in log space, Dirichlet rows' passes;
- :mod:`~spco.model.kernels.dirichlet` — Dirichlet rows, plain and hierarchical;
- :mod:`~spco.model.kernels.crt` — CRT (Antoniak) table counts;
- :mod:`~spco.model.kernels.niw` — Normal–inverse-Wishart posteriors and draws;
- :mod:`~spco.model.kernels.gaussian` — Gaussian log densities of positions;
- :mod:`~spco.model.kernels.categorical` — categorical and joint (C, R) draws;
- :mod:`~spco.model.kernels.special` — log, exp, digamma without library calls;
- :mod:`~spco.model.kernels.likelihood` — counts · log θᵀ (the multinomial likelihoods);
- :mod:`~spco.model.kernels.counts` — statistics of sparse counts;
- :mod:`~spco.model.kernels.dispatch` — how kernels are called (threads, vectoriser, dtypes).
"""

from __future__ import annotations

from spco.model.kernels.categorical import (  # noqa: F401
    _ASSIGNMENT_CHUNK,
    _categorical_rows,
    _draw_linear,
    _draw_log,
    _joint_assignment,
    _joint_assignment_chunks,
    sample_categorical_log,
    sample_joint_assignment,
)
from spco.model.kernels.counts import (  # noqa: F401
    FLOAT32_EXACT,
    _add_rows,
    _grouped_moments,
    _grouped_row_sums,
    grouped_moments,
    grouped_row_sums,
    move_rows,
    stack_counts,
)
from spco.model.kernels.crt import (  # noqa: F401
    _bernoulli_sum_moment_matched,
    _crt_entries,
    _crt_entry,
    _crt_tail,
    _crt_totals_row,
    _crt_totals_rows,
    sample_crt,
    sample_crt_totals,
)
from spco.model.kernels.dirichlet import (  # noqa: F401
    _dirichlet_rows,
    _dirichlet_short_rows,
    _hierarchical_dirichlet_rows,
    _short_rows,
    dirichlet,
    dirichlet_log_density,
    log_dirichlet,
    log_dirichlet_hierarchical,
)
from spco.model.kernels.dispatch import (  # noqa: F401
    _PARALLEL_MIN,
    _VECTORISED_READY,
    _argument_kind,
    _as,
    _call_in_parts,
    _call_vectorised,
    _index_array,
    _value_array,
)
from spco.model.kernels.gamma import (  # noqa: F401
    _GAMMA_BLOCK,
    _LOG_GAMMA_FLOOR,
    _SHORT_ROW,
    RowScratch,
    _gamma_blocks,
    _gamma_draw,
    _log_gamma_row,
    _log_gamma_short_row,
    _marsaglia_tsang_first,
    _marsaglia_tsang_rest,
    _row_scratch,
    _stream_gamma,
    _stream_gamma_any,
    _stream_log_gamma_small,
    log_gamma_variates,
)
from spco.model.kernels.gaussian import (  # noqa: F401
    _GAUSSIAN_CHUNK,
    _grouped_gaussian,
    _grouped_gaussian_chunks,
    _inverse_cholesky,
    gaussian_log_density,
    grouped_gaussian_log_density,
)
from spco.model.kernels.likelihood import (  # noqa: F401
    LANES,
    DimensionMajorCounts,
    _balanced_parts,
    _blocked_sparse_row,
    _blocked_sparse_rows,
    _dimension_major,
    _dimension_major_dot,
    _dimension_major_home,
    _fill_table_block,
    _likelihood_table_blocks,
    _table_block,
    blocked_sparse_dot,
    dimension_major,
    dimension_major_dot,
    grouped_sparse_dot,
    likelihood_table,
)
from spco.model.kernels.niw import (  # noqa: F401
    _cholesky_into,
    _niw_element,
    _niw_posterior_kernel,
    _niw_rows,
    niw_posterior,
    sample_niw,
)
from spco.model.kernels.normal import (  # noqa: F401
    _TWO52_BITS,
    _ZIG_BOTTOM,
    _ZIG_R,
    _ZIG_SCALE,
    _ZIG_THRESHOLD,
    _ZIG_THRESHOLD_SIGNED,
    _ZIG_TOP,
    _normal_from_bits,
    _stream_normal,
    _ziggurat_first_step,
    _ziggurat_tables,
)
from spco.model.kernels.rng import (  # noqa: F401
    _GOLDEN,
    _MIX1,
    _MIX2,
    _ONE_BITS,
    _ONE_MINUS_HALF_ULP,
    _ROW_STREAMS,
    _XORSHIFT_MULT,
    _fill_stream_words,
    _splitmix,
    _stream_bits,
    _stream_next,
    _stream_open,
    _stream_start,
    _words_to_uniforms,
)
from spco.model.kernels.special import (  # noqa: F401
    _EXP_TAYLOR,
    _INV_LN2,
    _LG1,
    _LG2,
    _LG3,
    _LG4,
    _LG5,
    _LG6,
    _LG7,
    _LN2_HI,
    _LN2_LO,
    _digamma,
    _digamma_large,
    _digamma_large_minus_log,
    _exp_parts,
    _log_minus,
    _powers_of_two,
    _scaled_exp,
    _sum_exp,
    _trigamma,
    _trigamma_large,
    scaled_exp,
)
