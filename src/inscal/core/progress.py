"""The progress of long work on standard error, one way for every command: a Rich bar on a terminal, a plain
line now and then in a log or CI (at every tenth of the work and at least every half minute), nothing when
disabled.  What a line says is the caller's (runs, records, candidates and their time left)."""

from __future__ import annotations

import sys
import time
from typing import Callable

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn


def duration(seconds: float) -> str:
    """``42 s``, ``3 min 05 s``, ``2 h 07 min``."""
    s = round(max(0.0, seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class ProgressBar:
    """``name``'s progress through ``total`` items on standard error.

    On a terminal a Rich bar (done / total, the time elapsed and the caller's ``note``), removed at the end when
    ``transient``; otherwise, when ``lines``, the caller's plain line at every ``step_pct`` percent of the total,
    at least every ``every_s`` seconds (None: no such minimum) and at the end; nothing when not ``enabled``.
    """

    def __init__(self, name: str, total: int, enabled: bool = True, lines: bool = True, step_pct: int = 10,
                 every_s: float | None = 30.0, transient: bool = False):
        self.name, self.total, self.done = name, total, 0
        self.step_pct, self.next_pct, self.every_s = step_pct, step_pct, every_s
        self.t0 = self.t_last = time.perf_counter()
        self.bar, self.plain = None, False
        if not enabled:
            return
        con = Console(stderr=True)
        if not con.is_terminal:  # no bar (nor its stray newline) in a log or a pipe
            self.plain = lines
            return
        self.bar = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                            TextColumn("{task.fields[note]}"), TimeElapsedColumn(), console=con, transient=transient)
        self.bar.start()
        self.task = self.bar.add_task(name, total=total, note="")

    @property
    def elapsed_s(self) -> float:
        """Seconds since the bar was made."""
        return time.perf_counter() - self.t0

    def update(self, done: int, total: int | None = None, note: str = "",
               line: Callable[[], str] | str | None = None) -> None:
        """``done`` items of ``total`` (None: as before) are done; ``note`` follows the bar; ``line`` (a string, or
        a function making it) is the plain line, printed when one is due (default ``NAME: DONE/TOTAL``)."""
        self.done = done
        if total is not None:
            self.total = total
        if self.bar is not None:
            self.bar.update(self.task, completed=done, total=self.total, note=note)
            return
        if not self.plain:
            return
        now = time.perf_counter()
        pct = 100.0 * done / max(1, self.total)
        late = self.every_s is not None and now - self.t_last >= self.every_s
        if pct >= self.next_pct or late or done >= self.total:
            text = line() if callable(line) else line
            self.print(text if text is not None else f"{self.name}: {done}/{self.total}")
            self.t_last = now
            while self.next_pct <= pct:
                self.next_pct += self.step_pct

    def print(self, text: str) -> None:
        """``text`` on standard error as a line of its own (above the bar on a terminal)."""
        if self.bar is not None:
            self.bar.console.print(text, markup=False, highlight=False, soft_wrap=True)
        else:
            print(text, file=sys.stderr, flush=True)

    def close(self) -> None:
        """Stop the bar (a plain line needs no closing)."""
        if self.bar is not None:
            self.bar.stop()

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
