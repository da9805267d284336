"""The wire between the trusted leaderboard runner and a controller's sandboxed process.

Only numbers and short text cross it, in fixed binary frames; the trusted side never
unpickles anything the controller's process sends (a pickle is code), reads at most
what a frame announces (bounded), and times every read against a deadline.

Frames (little-endian ``<4sII`` header: a tag, then two counts):

=========  ==================  ======================================================
tag        direction           then
=========  ==================  ======================================================
``ACCH``   controller -> run   nothing: the controller is loaded, ready for steps
``ACCO``   run -> controller   ``n`` rows of ``d`` observations: ``n`` bytes of
                               episode-start flags (1: this row starts a new episode),
                               ``n`` uint16 slot numbers (which episode in flight each
                               row belongs to), then ``n * d`` float64 observations
``ACCA``   controller -> run   ``n`` float64 actions, one per row, in row order
``ACCE``   controller -> run   an error: ``n`` bytes of UTF-8 text (at most 64 KiB;
                               received through :func:`clean_text`)
``ACCB``   run -> controller   goodbye: the controller's process exits
=========  ==================  ======================================================
"""

from __future__ import annotations

import math
import re
import socket
import struct
import time

import numpy as np

HEADER = struct.Struct("<4sII")
TIME_GAP = struct.Struct("<d")  # the ready message's payload: the declared time gap [s], 0.0 for none
MAX_TIME_GAP = 60.0  # [s]
HELLO, OBS, ACT, ERR, BYE = b"ACCH", b"ACCO", b"ACCA", b"ACCE", b"ACCB"
MAX_ROWS = 4096
MAX_DIM = 64
MAX_TEXT = 65536  # [bytes] of an error message


# what a terminal, a Markdown viewer or an editor would act on: escape sequences (CSI, OSC, the
# two-byte ones, 8-bit CSI), every other C0 and C1 control but newline and tab (carriage return,
# backspace, bell, ESC itself) and the bidirectional overrides that reorder a line on screen
_ESCAPE = re.compile(r"\x1b(?:\[[0-?]*[ -/]*[@-~]|\][^\x07\x1b]*(?:\x07|\x1b\\)?|[PX^_][^\x1b]*(?:\x1b\\)?|"
                     r"[ -/]*[0-~])|\x9b[0-?]*[ -/]*[@-~]")
_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f\u200e\u200f\u202a-\u202e\u2066-\u2069]")


def clean_text(text: str) -> str:
    """``text`` from a controller's process as the runner may print and write it: escape
    sequences removed, then every control character but newline and tab."""
    return _CONTROL.sub("", _ESCAPE.sub("", text))


class ProtocolError(RuntimeError):
    """The other side broke the protocol (a wrong tag, size or count)."""


class Timeout(RuntimeError):
    """The other side did not answer before the deadline."""


class Closed(RuntimeError):
    """The other side closed the connection (its process ended)."""


class ControllerError(RuntimeError):
    """The controller's process reported an error (its text: reason, then traceback)."""


def recv_exact(sock: socket.socket, n: int, deadline: float | None) -> bytes:
    """Exactly ``n`` bytes, or :class:`Timeout` past ``deadline`` (``time.monotonic``), or :class:`Closed`."""
    buf = bytearray()
    while len(buf) < n:
        if deadline is not None:
            left = deadline - time.monotonic()
            if left <= 0:
                raise Timeout()
            sock.settimeout(left)
        else:
            sock.settimeout(None)
        try:
            chunk = sock.recv(min(n - len(buf), 1 << 20))
        except socket.timeout:
            raise Timeout() from None
        except (ConnectionResetError, BrokenPipeError):
            raise Closed() from None
        if not chunk:
            raise Closed()
        buf += chunk
    return bytes(buf)


def send_frame(sock: socket.socket, tag: bytes, a: int = 0, b: int = 0, payload: bytes = b"") -> None:
    try:
        sock.sendall(HEADER.pack(tag, a, b) + payload)
    except (BrokenPipeError, ConnectionResetError):
        raise Closed() from None


