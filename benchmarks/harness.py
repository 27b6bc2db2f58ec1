"""Timing harness: medians of repeats, camkit and its peer measured in the same run."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Case:
    """One row of the table: an operation timed in camkit and in a peer library."""

    operation: str
    size: str
    camkit: Callable[[], object]
    peer_name: str
    peer: Callable[[], object]
    target: float | None = None  # the ratio camkit/peer an issue asks for (at most)
    repeats: int = 7
    warmup: int = 2


@dataclass(frozen=True)
class Row:
    case: Case
    camkit_s: float
    peer_s: float
    paired_ratio: float | None = None

    @property
    def ratio(self) -> float:
        """The median of the per-repeat ratios (each camkit call timed right beside a peer
        call), or the ratio of the medians where no pairs were taken."""
        return self.paired_ratio if self.paired_ratio is not None else self.camkit_s / self.peer_s

    @property
    def verdict(self) -> str:
        if self.case.target is None:
            return ""
        return "met" if self.ratio <= self.case.target else "MISSED"


def median_time(fn: Callable[[], object], repeats: int, warmup: int = 2) -> float:
    """Median wall time in seconds of ``repeats`` calls, after ``warmup`` untimed calls
    (which also pay for numba compilation or cache loading)."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def run_case(case: Case) -> Row:
    """Warm both up, then alternate: camkit, peer, camkit, peer... so a slow spell on the
    shared machine hits both sides of a pair; the ratio is the median of the pairs' ratios."""
    for _ in range(case.warmup):
        case.camkit()
        case.peer()
    ck, peer = [], []
    for _ in range(case.repeats):
        t0 = time.perf_counter()
        case.camkit()
        t1 = time.perf_counter()
        case.peer()
        t2 = time.perf_counter()
        ck.append(t1 - t0)
        peer.append(t2 - t1)
    ratios = [a / b for a, b in zip(ck, peer, strict=True)]
    return Row(case, statistics.median(ck), statistics.median(peer), statistics.median(ratios))


def _fmt_time(s: float) -> str:
    if s >= 1:
        return f"{s:.2f} s"
    if s >= 1e-3:
        return f"{s * 1e3:.2f} ms"
    return f"{s * 1e6:.1f} us"


def markdown_table(rows: list[Row]) -> str:
    head = ("| operation | size | camkit median | peer | peer median | ratio camkit/peer | target | |\n"
            "|---|---|---|---|---|---|---|---|\n")
    lines = []
    for r in rows:
        target = f"<= {r.case.target:g}" if r.case.target is not None else ""
        lines.append(
            f"| {r.case.operation} | {r.case.size} | {_fmt_time(r.camkit_s)} | {r.case.peer_name} | "
            f"{_fmt_time(r.peer_s)} | {r.ratio:.3f} | {target} | {r.verdict} |"
        )
    return head + "\n".join(lines) + "\n"
