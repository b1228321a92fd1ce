"""The trainers' progress line: steps, steps/s, mean return, success rate and time left, at most
every ``every`` seconds (and on the first and last report), so that a run of hours says it is alive
and a run of seconds still shows one line."""

from __future__ import annotations

import math
import sys
import time


def _duration(seconds: float) -> str:
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, seconds = divmod(rest, 60)
    return f"{hours}h{minutes:02d}m" if hours else f"{minutes}m{seconds:02d}s" if minutes else f"{seconds}s"


def _mean(values) -> float:
    values = list(values)
    return sum(values) / len(values) if values else math.nan


class Progress:
    """Prints ``steps 20,480/1,000,000 (2%)  9,012 steps/s  return -12.3  success 0.45  ETA 1m49s``.
    steps/s counts the steps of this process (a resumed run's earlier steps are not timed here)."""

    def __init__(self, total: int, start_step: int = 0, every: float = 10.0, stream=None) -> None:
        self.total, self.start_step, self.every = int(total), int(start_step), every
        self.stream = stream
        self.started = time.perf_counter()
        self.last_print = -math.inf

    def report(self, steps: int, returns=(), successes=(), final: bool = False) -> str | None:
        """The line, printed if ``every`` seconds passed since the last one (or ``final``)."""
        now = time.perf_counter()
        if not final and now - self.last_print < self.every:
            return None
        self.last_print = now
        rate = (steps - self.start_step) / max(now - self.started, 1e-9)
        left = max(self.total - steps, 0)
        eta = _duration(left / rate) if rate > 0 else "?"
        mean_return, success = _mean(returns), _mean(successes)
        # before the first episode ends there is no return to show: "-", not nan
        shown_return = "-" if math.isnan(mean_return) else f"{mean_return:.1f}"
        shown_success = "-" if math.isnan(success) else f"{success:.2f}"
        line = (f"steps {steps:,}/{self.total:,} ({100 * steps / max(self.total, 1):.0f}%)  {rate:,.0f} steps/s  "
                f"return {shown_return}  success {shown_success}  ETA {eta}")
        print(line, file=self.stream or sys.stdout, flush=True)
        return line


def saved_to(folder) -> str:
    """The last line of a training command: where its run is."""
    line = f"saved to {folder}"
    print(line, flush=True)
    return line
