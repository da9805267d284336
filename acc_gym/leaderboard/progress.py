"""What ``acc-gym leaderboard`` shows while it runs: a rich progress bar on standard error.

The bar counts episodes, controller by controller, with the elapsed time: one more each time
the runner accepts an episode's record from a simulation process (trusted code; nothing the
controller sends moves it), and a controller's whole share once it ends (a failed one's
unrun episodes too). Until the first episode ends the total is not known (the bar pulses). Its line
says what runs now: the kernels (with a notice when a first run compiles them), then the
controllers in flight (the runner starts them in the order given, ``workers`` at a time).
Each controller's end is printed above the bar (its episodes, time, and the reason if it
failed). On a terminal the bar redraws in place; elsewhere (a CI log) rich prints the lines
without redrawing.
"""

from __future__ import annotations

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn


class LeaderboardProgress:
    """The bar for ``names`` (controllers, in the order they start) on ``suites`` suites (named in
    the bar's line)."""

    def __init__(self, names: list[str], suites: int, workers: int, console: Console | None = None):
        self.names, self.suites, self.workers = list(names), int(suites), int(workers)
        self.console = console or Console(stderr=True)
        self.done: list[str] = []
        self.running: list[str] = []
        self.scheduled: int | None = None  # episodes per controller, known from the first one's report
        self.received: dict[str, int] = {}  # episodes received so far, per controller
        unit = f"episodes of {self.suites} suite{'s' if self.suites != 1 else ''}"
        self.bar = Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(bar_width=30),
                            MofNCompleteColumn(), TextColumn(unit), TimeElapsedColumn(),
                            console=self.console, transient=True)
        self.task = self.bar.add_task("checking the suites and controllers", total=None)

    def __enter__(self):
        self.bar.start()
        return self

    def __exit__(self, *exc):
        self.bar.stop()
        return False

    def _describe(self) -> None:
        shown = ", ".join(self.running[:3]) + (" ..." if len(self.running) > 3 else "")
        self.bar.update(self.task, description=f"running {shown}" if shown else "writing the results")

    def phase(self, name: str, notice: str | None) -> None:
        """A stage starts (:func:`acc_gym.leaderboard.run.run_leaderboard`'s ``phase``)."""
        if notice:
            self.bar.console.print(notice, soft_wrap=True)
        if name == "kernels":
            self.bar.update(self.task, description="compiling kernels" if notice else "loading kernels")
        elif name == "waves":
            self.bar.update(self.task, description="driving the all-human rings of the wave column")
        elif name == "controllers":
            self.running = self.names[:self.workers]
            self._describe()

    def _count(self) -> None:
        if self.scheduled is not None:
            done = len(self.done) * self.scheduled + sum(k for n, k in self.received.items() if n not in self.done)
            self.bar.update(self.task, total=len(self.names) * self.scheduled, completed=done)

    def episode(self, name: str, received: int, scheduled: int) -> None:
        """An episode of ``name`` ended (``episode_progress``): ``received`` of its ``scheduled``."""
        self.scheduled = int(scheduled)
        self.received[name] = int(received)
        self._count()

    def finished(self, outcome) -> None:
        """A controller ended (``progress(outcome)``): print it, advance, name the next in flight."""
        name = outcome.reference
        state = "ok" if outcome.status == "ok" else f"FAILED: {outcome.reason}"
        self.bar.console.print(f"  {name}: {len(outcome.episodes)} episodes in {outcome.wall_time_s:.1f} s, {state}",
                               markup=False, highlight=False, soft_wrap=True)
        self.done.append(name)
        if name in self.running:
            self.running.remove(name)
        waiting = [n for n in self.names if n not in self.done and n not in self.running]
        while waiting and len(self.running) < self.workers:
            self.running.append(waiting.pop(0))
        self._count()
        self._describe()
