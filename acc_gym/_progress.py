"""Progress bars of the long commands (``acc-gym campaign``, ``risk``, ``conformance``,
``string-stability``, ``train``): rich, on stderr, shown from the moment the command starts,
with the elapsed time and (once the total is known) the time left.

A bar is shown only when stderr is a terminal (rich's own test, :attr:`rich.console.Console.
is_terminal`, so ``TTY_COMPATIBLE=1`` forces it and ``TTY_COMPATIBLE=0`` turns it off): a log,
a pipe or a test that captures the output gets nothing from it, rather than rich's final
frame. The commands turn it off for ``--json``, so that stdout holds the one JSON object and
stderr only errors.

    with progress_bar("risk", total=budget, unit="episodes", enabled=not args.json) as bar:
        bar.advance(64)
        bar.update(total=1024, description="risk: estimation")
"""

from __future__ import annotations


class ProgressBar:
    """One task of a :class:`rich.progress.Progress` on stderr, or nothing (disabled): the same
    calls either way. Use it as a context manager, or :meth:`start` and :meth:`close`."""

    def __init__(self, description: str, total: float | None = None, *, unit: str = "", enabled: bool = True,
                 console=None):
        self.description, self.total, self.unit = description, total, unit
        self._progress = None
        self._task = None
        if not enabled:
            return
        from rich.console import Console

        console = console if console is not None else Console(stderr=True)
        if not console.is_terminal:
            return
        from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn,
                                   TimeRemainingColumn)

        self._progress = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                                  TextColumn(unit), TimeElapsedColumn(), TextColumn("left"), TimeRemainingColumn(),
                                  console=console, transient=False)

    @property
    def shown(self) -> bool:
        """Whether a bar is drawn (enabled, on a terminal)."""
        return self._progress is not None

    def start(self) -> "ProgressBar":
        if self._progress is not None and self._task is None:
            self._progress.start()
            self._task = self._progress.add_task(self.description, total=self.total)
        return self

    def advance(self, n: float = 1) -> None:
        if self._task is not None:
            self._progress.advance(self._task, n)

    def update(self, *, completed: float | None = None, total: float | None = None,
               description: str | None = None) -> None:
        if self._task is not None:
            kwargs = {k: v for k, v in (("completed", completed), ("total", total), ("description", description))
                      if v is not None}
            self._progress.update(self._task, **kwargs)

    def close(self) -> None:
        if self._progress is not None and self._task is not None:
            self._progress.stop()
            self._task = None

    def __enter__(self) -> "ProgressBar":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()


def progress_bar(description: str, total: float | None = None, *, unit: str = "", enabled: bool = True,
                 console=None) -> ProgressBar:
    """A :class:`ProgressBar` (not started: ``with progress_bar(...) as bar:`` starts it);
    ``total`` None: not known yet (:meth:`ProgressBar.update` sets it)."""
    return ProgressBar(description, total, unit=unit, enabled=enabled, console=console)
