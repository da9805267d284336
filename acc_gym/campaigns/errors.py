"""The errors a campaign raises (both are ``ValueError`` subclasses, so callers that
already turn ``ValueError`` into a usage message keep working)."""

from __future__ import annotations


class CampaignError(ValueError):
    """A campaign cannot go on: bad settings, a settings mismatch with what the output
    directory already holds, or an output file that is corrupted. The message names the
    value or the file."""


class MissingDependencyError(ImportError):
    """An optional dependency a campaign needs is not installed; the message says what to install."""


def require_pyarrow():
    """``pyarrow`` and ``pyarrow.parquet``, or a :class:`MissingDependencyError` saying what to install."""
    try:
        import pyarrow
        import pyarrow.parquet as pq
    except ImportError as exc:  # pragma: no cover - exercised only without pyarrow
        raise MissingDependencyError(
            f"Monte Carlo campaigns store their results as Parquet and need pyarrow, which is not installed "
            f"({exc}): pip install 'acc-gym[campaign]' (or: pip install pyarrow)") from None
    return pyarrow, pq


def require_distributed():
    """``dask.distributed``, or a :class:`MissingDependencyError` saying what to install."""
    try:
        import distributed
    except ImportError as exc:  # pragma: no cover - exercised only without dask
        raise MissingDependencyError(
            f"running a campaign on a Dask cluster (--scheduler) needs dask.distributed, which is not installed "
            f"({exc}): pip install 'acc-gym[dist]' (or run on local processes with --workers N)") from None
    return distributed
