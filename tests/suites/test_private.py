"""The private split: a pure function of (secret, suite), unlike dev and test, shuffled,
and never recorded except as a commitment."""

import numpy as np
import pytest

from acc_gym.suites import get_suite, list_suites
from acc_gym.suites import private
from acc_gym.suites.suite import PRIVATE_ORDER_STREAM, entry

SECRET = b"host secret: 7f3a9c0e51d24b86a1"
OTHER = b"another host's secret 0123456789"


def entries(scenarios):
    return [entry(s) for s in scenarios]


@pytest.mark.parametrize("name", ["carfollowing-v1", "ncap-v1", "malicious-v3"])
def test_private_episodes_are_a_pure_function_of_secret_and_suite(name):
    s = get_suite(name)
    a = entries(private.private_episodes(s, SECRET))
    assert a == entries(private.private_episodes(s, bytearray(SECRET)))  # the same secret, the same episodes
    assert len(a) == len(s.to_dict()["episodes"]["test"])  # as many as the test split
    b = entries(private.private_episodes(s, OTHER))
    assert a != b and not {repr(e) for e in a} & {repr(e) for e in b}
    public = {repr(e) for sp in ("dev", "test") for e in s.to_dict()["episodes"][sp]}
    assert not {repr(e) for e in a} & public  # not one episode of dev or test
    # the suite's own generator, from the HMAC-derived root seed, in a shuffled order
    root = private.private_root_seed(SECRET, name)
    drawn = entries(s._drawn(i, root) for i in range(len(a)))
    order = np.random.default_rng([root, PRIVATE_ORDER_STREAM]).permutation(len(a))
    assert a == [drawn[k] for k in order] and list(order) != sorted(order)
    assert sorted(map(repr, a)) == sorted(map(repr, drawn))


def test_the_hours_sized_suite_draws_about_its_hours():
    s = get_suite("singlelane-v3")
    eps = private.private_episodes(s, SECRET)
    total = sum(sc.duration for sc in eps)
    assert total >= 3600.0 and total - max(sc.duration for sc in eps) < 3600.0


def test_root_seeds_differ_per_suite_and_secret():
    seeds = {(n, k): private.private_root_seed(sec, n) for n in list_suites() for k, sec in enumerate((SECRET, OTHER))}
    assert len(set(seeds.values())) == len(seeds)
    assert all(0 <= v < 2 ** 64 for v in seeds.values())


def test_commitment_hides_the_secret_and_binds_it():
    c = private.commitment(SECRET)
    assert c.startswith("sha256:") and SECRET.decode() not in c and SECRET.hex() not in c
    assert c == private.commitment(SECRET.decode() + "\n") != private.commitment(OTHER)


def test_secrets_are_read_from_a_private_file_never_the_environment(tmp_path, monkeypatch):
    f = tmp_path / "secret.txt"
    f.write_bytes(SECRET + b"\n")
    f.chmod(0o600)
    assert private.read_secret(f) == SECRET
    with pytest.raises(ValueError, match="needs a secret: --secret FILE"):
        private.read_secret()
    monkeypatch.setenv(private.SECRET_ENV, OTHER.decode())
    with pytest.raises(ValueError, match="ACC_GYM_LEADERBOARD_SECRET is set"):
        private.read_secret(f)
    monkeypatch.delenv(private.SECRET_ENV)
    with pytest.raises(ValueError, match=r"cannot read the secret file .*missing\.txt"):
        private.read_secret(tmp_path / "missing.txt")
    f.write_text("short\n")
    with pytest.raises(ValueError, match=r"secret in .*secret\.txt' is 5 bytes long; .* at least 16"):
        private.read_secret(f)
    with pytest.raises(ValueError, match="at least 16"):
        private.private_root_seed(b"", "ncap-v1")