def recv_header(sock: socket.socket, deadline: float | None) -> tuple[bytes, int, int]:
    return HEADER.unpack(recv_exact(sock, HEADER.size, deadline))


# -- the trusted side -------------------------------------------------------------------------
def send_observations(sock: socket.socket, obs: np.ndarray, starts: np.ndarray, slots: np.ndarray) -> None:
    obs = np.ascontiguousarray(obs, dtype="<f8")
    starts = np.ascontiguousarray(starts, dtype=np.uint8)
    slots = np.ascontiguousarray(slots, dtype="<u2")
    send_frame(sock, OBS, obs.shape[0], obs.shape[1], starts.tobytes() + slots.tobytes() + obs.tobytes())


def recv_actions(sock: socket.socket, n: int, deadline: float | None) -> np.ndarray:
    """``n`` actions as float32 (the env's dtype), or :class:`ProtocolError` with the
    controller's own error text when it sent one."""
    tag, a, _ = recv_header(sock, deadline)
    if tag == ERR:
        if a > MAX_TEXT:
            raise ProtocolError(f"an error message of {a} bytes (at most {MAX_TEXT})")
        raise ControllerError(clean_text(recv_exact(sock, a, deadline).decode("utf-8", "replace")))
    if tag != ACT:
        raise ProtocolError(f"expected actions, got a frame tagged {tag!r}")
    if a != n:
        raise ProtocolError(f"answered {a} actions for {n} observations")
    values = np.frombuffer(recv_exact(sock, 8 * n, deadline), dtype="<f8")
    return values.astype(np.float32)


def recv_hello(sock: socket.socket, deadline: float | None) -> float | None:
    """The ready message: the time gap the controller declares [s] (None: none), checked."""
    tag, a, _ = recv_header(sock, deadline)
    if tag == ERR:
        if a > MAX_TEXT:
            raise ProtocolError(f"an error message of {a} bytes (at most {MAX_TEXT})")
        raise ControllerError(clean_text(recv_exact(sock, a, deadline).decode("utf-8", "replace")))
    if tag != HELLO:
        raise ProtocolError(f"expected the ready message, got a frame tagged {tag!r}")
    if a != TIME_GAP.size:
        raise ProtocolError(f"a ready message of {a} bytes (expected {TIME_GAP.size})")
    (value,) = TIME_GAP.unpack(recv_exact(sock, a, deadline))
    if value == 0.0:
        return None
    if not (math.isfinite(value) and 0.0 < value <= MAX_TIME_GAP):
        raise ProtocolError(f"declared a time gap of {value!r} s (a finite number in (0, {MAX_TIME_GAP:g}] expected)")
    return value


def send_hello(sock: socket.socket, time_gap: float | None) -> None:
    """The controller's side of the ready message (its declared time gap, 0.0 for none)."""
    send_frame(sock, HELLO, TIME_GAP.size, 0, TIME_GAP.pack(0.0 if time_gap is None else float(time_gap)))


# -- the controller's side -----------------------------------------------------------------------
def recv_observations(sock: socket.socket) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The next batch ``(obs (n, d), starts (n,) bool, slots (n,) int)``, or None on goodbye."""
    tag, n, d = recv_header(sock, None)
    if tag == BYE:
        return None
    if tag != OBS or not (0 < n <= MAX_ROWS and 0 < d <= MAX_DIM):
        raise ProtocolError(f"unexpected frame {tag!r} ({n} x {d})")
    starts = np.frombuffer(recv_exact(sock, n, None), dtype=np.uint8).astype(bool)
    slots = np.frombuffer(recv_exact(sock, 2 * n, None), dtype="<u2").astype(int)
    obs = np.frombuffer(recv_exact(sock, 8 * n * d, None), dtype="<f8").reshape(n, d)
    return obs, starts, slots


def send_actions(sock: socket.socket, actions: np.ndarray) -> None:
    actions = np.ascontiguousarray(actions, dtype="<f8")
    send_frame(sock, ACT, actions.shape[0], 0, actions.tobytes())


def send_error(sock: socket.socket, text: str) -> None:
    data = text.encode("utf-8", "replace")[:MAX_TEXT]
    send_frame(sock, ERR, len(data), 0, data)
