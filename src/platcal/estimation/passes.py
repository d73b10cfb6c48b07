"""Estimators whose runs another's run gives on the way (issue 22 item 4).

A multi-pass filter's pass p reads nothing of the passes after it, so the estimate after p
passes of a P-pass run is, bit for bit, the estimate of the same filter run with p passes on the
same records. An estimator of a cell or a comparison level that differs from another only by
fewer passes is then tabled from that run instead of filtering the records again. The rig says
which of its estimators qualify (its kind hands snapshots of its passes, and every other setting
is equal); this module pairs them and collects the snapshots with their clocks. Nothing here
names a rig.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Hashable, Mapping
from typing import Any


def pass_prefixes(passes: Mapping[str, int], same: Callable[[str, str], bool]) -> dict[str, tuple[str, int]]:
    """Which estimators' runs another's gives on the way: name -> (the estimator of ``passes``
    (name -> its number of passes) with more passes for which ``same(name, other)`` holds, the
    name's passes); ``same`` is the rig's word that ``name``'s kind hands snapshots of its passes
    and that the two differ in nothing but passes. Of several, the one with the most passes, the
    first listed on a tie. Names that run themselves are not keys."""
    out = {}
    for name, p in passes.items():
        longer = [m for m, q in passes.items() if q > p and same(name, m)]
        if longer:
            out[name] = (max(longer, key=lambda m: passes[m]), p)   # max keeps the first of a tie
    return out


def takers(prefixes: Mapping[str, tuple[str, int]]) -> dict[str, dict[str, int]]:
    """:func:`pass_prefixes` inverted: the estimator that runs -> {name: passes} of those its run
    gives on the way (the ``takers`` of :func:`run_with_takers`)."""
    out: dict[str, dict[str, int]] = {}
    for name, (run, passes) in prefixes.items():
        out.setdefault(run, {})[name] = passes
    return out


def run_with_takers(run: Callable[..., Any], takers: Mapping[Hashable, int],
                    clock: Callable[[], Any] = time.perf_counter) -> tuple[Any, Any, dict]:
    """``run(on_pass=...)``, a filter run that calls ``on_pass(p, estimate)`` after each of its
    passes but the last with the estimate a run of p passes returns, and on the way the estimates
    that ``takers`` (key -> passes) ask for (``run()`` when none does). Returns (the run's
    result, its clock from start to end, key -> (the estimate after that key's passes, the clock
    from the start to the end of those passes)). ``clock``: seconds now (a number or an array
    such as (wall, CPU)); a taken estimator's cost is the run's clock at the end of its passes."""
    start = clock()
    taken = {}

    def on_pass(p: int, estimate) -> None:
        for key, passes in takers.items():
            if passes == p:
                taken[key] = (estimate, clock() - start)

    result = run(on_pass=on_pass) if takers else run()
    return result, clock() - start, taken
