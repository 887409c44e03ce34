"""``numpy.random.default_rng(entropy).uniform(low, high, n)`` for many entropies at once.

A sampled sweep draws each mission's values from its own Generator, seeded by
``[sweep seed, replica, 1]``: numpy's ``SeedSequence`` hashes the entropy into a PCG64 state,
and each draw is one PCG64 step. Making a Generator costs ~10 us, more than the rest of
planning a mission; here the same hashing, seeding and steps run over arrays, one row per
Generator, and give the same numbers bit for bit (checked against numpy in
``tests/test_sweep_speed.py``).

The algorithms are numpy's, from its documentation and source (``numpy.random.SeedSequence``:
M. E. O'Neill's seed_seq hash, pool size 4; ``PCG64``: O'Neill's PCG XSL RR 128/64 with
``pcg64_set_seed``'s two-step seeding; ``Generator.uniform``: ``low + (high - low) * u`` with
``u = (next64 >> 11) * 2**-53``). Only what a sweep needs is here: 32-bit entropy words, the
default pool, uint64 state, and uniform draws.
"""

from __future__ import annotations

import numpy as np

_MASK32 = np.uint64(0xFFFFFFFF)
_INIT_A, _MULT_A = 0x43B0D7E5, 0x931E8875
_INIT_B, _MULT_B = 0x8B51F9DD, 0x58F38DED
_MIX_MULT_L, _MIX_MULT_R = 0xCA01F9DD, 0x4973F715
_XSHIFT = 16
_POOL = 4

_PCG_MULT_HI = np.uint64(0x2360ED051FC65DA4)
_PCG_MULT_LO = np.uint64(0x4385DF649FCCF645)


def entropy_words(value: int) -> list[int]:
    """``value`` (>= 0) as SeedSequence reads an integer: little-endian 32-bit words, [0] for 0."""
    words = [value & 0xFFFFFFFF]
    value >>= 32
    while value:
        words.append(value & 0xFFFFFFFF)
        value >>= 32
    return words


class _Hash:
    """The running multiplier of SeedSequence's ``hashmix`` (one for the whole array: it
    does not depend on the data)."""

    def __init__(self, start: int, mult: int) -> None:
        self.const, self.mult = start, mult

    def mix(self, value: np.ndarray) -> np.ndarray:
        value = value ^ np.uint64(self.const)
        self.const = (self.const * self.mult) & 0xFFFFFFFF
        value = (value * np.uint64(self.const)) & _MASK32
        return value ^ (value >> np.uint64(_XSHIFT))


def _mix(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    result: np.ndarray = np.bitwise_and(
        x * np.uint64(_MIX_MULT_L) - y * np.uint64(_MIX_MULT_R), _MASK32
    )
    return result ^ (result >> np.uint64(_XSHIFT))


def _pool(words: np.ndarray) -> list[np.ndarray]:
    """SeedSequence's entropy pool (4 words) of each row of (M, K) uint32 ``words``."""
    hashed = _Hash(_INIT_A, _MULT_A)
    n_words = words.shape[1]
    zero = np.zeros(words.shape[0], np.uint64)
    pool = [hashed.mix(words[:, i] if i < n_words else zero) for i in range(_POOL)]
    for src in range(_POOL):
        for dst in range(_POOL):
            if src != dst:
                pool[dst] = _mix(pool[dst], hashed.mix(pool[src]))
    for src in range(_POOL, n_words):
        for dst in range(_POOL):
            pool[dst] = _mix(pool[dst], hashed.mix(words[:, src]))
    return pool


def _state_words(pool: list[np.ndarray]) -> list[np.ndarray]:
    """``generate_state(4, uint64)`` of each pool: four uint64 per row."""
    hashed = _Hash(_INIT_B, _MULT_B)
    halves = []
    for i in range(8):
        value = pool[i % _POOL] ^ np.uint64(hashed.const)
        hashed.const = (hashed.const * _MULT_B) & 0xFFFFFFFF
        value = (value * np.uint64(hashed.const)) & _MASK32
        halves.append(value ^ (value >> np.uint64(_XSHIFT)))
    return [halves[2 * i] | (halves[2 * i + 1] << np.uint64(32)) for i in range(4)]


def _mulhi(a: np.ndarray, b: np.uint64) -> np.ndarray:
    """High 64 bits of the 128-bit products ``a * b`` (uint64)."""
    a_lo, a_hi = a & _MASK32, a >> np.uint64(32)
    b_lo, b_hi = b & _MASK32, b >> np.uint64(32)
    lo_lo = a_lo * b_lo
    mid1 = a_hi * b_lo + (lo_lo >> np.uint64(32))
    mid2 = a_lo * b_hi + (mid1 & _MASK32)
    return a_hi * b_hi + (mid1 >> np.uint64(32)) + (mid2 >> np.uint64(32))


class PCG64Rows:
    """M PCG64 generators, one per row, each as ``np.random.PCG64(SeedSequence(entropy))``.

    Args:
        words: (M, K) the uint32 entropy words of each generator (:func:`entropy_words`
            of each integer of the entropy list, concatenated).
    """

    def __init__(self, words: np.ndarray) -> None:
        seed_hi, seed_lo, inc_hi, inc_lo = _state_words(_pool(words.astype(np.uint64)))
        with np.errstate(over="ignore"):
            # pcg64_set_seed: inc = (initseq << 1) | 1; state = 0; step; state += seed; step
            self.inc_hi = (inc_hi << np.uint64(1)) | (inc_lo >> np.uint64(63))
            self.inc_lo = (inc_lo << np.uint64(1)) | np.uint64(1)
            self.hi = np.zeros_like(seed_hi)
            self.lo = np.zeros_like(seed_lo)
            self._step()
            lo = self.lo + seed_lo
            self.hi = self.hi + seed_hi + (lo < seed_lo).astype(np.uint64)
            self.lo = lo
            self._step()

    def _step(self) -> None:
        """state = state * MULT + inc (mod 2**128), every row."""
        hi = self.hi * _PCG_MULT_LO + self.lo * _PCG_MULT_HI + _mulhi(self.lo, _PCG_MULT_LO)
        lo = self.lo * _PCG_MULT_LO
        new_lo = lo + self.inc_lo
        self.hi = hi + self.inc_hi + (new_lo < lo).astype(np.uint64)
        self.lo = new_lo

    def next64(self) -> np.ndarray:
        """(M,) the next uint64 of every generator (step, then XSL RR output)."""
        with np.errstate(over="ignore"):
            self._step()
        xored = self.hi ^ self.lo
        rot = self.hi >> np.uint64(58)
        return (xored >> rot) | (xored << ((np.uint64(64) - rot) & np.uint64(63)))

    def uniform(self, low: float, high: float, size: int) -> np.ndarray:
        """(M, size) what ``Generator.uniform(low, high, size)`` gives for each row."""
        span = float(high) - float(low)
        out = np.empty((self.lo.size, size))
        for j in range(size):
            unit = (self.next64() >> np.uint64(11)).astype(float) * (1.0 / 9007199254740992.0)
            out[:, j] = low + span * unit
        return out
