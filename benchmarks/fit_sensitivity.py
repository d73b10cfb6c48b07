"""What the fit check catches (issue 25): the smallest unit, sign and clock error of a record that
``platcal identify`` refuses (exit 2), cannot identify (exit 1) or finds not to fit (exit 3), per rig.

Each rig's default test (``platcal simulate --seed N``, seeds 0..N-1; the rig and config of
``fit_false_alarm.py``) is corrupted, record by record, and identified in-process through
``platcal.cli.main`` (the command's own path: the record checks, the plausibility refusal, the
filter and the fit check; the exit status is the command's, an InputError mapped to 2):

- scale: one data column times (1 + e), e on a log grid 1e-7 .. 1;
- unit: one data column written in another unit of the same kind (m/s^2 for g, rad for deg,
  deg/s for rad/s, km for m, ...; the factor from ``platcal.mapping.conversion_factor``), and
  ``t`` in ms; whether the message names the column and the scale (9.80665, 57.2958, 1000, 3600);
- sign: one data column times -1;
- clock jitter: ``t`` plus a uniform draw in [-a, a], a on a log grid 10 ns .. 1 ms (the same
  draw, scaled, at every a; SeedSequence(config seed, "fit_sensitivity jitter", seed N));
- clock rate: ``t`` times (1 + e), e on a log grid 1e-10 .. 0.1.

A size is *caught* when the identification exits non-zero on at least ``--need`` of the seeds
(default 4 of 5). A size *shifts* the identification when, on at least as many seeds, some
estimate moves from the clean record's by more than its clean sigma, or the record is refused
(a size beyond a refusal counts as shifted, so the figure grows with the size). Both smallest
sizes are found by bisection on the grid (the figures grow with the size); the *dangerous
zone* runs from the smallest shifting size to the smallest caught one: the identification
passes (exit 0) and is wrong by more than 1 sigma. ``passed_shift_max`` is the largest shift,
in clean sigmas, of any seed that passed at any size evaluated.

    python benchmarks/fit_sensitivity.py [--rig R ...] [--only FAMILY ...] [--seeds 5] [--out benchmarks/fit_sensitivity]

writes ``<out>.csv``/``.md``/``.html`` (one row per rig, corruption and column) and
``<out>_points.csv``/... (one row per size evaluated) through ``platcal.study.tables``; with
``--only`` (scale, unit, sign, jitter, rate) the rows of those families replace theirs in the
tables already there.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from platcal.cli import main as platcal
from platcal.estimation.fit import UNIT_SCALES
from platcal.io import read_config
from platcal.mapping import STANDARD_GRAVITY, conversion_factor
from platcal.rig import get_rig
from platcal.rigs.centrifuge.record import UNITS as CENTRIFUGE_UNITS
from platcal.rigs.lowprec_centrifuge.record import UNITS as LOWPREC_UNITS
from platcal.rigs.multiposition.record import UNITS as MULTIPOSITION_UNITS
from platcal.rigs.sled.record import UNITS as SLED_UNITS
from platcal.seeding import seed_sequence
from platcal.study.tables import write_table

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from fit_false_alarm import RIGS  # noqa: E402  (each rig's default config, the false-alarm benchmark's)

SCALE_GRID = np.logspace(-7, 0, 22)
"""Relative scale errors e (column times 1 + e): 3 per decade."""
JITTER_GRID = np.logspace(-8, -3, 16)
"""Uniform timestamp jitter amplitudes a, s (t + U(-a, a)): 3 per decade, below half of every
rig's sample period (5 ms and more), so the stamps stay in order."""
RATE_GRID = np.logspace(-10, -1, 28)
"""Clock-rate errors e (t times 1 + e): 3 per decade."""

WRONG_UNITS = {"g": ("m/s^2", "mg"), "m/s^2": ("g", "mg"), "deg": ("rad",), "rad/s": ("deg/s", "rad/h"),
               "m/s": ("km/h", "mm/s"), "m": ("km", "mm"), "s": ("ms",)}
"""The units a column in the rig's unit (key) is plausibly written in by mistake."""


@dataclass(frozen=True)
class RigCase:
    """One rig's default test: config, the extra options of simulate and identify, and the data
    columns that are corrupted with their units (the rig's record UNITS)."""

    config: str
    simulate: tuple[str, ...]
    identify: tuple[str, ...]
    columns: tuple[str, ...]
    units: dict
    summary: str = "summary.json"


