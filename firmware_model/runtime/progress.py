"""Progress on standard error: one line redrawn in place on a terminal, nothing when stderr is not a terminal
(logs and tests stay clean). The one progress reporter of every long command (vectors, run, evaluate, sweep)."""

from __future__ import annotations

import sys
import time


class Progress:
    """A one-line progress bar on stderr, drawn only when stderr is a terminal (or ``enabled`` forces it):
    ``label [####....] done/total unit rate/s what``, redrawn at most every ``interval`` seconds.

    ``step(what, amount)`` counts work done; ``update(done, total, what)`` sets it (the callback of the harness and of
    ``evaluate_many``);
    ``close()`` ends the line. ``eta``: also show the time left at the mean rate so far."""

    def __init__(self, total: int, label: str, enabled: bool | None = None, unit: str = "samples",
                 interval: float = 0.1, eta: bool = False) -> None:
        self.total = max(total, 1)
        self.label = label
        self.unit = unit
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.interval = interval
        self.eta = eta
        self.done = 0
        self.t0 = time.monotonic()
        self._last = -1.0
        self._open = False

    def step(self, what: str = "", amount: int = 1) -> None:
        self.done += amount
        self._draw(what)

    def update(self, done: int, total: int, what: str = "") -> None:
        self.done, self.total = done, max(total, 1)
        self._draw(what)
        if done >= total:
            self.close()

    def __call__(self, done: int, total: int, what: str = "") -> None:
        self.update(done, total, what)

    def _draw(self, what: str) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self._last < self.interval and self.done < self.total:
            return
        self._last = now
        width = 30
        fill = int(width * min(self.done, self.total) / self.total)
        rate = self.done / max(now - self.t0, 1e-9)
        if self.eta:
            left = (self.total - self.done) / rate if rate > 0 else float("nan")
            what = (f"ETA {left:,.0f} s" if left == left else "ETA -") + (f"  {what}" if what else "")
        sys.stderr.write(f"\r{self.label} [{'#' * fill}{'.' * (width - fill)}] {self.done:,}/{self.total:,} "
                         f"{self.unit} {rate:,.0f}/s {what[:40]:<40}")
        sys.stderr.flush()
        self._open = True

    def close(self) -> None:
        if self.enabled and self._open:
            sys.stderr.write("\n")
            sys.stderr.flush()
            self._open = False
