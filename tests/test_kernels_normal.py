"""The ziggurat normal's random bits: the layer must not come from xorshift64*'s weak low bits.

Bit 0 of a xorshift64* output equals bit 0 of its state (the multiplier is odd), and the state's
bits follow a linear recurrence over GF(2) of order ≤ 64: a layer taken from the low bits
(``bits & 255``, the earlier code) has a parity sequence of linear complexity ≤ 64, where random
bits have ≈ n/2. The Berlekamp–Massey test below measures that complexity for every layer bit.
"""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit
from scipy import stats

from spco.model.kernels.normal import _stream_normal, _ziggurat_parts
from spco.model.kernels.rng import _stream_bits, _stream_start


def linear_complexity(bits: np.ndarray) -> int:
    """Length of the shortest GF(2) linear recurrence generating ``bits`` (Berlekamp–Massey)."""
    n = bits.size
    c, b = np.zeros(n + 1, dtype=np.uint8), np.zeros(n + 1, dtype=np.uint8)
    c[0] = b[0] = 1
    length, m = 0, -1
    for i in range(n):
        discrepancy = (bits[i] + int(np.dot(c[1:length + 1], bits[i - length:i][::-1]))) & 1
        if discrepancy:
            previous = c.copy()
            shift = i - m
            c[shift:] ^= b[:n + 1 - shift]
            if 2 * length <= i:
                length, m, b = i + 1 - length, i, previous
    return length


@njit
def stream_words(n: int, seed: int = 7) -> np.ndarray:
    """n consecutive 64-bit outputs of one kernel stream."""
    state = _stream_start(np.uint64(seed), np.uint64(0))
    words = np.empty(n, dtype=np.uint64)
    for i in range(n):
        state, words[i] = _stream_bits(state)
    return words


@njit
def layers_and_signs(words: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ziggurat layer and sign bit of every word."""
    layers = np.empty(words.size, dtype=np.int64)
    signs = np.empty(words.size, dtype=np.uint8)
    for i in range(words.size):
        layer, sign, _ = _ziggurat_parts(words[i])
        layers[i], signs[i] = layer, np.uint8(sign)
    return layers, signs


@njit
def normals(n: int, seed: int) -> np.ndarray:
    """n standard normals from one kernel stream."""
    state = _stream_start(np.uint64(seed), np.uint64(0))
    out = np.empty(n)
    for i in range(n):
        state, out[i] = _stream_normal(state)
    return out


def test_linear_complexity_helper_finds_an_lfsr() -> None:
    """The helper itself: an order-5 recurrence has complexity 5, random bits about n/2."""
    bits = np.zeros(200, dtype=np.uint8)
    bits[:5] = [1, 0, 0, 1, 1]
    for i in range(5, bits.size):
        bits[i] = bits[i - 5] ^ bits[i - 3]
    assert linear_complexity(bits) == 5
    random_bits = np.random.default_rng(0).integers(0, 2, 400).astype(np.uint8)
    assert abs(linear_complexity(random_bits) - 200) <= 10


def test_ziggurat_layer_bits_have_full_linear_complexity() -> None:
    """Every bit of the layer index (and the sign) looks random to a linear-complexity test; the
    low bits of the raw words, which the layer used to come from, do not."""
    n = 600
    words = stream_words(n)
    layers, signs = layers_and_signs(words)
    for bit in range(8):
        assert linear_complexity(((layers >> bit) & 1).astype(np.uint8)) >= 0.45 * n, f"layer bit {bit}"
    assert linear_complexity(signs) >= 0.45 * n
    low_bit = (words & np.uint64(1)).astype(np.uint8)
    assert linear_complexity(low_bit) <= 64  # what the test would catch


def test_ziggurat_layers_are_uniform_and_normals_are_normal() -> None:
    """Layers uniform over 0–255 (χ²) and the variates standard normal (Kolmogorov–Smirnov)."""
    words = stream_words(51_200, seed=3)
    layers, _ = layers_and_signs(words)
    assert stats.chisquare(np.bincount(layers, minlength=256)).pvalue > 1e-3
    draws = normals(20_000, 11)
    assert stats.kstest(draws, "norm").pvalue > 1e-3


@pytest.mark.parametrize("bit", [0, 1, 2])
def test_the_lowest_word_bits_do_not_move_the_layer_or_sign(bit: int) -> None:
    """Flipping one of the three lowest bits of a word leaves its layer and sign unchanged."""
    words = stream_words(50, seed=bit)
    flipped = words ^ np.uint64(1 << bit)
    for a, b in zip(layers_and_signs(words), layers_and_signs(flipped), strict=True):
        np.testing.assert_array_equal(a, b)