def rig_cases() -> dict[str, RigCase]:
    """The four rigs' default tests (the centrifuge's table1 scheme, as ``fit_false_alarm.py``;
    the multiposition rig's first scheme, named to identify as the README does, so that the
    record's dwells are checked against it; the low-precision centrifuge's first platform and run)."""
    mp_cfg = RIGS["multiposition"][1]
    mp_scheme = ("--scheme", get_rig("multiposition").load_config(read_config(mp_cfg)).scheme(None).name)
    lp_cfg = RIGS["lowprec_centrifuge"][1]
    lp = get_rig("lowprec_centrifuge").load_config(read_config(lp_cfg))
    platform = lp.platform_names()[0]
    return {
        "centrifuge": RigCase(RIGS["centrifuge"][1], ("--scheme", "table1"), ("--scheme", "table1"),
                              ("Ax", "Ay", "Az"), CENTRIFUGE_UNITS),
        "multiposition": RigCase(mp_cfg, mp_scheme, mp_scheme, ("Ax", "Ay", "Az", "alpha_m", "beta_m", "gamma_m"),
                                 MULTIPOSITION_UNITS),
        "sled": RigCase(RIGS["sled"][1], (), (), ("fx", "fy", "fz", "wx", "wy", "wz"), SLED_UNITS, "metrics.json"),
        "lowprec_centrifuge": RigCase(lp_cfg, ("--platform", platform, "--run", lp.run_names(platform)[0]), (),
                                      ("VE", "VN", "pE", "pN", "heading_deg", "fE", "fN"), LOWPREC_UNITS),
    }


@dataclass(frozen=True)
class Outcome:
    """One identification: exit status (-1: a traceback), stderr, the largest estimate shift in
    clean sigmas (NaN: nothing written)."""

    status: int
    message: str
    shift: float
    most: str = ""


class Runner:
    """Identifies corrupted copies of a rig's clean records in-process and keeps the outcomes."""

    def __init__(self, rig: str, case: RigCase, seeds: int, work: Path):
        self.rig, self.case, self.work = rig, case, work
        self.seed_root = int(read_config(case.config)["seed"])
        self.frames, self.clean = [], []
        self.calls, self.cpu = 0, 0.0
        for n in range(seeds):
            rec = work / f"clean_{n}.parquet"
            code = self._quiet(["simulate", "--config", case.config, *case.simulate, "--seed", str(n),
                                "--out", str(rec)])
            if code[0] != 0:
                raise SystemExit(f"{rig}: platcal simulate seed {n} exited {code[0]}: {code[1]}")
            self.frames.append(pd.read_parquet(rec))
            out = self.identify(self.frames[-1], n)
            if out[0] != 0:
                raise SystemExit(f"{rig}: the clean record of seed {n} exits {out[0]}: {out[1]}")
            self.clean.append(out[2])

    @staticmethod
    def _quiet(argv) -> tuple[int, str]:
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                code = platcal(argv)
            except Exception as exc:  # a traceback is a finding of its own: recorded, not raised
                return -1, f"traceback: {exc.__class__.__name__}: {exc}"
        return code, err.getvalue()

    def identify(self, df: pd.DataFrame, n: int) -> tuple[int, str, pd.DataFrame | None]:
        """``platcal identify --no-truth`` of a record frame; the estimates when written."""
        data, out = self.work / f"rec_{n}.parquet", self.work / f"id_{n}"
        df.to_parquet(data)
        t0 = time.process_time()
        code, msg = self._quiet(["identify", "--config", self.case.config, *self.case.identify, "--data", str(data),
                                 "--out", str(out), "--no-truth"])
        self.cpu += time.process_time() - t0
        self.calls += 1
        est = pd.read_csv(out / "estimates.csv") if code in (0, 3) else None
        return code, msg, est

    def outcome(self, corrupt, n: int) -> Outcome:
        """Seed ``n``'s record corrupted by ``corrupt(frame, n)`` (in place), identified."""
        df = self.frames[n].copy()
        corrupt(df, n)
        code, msg, est = self.identify(df, n)
        if est is None:
            return Outcome(code, msg.strip(), np.nan)
        return Outcome(code, msg.strip(), *shift_sigmas(self.clean[n], est))

    def jitter_draw(self, n: int) -> np.ndarray:
        """Seed ``n``'s uniform draw in [-1, 1] per row, scaled by the jitter amplitude."""
        rng = np.random.default_rng(seed_sequence(self.seed_root, "fit_sensitivity jitter", n))
        return rng.uniform(-1.0, 1.0, len(self.frames[n]))


