"""Standard normal variates by the ziggurat method (Marsaglia & Tsang 2000), 256 layers.

:func:`_stream_normal` draws one from a stream; :func:`_normal_from_bits` finishes a draw whose
first 64 random bits are given; :func:`_ziggurat_first_step` runs the first (branch-free) step
for a whole array of random words, as the Dirichlet rows need.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spco.model.kernels.rng import _stream_bits, _stream_next, _stream_open


def _ziggurat_tables(layers: int = 256, r: float = 3.6541528853610088,
                     area: float = 4.92867323399e-3) -> tuple[np.ndarray, ...]:
    """Tables of the ziggurat method for the standard normal (Marsaglia & Tsang 2000).

    Layer 0 is the base strip [0, area/f(r)] × [0, f(r)] plus the tail beyond ``r``; layer i ≥ 1
    is the box [0, e_{i-1}] × [f(e_{i-1}), f(e_i)] with edges r = e_0 > e_1 > … > e_255 = 0 and
    f(x) = exp(−x²/2), every layer of the same ``area``. Returns the scale turning 52 random bits
    into an abscissa, the 52-bit threshold below which that abscissa is under the curve, and
    f at the layer's bottom and top edges.
    """
    f = lambda x: np.exp(-0.5 * x * x)  # noqa: E731
    edges = np.zeros(layers)
    edges[0] = r
    for i in range(layers - 2):
        edges[i + 1] = np.sqrt(-2.0 * np.log(area / edges[i] + f(edges[i])))
    width = np.concatenate([[area / f(r)], edges[:-1]])
    threshold = np.floor(edges / width * 2.0**52).astype(np.uint64)
    bottom = np.concatenate([[0.0], f(edges[:-1])])
    return width / 2.0**52, threshold, bottom, f(edges)


_ZIG_SCALE, _ZIG_THRESHOLD, _ZIG_BOTTOM, _ZIG_TOP = _ziggurat_tables()
_ZIG_R = 3.6541528853610088


#: Where a ziggurat draw takes its random bits from one 64-bit word of xorshift64*: the layer from
#: the top 8 bits, the sign from bit 55, the 52-bit abscissa from bits 3–54. The low bits of
#: xorshift64* are its weakest (bit 0 is a linear recurrence of order ≤ 64 over GF(2)); the layer
#: decides most of a variate's distribution, so it must not come from them.
_LAYER_SHIFT = np.uint64(56)
_SIGN_SHIFT = np.uint64(55)
_ABSCISSA_SHIFT = np.uint64(3)
_ABSCISSA_MASK = np.uint64(2**52 - 1)


@njit(cache=True, inline="always")
def _ziggurat_parts(bits: np.uint64) -> tuple[np.int64, np.uint64, np.uint64]:
    """(layer 0–255, sign bit, 52-bit abscissa integer) of a random word."""
    return (np.int64(bits >> _LAYER_SHIFT), (bits >> _SIGN_SHIFT) & np.uint64(1),
            (bits >> _ABSCISSA_SHIFT) & _ABSCISSA_MASK)


@njit(cache=True, error_model="numpy")
def _stream_normal(state: np.uint64) -> tuple[np.uint64, float]:
    """The next state and a standard normal variate (ziggurat; ~99 % of draws take one step)."""
    state, bits = _stream_bits(state)
    return _normal_from_bits(state, bits)


@njit(cache=True, error_model="numpy")
def _normal_from_bits(state: np.uint64, bits: np.uint64) -> tuple[np.uint64, float]:
    """A ziggurat normal whose first 64 random bits are ``bits``, further ones (if the first step
    does not return) from the stream ``state``: returns the stream's next state and the variate."""
    while True:
        layer, negative, u = _ziggurat_parts(bits)
        x = np.int64(u) * _ZIG_SCALE[layer]
        if u < _ZIG_THRESHOLD[layer]:  # the sign by arithmetic: a branch on a random bit mispredicts
            return state, x * (1.0 - 2.0 * np.int64(negative))
        if layer == 0:  # the tail beyond r (Marsaglia 1964)
            while True:
                state, u1 = _stream_open(state)
                state, u2 = _stream_open(state)
                xx = -np.log(u1) / _ZIG_R
                if -2.0 * np.log(u2) > xx * xx:
                    return state, -(_ZIG_R + xx) if negative else _ZIG_R + xx
        state, u1 = _stream_next(state)
        if _ZIG_BOTTOM[layer] + u1 * (_ZIG_TOP[layer] - _ZIG_BOTTOM[layer]) < np.exp(-0.5 * x * x):
            return state, -x if negative else x
        state, bits = _stream_bits(state)
_ZIG_THRESHOLD_SIGNED = _ZIG_THRESHOLD.astype(np.int64)  # thresholds < 2^52: signed compares


_TWO52_BITS = np.uint64(0x4330000000000000)  # the bit pattern of 2^52


@njit(cache=True, error_model="numpy")
def _ziggurat_first_step(words: np.ndarray, x: np.ndarray, fast: np.ndarray) -> None:
    """The first step of :func:`_stream_normal` for every word, without branches: the abscissa
    x[j] and fast[j] = 1 where that step already returns it (≈ 98 % of words), else 0 (the draw
    continues in :func:`_normal_from_bits`). The 52-bit integer becomes a double through the bit
    pattern of 2^52 + u (no integer conversion, which AVX2 lacks for 64-bit integers)."""
    patterns = x.view(np.uint64)
    for j in range(x.size):
        patterns[j] = ((words[j] >> _ABSCISSA_SHIFT) & _ABSCISSA_MASK) | _TWO52_BITS
    for j in range(x.size):
        bits = words[j]
        layer = np.int64(bits >> _LAYER_SHIFT)
        sign = 1.0 - 2.0 * np.float64(np.int64((bits >> _SIGN_SHIFT) & np.uint64(1)))
        x[j] = (x[j] - 4503599627370496.0) * _ZIG_SCALE[layer] * sign
        abscissa = np.int64((bits >> _ABSCISSA_SHIFT) & _ABSCISSA_MASK)
        fast[j] = np.float64(abscissa < _ZIG_THRESHOLD_SIGNED[layer])
