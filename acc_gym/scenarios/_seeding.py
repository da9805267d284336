"""A scenario's two generators, as numpy's ``SeedSequence`` makes them, in one compiled call.

:func:`acc_gym.scenarios.registry.scenario_rngs` gives each ``(id, seed)`` the two children
of ``SeedSequence([crc32(id), seed])`` (spawn keys ``(0,)`` and ``(1,)``), and every reset
draws a scenario: numpy's ``SeedSequence`` builds each child's entropy pool and its PCG64
seed words in Python-level loops, about 10 us a child. :func:`children_states` runs the same
algorithm -- numpy's ``SeedSequence.mix_entropy`` and ``generate_state`` (the hash and mix
functions of Melissa O'Neill's ``seed_seq_fe``, numpy/random/bit_generator.pyx), on 32-bit
words -- for both children at once, and :class:`SpawnedSeed` hands each child's words to
``PCG64`` as an ``ISeedSequence``, so the generators are numpy's own, in the same state
(``tests/scenarios/test_seeding.py`` compares states and draws with numpy's for seeds across
the word boundaries). Anything else a caller asks of such a generator's seed sequence
(``spawn``, other ``generate_state`` sizes, ``entropy``, ``spawn_key``, ...) is answered by
the real ``SeedSequence``, made on first use.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.random.bit_generator import ISpawnableSeedSequence

POOL_SIZE = 4  # numpy's DEFAULT_POOL_SIZE (32-bit words)
_M32 = np.uint64(0xFFFFFFFF)
_INIT_A = np.uint64(0x43B0D7E5)
_MULT_A = np.uint64(0x931E8875)
_INIT_B = np.uint64(0x8B51F9DD)
_MULT_B = np.uint64(0x58F38DED)
_MIX_MULT_L = np.uint64(0xCA01F9DD)
_MIX_MULT_R = np.uint64(0x4973F715)
_XSHIFT = np.uint64(16)  # half a 32-bit word


@numba.njit(cache=True)
def _hashmix(value, hash_const):  # pragma: no cover - compiled
    """numpy's ``hashmix``: ``(value, hash_const)`` after one mixing step (32-bit words in uint64)."""
    value = value ^ hash_const
    hash_const = (hash_const * _MULT_A) & _M32
    value = (value * hash_const) & _M32
    return value ^ (value >> _XSHIFT), hash_const


@numba.njit(cache=True)
def _mix(x, y):  # pragma: no cover - compiled
    result = (_MIX_MULT_L * x - _MIX_MULT_R * y) & _M32  # uint64 wraps modulo 2**64, so modulo 2**32 after the mask
    return result ^ (result >> _XSHIFT)


@numba.njit(cache=True)
def children_states(run, n_children, out):  # pragma: no cover - compiled
    """PCG64's seed words of the children ``0 .. n_children - 1`` of a ``SeedSequence`` whose
    entropy is the 32-bit words ``run`` (uint64 array, at least :data:`POOL_SIZE` long: numpy
    pads a short entropy with zeros to the pool size when there is a spawn key), written to
    ``out[j]`` (``(n_children, 4)`` uint64): child ``j``'s ``generate_state(4, np.uint64)``."""
    n = run.shape[0]
    entropy = np.empty(n + 1, dtype=np.uint64)
    entropy[:n] = run
    pool = np.empty(POOL_SIZE, dtype=np.uint64)
    words = np.empty(2 * out.shape[1], dtype=np.uint64)
    for j in range(n_children):
        entropy[n] = np.uint64(j)  # the spawn key (j,)
        hash_const = _INIT_A
        for i in range(POOL_SIZE):  # mix_entropy: the entropy up to the pool size
            pool[i], hash_const = _hashmix(entropy[i], hash_const)
        for i_src in range(POOL_SIZE):  # every word into every other
            for i_dst in range(POOL_SIZE):
                if i_src != i_dst:
                    h, hash_const = _hashmix(pool[i_src], hash_const)
                    pool[i_dst] = _mix(pool[i_dst], h)
        for i_src in range(POOL_SIZE, n + 1):  # the remaining entropy words into every pool word
            for i_dst in range(POOL_SIZE):
                h, hash_const = _hashmix(entropy[i_src], hash_const)
                pool[i_dst] = _mix(pool[i_dst], h)
        hash_const = _INIT_B
        for i in range(words.shape[0]):  # generate_state: the pool's words in a cycle
            value = pool[i % POOL_SIZE] ^ hash_const
            hash_const = (hash_const * _MULT_B) & _M32
            value = (value * hash_const) & _M32
            words[i] = value ^ (value >> _XSHIFT)
        for k in range(out.shape[1]):  # 32-bit words as little-endian 64-bit ones
            out[j, k] = words[2 * k] | (words[2 * k + 1] << np.uint64(32))


def int_words(n: int) -> list[int]:
    """A non-negative integer as numpy's ``SeedSequence`` reads it: its 32-bit words, least
    significant first (``[0]`` for 0)."""
    words = [n & 0xFFFFFFFF]
    n >>= 32
    while n:
        words.append(n & 0xFFFFFFFF)
        n >>= 32
    return words


class SpawnedSeed(ISpawnableSeedSequence):
    """Child ``key`` of ``SeedSequence(entropy)`` as PCG64 needs it: its seed words, computed
    (:func:`children_states`); every other question goes to the real
    ``SeedSequence(entropy, spawn_key=(key,))``, made on first use."""

    __slots__ = ("_entropy", "_key", "_words", "_real")

    def __init__(self, entropy: list, key: int, words: np.ndarray):
        self._entropy, self._key, self._words, self._real = entropy, key, words, None

    def real(self) -> np.random.SeedSequence:
        if self._real is None:
            self._real = np.random.SeedSequence(self._entropy, spawn_key=(self._key,))
        return self._real

    def generate_state(self, n_words, dtype=np.uint32):
        if n_words == 4 and np.dtype(dtype) == np.uint64:  # what PCG64 asks for
            return self._words.copy()
        return self.real().generate_state(n_words, dtype)

    def spawn(self, n_children):
        return self.real().spawn(n_children)

    def __getattr__(self, name):  # entropy, spawn_key, pool, n_children_spawned, ...
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.real(), name)

    def __reduce__(self):
        return SpawnedSeed, (self._entropy, self._key, self._words)


def spawned_generators(entropy: list, n: int = 2) -> list[np.random.Generator]:
    """The generators of the first ``n`` children of ``SeedSequence(entropy)`` (what
    ``[np.random.default_rng(c) for c in SeedSequence(entropy).spawn(n)]`` gives), for
    ``entropy`` a list of non-negative integers."""
    run = [w for value in entropy for w in int_words(int(value))]
    run += [0] * (POOL_SIZE - len(run))  # numpy pads a short entropy when there is a spawn key
    states = np.empty((n, 4), dtype=np.uint64)
    children_states(np.array(run, dtype=np.uint64), n, states)
    return [np.random.Generator(np.random.PCG64(SpawnedSeed(entropy, j, states[j]))) for j in range(n)]