def shift_sigmas(clean: pd.DataFrame, est: pd.DataFrame) -> tuple[float, str]:
    """The largest |estimate - clean estimate| / clean sigma over the estimates with a sigma
    (rows in the same order: the same rig and config; inf for a non-finite estimate) and the
    estimate it is of."""
    sig = clean["sigma"].to_numpy(float)
    ok = np.flatnonzero(np.isfinite(sig) & (sig > 0))
    d = np.abs(est["estimate"].to_numpy(float)[ok] - clean["estimate"].to_numpy(float)[ok]) / sig[ok]
    d = np.where(np.isfinite(d), d, np.inf)
    i = int(np.argmax(d))
    where = f" ({clean['filter'].iloc[ok[i]]})" if "filter" in clean else ""  # the sled: run and stop filter
    return float(d[i]), str(clean["name"].iloc[ok[i]]) + where


@dataclass
class Point:
    """The outcomes of one corruption at one size over the seeds."""

    outcomes: list

    @property
    def caught(self) -> int:
        return sum(o.status != 0 for o in self.outcomes)

    @property
    def shifted(self) -> int:
        """Seeds whose estimates moved by > 1 clean sigma, or that were refused (no estimate)."""
        return sum(not (o.shift <= 1.0) for o in self.outcomes)

    @property
    def passed_shift(self) -> float:
        """Largest shift of a seed that passed (exit 0); 0 when none passed."""
        return max([o.shift for o in self.outcomes if o.status == 0], default=0.0)

    def by(self) -> str:
        codes = [o.status for o in self.outcomes]
        return ", ".join(f"exit {c}: {codes.count(c)}" for c in sorted(set(codes)))

    def most_shifted(self) -> str:
        """The estimate that moved most (in clean sigmas) on the seeds with an estimate."""
        shown = [o for o in self.outcomes if np.isfinite(o.shift)]
        return max(shown, key=lambda o: o.shift).most if shown else "-"

    def first_message(self) -> str:
        """The stderr of the first seed caught, its error line first (exit 3 prints a summary line before it)."""
        text = next((o.message for o in self.outcomes if o.status != 0), "")
        return "\n".join(sorted(text.splitlines(), key=lambda line: "error:" not in line))


def smallest(grid, pred) -> int | None:
    """Index of the smallest grid size where ``pred`` holds, by bisection (``pred`` False below
    it and True from it on); None when it does not hold at the top."""
    if not pred(len(grid) - 1):
        return None
    if pred(0):
        return 0
    lo, hi = 0, len(grid) - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if pred(mid) else (mid, hi)
    return hi


def names(message: str, column: str, scale: float | None) -> str:
    """What a refusal's message names: the column, and (for a named scale of
    :data:`platcal.estimation.fit.UNIT_SCALES`, either way round) the scale."""
    said = [column] if column in message else []
    named = [f"{s:.6g}" for s, _ in UNIT_SCALES
             if scale is not None and min(abs(scale / s - 1), abs(scale * s - 1)) < 1e-3]
    if named and named[0] in message:
        said.append(f"scale {named[0]}")
    return " and ".join(said) or "no"


