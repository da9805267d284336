"""A private split: episodes nobody outside the host can know, drawn from a host's secret.

The ``dev`` and ``test`` splits ship with the package, in a fixed order: anyone can run
them offline and tune a controller to them, episode by episode. For an official ranking
the host keeps a secret in a file only its owner can read (mode 0600; never in the
environment: :func:`read_secret`) and runs ``acc-gym leaderboard --split private --secret FILE``:

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
new secret once they are out. The leaderboard writes a private run's files readable by the
host only (0600 files in a 0700 directory) and runs strangers' controllers on it only under
user ids of their own (:func:`acc_gym.leaderboard.sandbox.vet`). A secret shorter than :data:`MIN_SECRET_BYTES` bytes is
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
                         f"(e.g. (umask 077; python -c 'import secrets; print(secrets.token_hex(32))' > secret.txt))")
    return secret


def read_private_file(path, what: str) -> bytes:
    """The bytes of ``path``, a file only its owner may read: ``ValueError`` naming the file and
    its mode when group or others may read or write it (``chmod 600``), or when it cannot be read."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            mode = os.fstat(f.fileno()).st_mode
            data = f.read()
    except OSError as exc:
        raise ValueError(f"cannot read {what} file {str(path)!r}: {exc.strerror or exc}") from None
    if mode & 0o077:
        raise ValueError(f"{what} file {str(path)!r} is mode {mode & 0o777:04o}: group or others may read it; "
                         f"it must be readable by its owner only (chmod 600 {str(path)!r})")
    return data


def read_secret(path=None) -> bytes:
    """The secret in the file ``path`` (surrounding whitespace removed), which only its owner may
    read (:func:`read_private_file`). Never from the environment: ``ValueError`` when no path
    is given, or when :data:`SECRET_ENV` is set (a process of the host's user could read it in
    the runner's environment)."""
    if os.environ.get(SECRET_ENV) is not None:
        raise ValueError(f"the environment variable {SECRET_ENV} is set: the secret is read from a file only "
                         f"(--secret FILE, mode 0600), never from the environment, where a process of the same "
                         f"user can read it; unset it")
    if path is None:
        raise ValueError("the private split needs a secret: --secret FILE, a file only its owner can read "
                         "(e.g. (umask 077; python -c 'import secrets; print(secrets.token_hex(32))' > secret.txt))")
    return check_secret(read_private_file(path, "the secret"), f"the secret in {str(Path(path))!r}")


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
