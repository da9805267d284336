"""A private split: episodes nobody outside the host can know, drawn from a host's secret.

The ``dev`` and ``test`` splits ship with the package, in a fixed order: anyone can run
them offline and tune a controller to them, episode by episode. For an official ranking
the host keeps a secret (a file, or the environment variable :data:`SECRET_ENV`) and runs
``acc-gym leaderboard --split private --secret FILE``:

* each suite's private root seed is ``HMAC-SHA256(secret, "acc_gym.suites:<name>:private")``
  (its first 8 bytes), so the episodes are a pure function of (secret, suite) -- the same
  secret reruns the same episodes -- and differ from dev and test;
* the suite's own generator draws as many episodes as the test split holds, and they are
  shuffled by a generator seeded from the same root (:meth:`Suite.private_episodes`),
  so neither the episodes nor their order come from anything shipped;
* the manifest records only a commitment, ``sha256("acc_gym.leaderboard.secret/1" NUL
  secret)``: a host can later prove which secret a table used by revealing it, and a
  reader of the table learns nothing about the episodes from it.

Intended use: **develop on dev, publish reproducible tables on test, rank officially on
private.** The per-episode records in ``results.json`` and ``report.html`` of a private
run name the episodes they ran (scenario id, parameters, seed): publish the ranking
(``leaderboard.md``, ``results.csv``), keep those two files with the host, and choose a
new secret once they are out. A secret shorter than :data:`MIN_SECRET_BYTES` bytes is
refused (it could be guessed and the episodes regenerated).
"""

from __future__ import annotations

import hashlib
import hmac
import os
from pathlib import Path

SECRET_ENV = "ACC_GYM_LEADERBOARD_SECRET"
MIN_SECRET_BYTES = 16
PRIVATE = "private"


def check_secret(secret, where: str = "the secret") -> bytes:
    if isinstance(secret, str):
        secret = secret.encode("utf-8")
    if not isinstance(secret, (bytes, bytearray)):
        raise TypeError(f"{where} must be bytes or text, got {type(secret).__name__}")
    secret = bytes(secret).strip()
    if len(secret) < MIN_SECRET_BYTES:
        raise ValueError(f"{where} is {len(secret)} bytes long; a private split needs at least {MIN_SECRET_BYTES} "
                         f"(e.g. python -c 'import secrets; print(secrets.token_hex(32))' > secret.txt)")
    return secret


def read_secret(path=None) -> bytes:
    """The secret in the file ``path`` (surrounding whitespace removed), or, without a path,
    in the environment variable :data:`SECRET_ENV`; ``ValueError`` naming what is missing."""
    if path is not None:
        path = Path(path)
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise ValueError(f"cannot read the secret file {str(path)!r}: {exc.strerror or exc}") from None
        return check_secret(data, f"the secret in {str(path)!r}")
    value = os.environ.get(SECRET_ENV)
    if value is None:
        raise ValueError(f"the private split needs a secret: --secret FILE, or the environment variable {SECRET_ENV}")
    return check_secret(value, f"the secret in ${SECRET_ENV}")


def commitment(secret: bytes) -> str:
    """What the manifest records instead of the secret."""
    return "sha256:" + hashlib.sha256(b"acc_gym.leaderboard.secret/1\0" + check_secret(secret)).hexdigest()


def private_root_seed(secret: bytes, suite: str) -> int:
    """The suite's private root seed (64 bits of HMAC-SHA256 keyed by the secret)."""
    mac = hmac.new(check_secret(secret), f"acc_gym.suites:{suite}:{PRIVATE}".encode(), hashlib.sha256)
    return int.from_bytes(mac.digest()[:8], "big")


def private_episodes(suite, secret: bytes):
    """The suite's private episodes for this secret (see the module docstring)."""
    return suite.private_episodes(private_root_seed(secret, suite.name))