def sweep(r: Runner, kind: str, column: str, grid, corrupt, need: int, points: list) -> dict:
    """The smallest caught and smallest shifting size of one corruption family (bisection)."""
    cache: dict[int, Point] = {}

    def at(i: int) -> Point:
        if i not in cache:
            cache[i] = Point([r.outcome(lambda df, n: corrupt(df, n, grid[i]), n) for n in range(len(r.frames))])
            p = cache[i]
            points.append({"rig": r.rig, "corruption": kind, "column": column, "size": float(grid[i]),
                           "caught": p.caught, "shifted": p.shifted, "by": p.by(),
                           "passed_shift_max": p.passed_shift, "most_shifted": p.most_shifted(),
                           "message": p.first_message()[:160]})
        return cache[i]

    ic = smallest(grid, lambda i: at(i).caught >= need)
    iw = smallest(grid, lambda i: at(i).shifted >= need)
    caught = np.nan if ic is None else float(grid[ic])
    wrong = np.nan if iw is None else float(grid[iw])
    if iw is not None and (ic is None or iw < ic):
        zone = (f"{wrong:.2g} .. {caught:.2g}" if ic is not None
                else f">= {wrong:.2g} (never caught up to {grid[-1]:.2g})")
    else:
        zone = "none"
    top = at(ic) if ic is not None else None
    first_wrong = at(iw).most_shifted() if iw is not None else "-"
    return {"rig": r.rig, "corruption": kind, "column": column, "smallest_caught": caught,
            "caught": (f"{top.caught}/{len(r.frames)}" if top
                       else f"0-{max(p.caught for p in cache.values())}/{len(r.frames)}"),
            "by": top.by() if top else "-", "smallest_shift_1sigma": wrong, "most_shifted": first_wrong,
            "dangerous_zone": zone,
            "passed_shift_max": max(p.passed_shift for p in cache.values()),
            "message_names": names(top.first_message(), column, None) if top else "-",
            "sizes_evaluated": len(cache)}


def fixed(r: Runner, kind: str, column: str, corrupt, scale: float | None, points: list) -> dict:
    """One corruption of fixed size (a unit, a sign) over the seeds."""
    p = Point([r.outcome(corrupt, n) for n in range(len(r.frames))])
    points.append({"rig": r.rig, "corruption": kind, "column": column, "size": np.nan if scale is None else scale,
                   "caught": p.caught, "shifted": p.shifted, "by": p.by(), "passed_shift_max": p.passed_shift,
                   "most_shifted": p.most_shifted(), "message": p.first_message()[:160]})
    return {"rig": r.rig, "corruption": kind, "column": column, "smallest_caught": np.nan,
            "caught": f"{p.caught}/{len(r.frames)}", "by": p.by(), "smallest_shift_1sigma": np.nan,
            "most_shifted": p.most_shifted(), "dangerous_zone": "yes" if p.passed_shift > 1.0 else "none",
            "passed_shift_max": p.passed_shift,
            "message_names": names(p.first_message(), column, scale) if p.caught else "-", "sizes_evaluated": 1}


def scaled(column: str, factor: float):
    def corrupt(df, n):
        df[column] = df[column] * factor
    return corrupt


FAMILIES = ("scale", "unit", "sign", "jitter", "rate")
"""The corruption families (the module docstring's), for ``--only``."""


def rig_rows(r: Runner, need: int, points: list, families=FAMILIES) -> list[dict]:
    """The corruptions of one rig of ``families`` (the module docstring's; default all)."""
    rows = []
    case = r.case
    for c in case.columns if "scale" in families else ():
        rows.append(sweep(r, "scale x(1+e)", c, SCALE_GRID,
                          lambda df, n, e, c=c: df.__setitem__(c, df[c] * (1.0 + e)), need, points))
    for c in case.columns + ("t",) if "unit" in families else ():
        for wrong in WRONG_UNITS.get(case.units[c], ()):
            # a value v in the rig's unit reads v / conversion_factor(wrong -> rig's unit) in the wrong one
            factor = 1.0 / conversion_factor(wrong, case.units[c], STANDARD_GRAVITY, c)
            rows.append(fixed(r, f"unit: {wrong} for {case.units[c]}", c, scaled(c, factor), factor, points))
    for c in case.columns if "sign" in families else ():
        rows.append(fixed(r, "sign", c, scaled(c, -1.0), None, points))
    if "jitter" in families:
        rows.append(sweep(r, "clock jitter +-a (s)", "t", JITTER_GRID,
                          lambda df, n, a: df.__setitem__("t", df["t"] + a * r.jitter_draw(n)), need, points))
    if "rate" in families:
        rows.append(sweep(r, "clock rate x(1+e)", "t", RATE_GRID,
                          lambda df, n, e: df.__setitem__("t", df["t"] * (1.0 + e)), need, points))
    return rows


