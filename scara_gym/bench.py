"""``scara-c11 bench``: speed figures, measured side by side in one run.

Task b to its located stop event: the compiled integrator (explicit and implicit
form) against scipy's ``solve_ivp`` with the same model functions, the same
hybrid current-limit modes and the same tolerances.
"""

from __future__ import annotations

import sys
import time

from scara_gym.reference import scipy_point_to_point
from scara_gym.tasks import point_to_point


def _best(run, repeats: int) -> tuple[float, float]:
    """(best runtime [s], reach time [s]) over repeats."""
    times, reach = [], None
    for _ in range(repeats):
        started = time.perf_counter()
        reach = run()
        times.append(time.perf_counter() - started)
    return min(times), reach


def bench_task_b(rtol: float = 1e-6, atol: float = 1e-9, repeats: int = 5,
                 scipy_methods=("RK45", "LSODA")) -> list[dict]:
    point_to_point(rtol=rtol, atol=atol)  # compile / load the cache outside the timing
    point_to_point(form="implicit", rtol=rtol, atol=atol)
    rows = []
    for form in ("explicit", "implicit"):
        best, reach = _best(lambda: point_to_point(form=form, rtol=rtol, atol=atol).reach_time, repeats)
        rows.append({"solver": f"scara_gym compiled DOPRI5, {form}", "runtime": best, "reach": reach})
    for method in scipy_methods:
        best, reach = _best(lambda: scipy_point_to_point(method=method, rtol=rtol, atol=atol)[0],
                            max(1, repeats // 2))
        rows.append({"solver": f"scipy solve_ivp {method}, explicit", "runtime": best, "reach": reach})
    base = rows[0]["runtime"]
    for row in rows:
        row["ratio"] = row["runtime"] / base
    return rows


def format_rows(rows: list[dict], rtol: float, atol: float) -> str:
    lines = [f"Task b to the stop event (rtol {rtol:g}, atol {atol:g}), best of repeats:",
             "| solver | runtime | x our explicit | reach time |", "|---|---|---|---|"]
    for row in rows:
        lines.append(f"| {row['solver']} | {row['runtime'] * 1e3:.3f} ms | {row['ratio']:.1f} "
                     f"| {row['reach']:.6f} s |")
    return "\n".join(lines)


def main(quick: bool = False, stream=sys.stdout) -> str:
    repeats = 2 if quick else 7
    chunks = []
    for rtol, atol in ((1e-6, 1e-9),) if quick else ((1e-6, 1e-9), (1e-10, 1e-12)):
        rows = bench_task_b(rtol, atol, repeats)
        chunks.append(format_rows(rows, rtol, atol))
    text = "\n\n".join(chunks)
    print(text, file=stream)
    return text
