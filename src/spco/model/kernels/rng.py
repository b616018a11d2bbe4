"""Random streams of the compiled kernels: xorshift64* seeded by splitmix64 hashes of (seed, index).

Every kernel that draws takes one uint64 seed from the caller's :class:`numpy.random.Generator`
and starts stream j at :func:`_stream_start` (seed, j): results depend on the seed only, never on
the number of threads. :func:`_stream_next` gives uniforms in [0, 1), :func:`_stream_open` in
(0, 1); :func:`_fill_stream_words` advances eight streams side by side (one row of a Dirichlet
batch) and :func:`_words_to_uniforms` turns their words into open uniforms in place.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# The compiled kernels draw their own random numbers: xorshift64* streams whose starting states
# are counter-based hashes (splitmix64) of a seed taken from the caller's Generator and of the
# block (or entry) index. Results therefore depend on the seed only — never on the number of
# threads or on how Numba schedules the blocks.

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_XORSHIFT_MULT = np.uint64(0x2545F4914F6CDD1D)


@njit(cache=True, inline="always")
def _splitmix(x: np.uint64) -> np.uint64:
    z = x + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return z ^ (z >> np.uint64(31))


@njit(cache=True, inline="always")
def _stream_start(seed: np.uint64, j: np.uint64) -> np.uint64:
    """Start of the random stream of block or entry ``j``: a counter-based seed, never zero."""
    return _splitmix(seed ^ _splitmix(j)) | np.uint64(1)


@njit(cache=True, inline="always")
def _stream_bits(state: np.uint64) -> tuple[np.uint64, np.uint64]:
    """xorshift64* step: the next state and 64 output bits."""
    state ^= state >> np.uint64(12)
    state ^= state << np.uint64(25)
    state ^= state >> np.uint64(27)
    return state, state * _XORSHIFT_MULT


@njit(cache=True, inline="always")
def _stream_next(state: np.uint64) -> tuple[np.uint64, float]:
    """The next state and a uniform in [0, 1) (53 bits)."""
    state, bits = _stream_bits(state)
    # through int64 (exact for 53 bits): x86 converts signed integers in one instruction
    return state, np.int64(bits >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True, inline="always")
def _stream_open(state: np.uint64) -> tuple[np.uint64, float]:
    """The next state and a uniform in (0, 1): never exactly 0, so its logarithm is finite."""
    state, bits = _stream_bits(state)
    return state, (np.int64(bits >> np.uint64(11)) + 0.5) * (1.0 / 9007199254740992.0)


#: Random streams per row in the Dirichlet kernels: eight xorshift64* streams advanced side by side
#: (LLVM's SLP vectoriser runs them in AVX2 lanes) fill the row's random words in one pass.
_ROW_STREAMS = 8


@njit(cache=True, inline="always")
def _fill_stream_words(states: np.ndarray, words: np.ndarray) -> None:
    """words[8i + k] ← output i of stream k (xorshift64*) for the eight streams of ``states``,
    which are advanced in place; ``words.size`` is a multiple of 8. Written as eight scalar
    streams so that the SLP vectoriser packs them into vector lanes."""
    s0, s1, s2, s3 = states[0], states[1], states[2], states[3]
    s4, s5, s6, s7 = states[4], states[5], states[6], states[7]
    a, b, c, m = np.uint64(12), np.uint64(25), np.uint64(27), _XORSHIFT_MULT
    for i in range(words.size // 8):
        s0 ^= s0 >> a
        s1 ^= s1 >> a
        s2 ^= s2 >> a
        s3 ^= s3 >> a
        s4 ^= s4 >> a
        s5 ^= s5 >> a
        s6 ^= s6 >> a
        s7 ^= s7 >> a
        s0 ^= s0 << b
        s1 ^= s1 << b
        s2 ^= s2 << b
        s3 ^= s3 << b
        s4 ^= s4 << b
        s5 ^= s5 << b
        s6 ^= s6 << b
        s7 ^= s7 << b
        s0 ^= s0 >> c
        s1 ^= s1 >> c
        s2 ^= s2 >> c
        s3 ^= s3 >> c
        s4 ^= s4 >> c
        s5 ^= s5 >> c
        s6 ^= s6 >> c
        s7 ^= s7 >> c
        j = 8 * i
        words[j] = s0 * m
        words[j + 1] = s1 * m
        words[j + 2] = s2 * m
        words[j + 3] = s3 * m
        words[j + 4] = s4 * m
        words[j + 5] = s5 * m
        words[j + 6] = s6 * m
        words[j + 7] = s7 * m
    states[0], states[1], states[2], states[3] = s0, s1, s2, s3
    states[4], states[5], states[6], states[7] = s4, s5, s6, s7


_ONE_BITS = np.uint64(0x3FF0000000000000)
#: 1 − 2^-53: (1 + m 2^-52) minus this is the open uniform (m + 1/2) 2^-52 in (0, 1), exactly.
_ONE_MINUS_HALF_ULP = 1.0 - 2.0**-53


@njit(cache=True, inline="always")
def _words_to_uniforms(words: np.ndarray) -> np.ndarray:
    """Turn 64-bit random words into open uniforms (m + 1/2) 2^-52, m their top 52 bits, in place,
    and return them as float64: the words become the bit patterns of 1 + m 2^-52 in [1, 2) (an
    integer operation that vectorises, where converting a 64-bit integer to a double does not on
    AVX2), from which the consumer subtracts :data:`_ONE_MINUS_HALF_ULP`."""
    for j in range(words.size):
        words[j] = (words[j] >> np.uint64(12)) | _ONE_BITS
    return words.view(np.float64)