def merged(old_csv: Path, new: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """The table of ``old_csv`` with its rows of each key (``keys``' values) in ``new`` replaced by
    ``new``'s, where they stood (new keys appended): a re-run of some families updates the full table."""
    if not old_csv.exists():
        return new
    old = pd.read_csv(old_csv)
    new_keys = [tuple(k) for k in new[keys].to_numpy()]
    out, placed = [], set()
    for _, row in old.iterrows():
        key = tuple(row[keys])
        if key in new_keys:
            if key not in placed:
                out.append(new[[k == key for k in new_keys]])
                placed.add(key)
            continue
        out.append(row.to_frame().T)
    out += [new[[k == key for k in new_keys]] for key in dict.fromkeys(new_keys) if key not in placed]
    return pd.concat(out, ignore_index=True)[old.columns.union(new.columns, sort=False)].infer_objects()


def old_note(stem: Path) -> str:
    """The note of an earlier full run (the .md's third line), kept when some rows are re-run."""
    md = stem.with_suffix(".md")
    lines = md.read_text().splitlines() if md.exists() else []
    return lines[2] if len(lines) > 2 else ""


FORMATS = {"smallest_caught": ".2g", "smallest_shift_1sigma": ".2g", "passed_shift_max": ".3g", "size": ".4g"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cases = rig_cases()
    ap.add_argument("--rig", choices=sorted(cases), action="append", help="a rig (repeat; default: all four)")
    ap.add_argument("--seeds", type=int, default=5, help="seeds 0..N-1 of each rig's default test")
    ap.add_argument("--need", type=int, default=None, help="seeds that must exit non-zero (default: ceil(0.8 N))")
    ap.add_argument("--out", default=str(HERE / "fit_sensitivity"), help="table stem (.csv, .md, .html)")
    ap.add_argument("--only", choices=FAMILIES, action="append",
                    help="a corruption family (repeat; default: all): its rows replace those of the tables at --out, "
                         "the rest are kept")
    args = ap.parse_args()
    if args.seeds < 1:
        ap.error("--seeds: must be >= 1")
    need = args.need if args.need is not None else math.ceil(0.8 * args.seeds)
    rows, points, notes = [], [], []
    for rig in args.rig or list(cases):
        t0, c0 = time.perf_counter(), time.process_time()
        with tempfile.TemporaryDirectory(prefix=f"fit_sensitivity_{rig}_") as work:
            r = Runner(rig, cases[rig], args.seeds, Path(work))
            rows += rig_rows(r, need, points, tuple(args.only or FAMILIES))
        note = (f"{rig}: {r.calls} identifications, {r.cpu:.0f} s CPU in identify, {time.process_time() - c0:.0f} s "
                f"CPU and {time.perf_counter() - t0:.0f} s wall in all")
        notes.append(note)
        print(note, flush=True)
    note = (f"Seeds 0..{args.seeds - 1} of each rig's default test; caught: exit != 0 on >= {need} of "
            f"{args.seeds} seeds; shift: max |estimate - clean| / clean sigma > 1 (or refused) on as many; "
            "most_shifted: the estimate that moved most there ('-': every seed refused, so the shift itself "
            "was not measured); dangerous zone: from the smallest shift to the smallest caught size; "
            "passed_shift_max: the largest shift of a seed that exited 0 at any size evaluated. ")
    run = "Command: python benchmarks/fit_sensitivity.py " + " ".join(sys.argv[1:]) + ". " + "; ".join(notes) + "."
    note += run
    table, every = pd.DataFrame(rows), pd.DataFrame(points)
    if args.only:  # some rows re-measured: the others (and the note of their run) are kept
        stem = Path(args.out)
        note = f"{old_note(stem)} Re-measured rows ({', '.join(args.only)}; {', '.join(args.rig or cases)}): {run}"
        table = merged(stem.with_suffix(".csv"), table, ["rig", "corruption", "column"])
        every = merged(Path(f"{args.out}_points.csv"), every, ["rig", "corruption", "column"])
    write_table(table, args.out, "What the fit check catches (issue 25)", note, FORMATS)
    write_table(every, f"{args.out}_points", "What the fit check catches: every size evaluated", note, FORMATS)
    print(pd.DataFrame(rows).drop(columns=["message_names"]).to_string(index=False))


if __name__ == "__main__":
    main()
