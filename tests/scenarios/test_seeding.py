"""``acc_gym.scenarios._seeding``: a scenario's generators made by the compiled
``SeedSequence`` algorithm are numpy's own children, in the same state.

Checked against ``numpy.random.SeedSequence(entropy).spawn(n)`` for seeds on both sides of
every 32-bit word boundary (one, two and three words of entropy, so with and without numpy's
padding to the pool size), ids whose CRC is small or large, and more than two children; the
seed sequence the generators carry answers ``spawn``, other state sizes and its attributes
as the real one does, and survives pickling."""

from __future__ import annotations

import pickle
import zlib

import numpy as np
import pytest

from acc_gym.scenarios._seeding import int_words, spawned_generators
from acc_gym.scenarios.registry import scenario_rngs

SEEDS = [0, 1, 7, 2 ** 31 - 1, 2 ** 32 - 1, 2 ** 32, 2 ** 32 + 5, 2 ** 40, 2 ** 63 - 1, 2 ** 64 - 1, 2 ** 64,
         2 ** 96 + 3, 2 ** 130]


def numpy_children(entropy, n):
    return [np.random.default_rng(c) for c in np.random.SeedSequence(entropy).spawn(n)]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("first", [0, 1, 0xFFFFFFFF, zlib.crc32(b"singlelane/2/cut-in")])
def test_children_equal_numpys_spawned_children(first, seed):
    ours = spawned_generators([first, seed], 3)
    ref = numpy_children([first, seed], 3)
    for a, b in zip(ours, ref):
        assert a.bit_generator.state == b.bit_generator.state
        assert np.array_equal(a.random(20), b.random(20))
        assert np.array_equal(a.standard_normal(7), b.standard_normal(7))


def test_many_random_seeds_equal_numpy():
    rng = np.random.default_rng(3)
    for _ in range(300):
        entropy = [int(rng.integers(0, 2 ** 32)), int(rng.integers(0, 2 ** 62))]
        for a, b in zip(spawned_generators(entropy), numpy_children(entropy, 2)):
            assert a.bit_generator.state == b.bit_generator.state


def test_scenario_rngs_are_the_spawned_children_of_id_and_seed():
    for sid, seed in (("singlelane/1/free-flow", 0), ("ncap/ccrs/30", 2 ** 40), ("carfollowing/90", 123)):
        ours = scenario_rngs(sid, seed)
        ref = numpy_children([zlib.crc32(sid.encode()), seed], 2)
        assert [a.bit_generator.state for a in ours] == [b.bit_generator.state for b in ref]


def test_the_seed_sequence_answers_as_numpys():
    """``spawn``, other ``generate_state`` sizes and the attributes come from the real
    ``SeedSequence`` (made on first use); a pickled generator continues identically."""
    entropy = [12345, 2 ** 33 + 9]
    ours = spawned_generators(entropy)[1].bit_generator.seed_seq
    real = np.random.SeedSequence(entropy).spawn(2)[1]
    assert ours.spawn_key == real.spawn_key == (1,) and ours.entropy == real.entropy
    assert np.array_equal(ours.generate_state(5), real.generate_state(5))
    assert np.array_equal(ours.generate_state(4, np.uint64), real.generate_state(4, np.uint64))
    for a, b in zip(ours.spawn(2), real.spawn(2)):
        assert np.array_equal(np.random.default_rng(a).random(4), np.random.default_rng(b).random(4))
    g = spawned_generators(entropy)[0]
    g.random(3)
    copy = pickle.loads(pickle.dumps(g))
    assert np.array_equal(copy.random(10), g.random(10))


def test_int_words_are_numpys_reading_of_an_integer():
    for n in SEEDS:
        words = int_words(n)
        assert sum(w << (32 * i) for i, w in enumerate(words)) == n and all(0 <= w < 2 ** 32 for w in words)
        assert len(words) == max(1, (n.bit_length() + 31) // 32)
