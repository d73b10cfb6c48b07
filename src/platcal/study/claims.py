"""The claims ledger: every paper claim as data, evaluated on the study's own results.

A rig declares its papers' claims in ``data/claims.yaml`` of its subpackage (one entry per claim:
``id``, ``source``, ``statement``, ``paper``, ``unit``, ``measure`` and its ``args``,
``statistic``, ``criterion``) and gives the measures, named functions that read the study's
result files and return the per-replicate values a claim is judged on (:class:`Evidence`). This
module, which names no rig, computes the statistic, its bootstrap confidence interval over the
replicates and the verdict:

- ``reproduced``: the whole interval lies inside the criterion's admissible set;
- ``not reproduced``: the whole interval lies outside it;
- ``inconclusive``: the interval straddles the criterion's edge, or the study did not run the
  cells the claim needs (the measure returns None).

The verdict words are written here and nowhere else: a rig's report shows the evaluated rows.
A deterministic quantity (a rank, a covariance-only sigma) is one sample: its interval is the
value itself.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import InputError
from ..io import read_yaml
from ..seeding import seed_sequence
from .tables import frame_markdown

REPRODUCED, NOT_REPRODUCED, INCONCLUSIVE = "reproduced", "not reproduced", "inconclusive"
VERDICTS = (REPRODUCED, NOT_REPRODUCED, INCONCLUSIVE)
LEDGER_COLUMNS = ["rig", "claim", "source", "statement", "paper", "measured", "ci_low", "ci_high", "unit",
                  "criterion", "verdict", "settings"]
LEDGER_PEOPLE_COLUMNS = ["rig", "claim", "verdict", "measured", "95 % interval", "paper", "criterion", "statement",
                         "source", "settings"]
OPS = ("<=", ">=", "between", "==")


@dataclass(frozen=True)
class Criterion:
    """What a reproduced claim's statistic must satisfy: ``op`` one of ``<=``, ``>=``,
    ``between`` (``value`` = [low, high], inclusive) or ``==``; as an admissible interval."""

    op: str
    value: float | tuple[float, float]

    @property
    def interval(self) -> tuple[float, float]:
        if self.op == "<=":
            return -math.inf, float(self.value)
        if self.op == ">=":
            return float(self.value), math.inf
        if self.op == "==":
            return float(self.value), float(self.value)
        lo, hi = self.value
        return float(lo), float(hi)

    def text(self) -> str:
        if self.op == "between":
            return f"in [{self.value[0]:g}, {self.value[1]:g}]"
        return f"{self.op} {float(self.value):g}"


@dataclass(frozen=True)
class Claim:
    """One claim of a paper (or of a spec's "what an implementation must show"), as declared."""

    rig: str
    id: str
    source: str
    statement: str
    paper: str
    unit: str
    measure: str
    statistic: str
    criterion: Criterion
    args: Mapping[str, object] = field(default_factory=dict)


@dataclass(frozen=True)
class Evidence:
    """What a measure found: ``samples`` (one value per replicate, or one value for a
    deterministic quantity) and ``settings``, a short text saying which cells, noise level,
    scheme, estimator and how many replicates they come from."""

    samples: np.ndarray
    settings: str


Measure = Callable[..., "Evidence | None"]


def _rms(x, axis=-1):
    return np.sqrt(np.mean(np.square(x), axis=axis))


STATISTICS: dict[str, Callable] = {
    "mean": lambda x, axis=-1: np.mean(x, axis=axis),
    "median": lambda x, axis=-1: np.median(x, axis=axis),
    "max": lambda x, axis=-1: np.max(x, axis=axis),
    "min": lambda x, axis=-1: np.min(x, axis=axis),
    "rms": _rms,
    "share_pct": lambda x, axis=-1: 100.0 * np.mean(x, axis=axis),  # samples are 0/1
    "value": lambda x, axis=-1: np.take(x, 0, axis=axis),  # a deterministic quantity: one sample
}
"""Statistics of the replicates' values a claim can be judged on (vectorised over resamples)."""


def bootstrap_interval(samples: np.ndarray, statistic: str, seed: np.random.SeedSequence,
                       resamples: int = 2000, level: float = 0.95) -> tuple[float, float, float]:
    """The statistic of ``samples`` and its percentile-bootstrap interval at ``level``.

    One sample, or a ``value`` statistic, gives the value itself as both ends (a deterministic
    quantity has no replicate spread to resample)."""
    x = np.asarray(samples, float).ravel()
    stat = STATISTICS[statistic]
    value = float(stat(x))
    if x.size < 2 or statistic == "value" or not np.all(np.isfinite(x)):
        return value, value, value
    rng = np.random.default_rng(seed)
    boot = stat(x[rng.integers(0, x.size, size=(resamples, x.size))], axis=1)
    lo, hi = np.quantile(boot, [(1 - level) / 2, (1 + level) / 2])
    return value, float(lo), float(hi)


def verdict(criterion: Criterion, low: float, high: float) -> str:
    """``reproduced`` when [low, high] lies inside the admissible interval, ``not reproduced``
    when it lies wholly outside, ``inconclusive`` when it straddles an edge or is not finite."""
    if not (np.isfinite(low) and np.isfinite(high)):
        return INCONCLUSIVE
    a, b = criterion.interval
    if a <= low and high <= b:
        return REPRODUCED
    if high < a or low > b:
        return NOT_REPRODUCED
    return INCONCLUSIVE


def _criterion(raw, where: str) -> Criterion:
    if not isinstance(raw, dict) or raw.get("op") not in OPS or "value" not in raw:
        raise InputError(f"{where}.criterion", f"must be {{op: one of {list(OPS)}, value: number "
                         "(or [low, high] for between)}}")
    v = raw["value"]
    if raw["op"] == "between":
        if not (isinstance(v, list) and len(v) == 2 and all(isinstance(u, (int, float)) for u in v) and v[0] <= v[1]):
            raise InputError(f"{where}.criterion.value", "between takes [low, high] with low <= high")
        return Criterion("between", (float(v[0]), float(v[1])))
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        raise InputError(f"{where}.criterion.value", "must be a number")
    return Criterion(raw["op"], float(v))


def load_claims(rig: str, text: str) -> list[Claim]:
    """The claims a rig declares (the YAML text of its ``data/claims.yaml``: ``claims:`` a list
    of mappings); InputError naming the entry and field otherwise. Ids are unique snake_case."""
    raw = read_yaml(text)
    entries = raw.get("claims") if isinstance(raw, dict) else None
    if not isinstance(entries, list):
        raise InputError("claims", "must be a list of claims")
    out, seen = [], set()
    need = ("id", "source", "statement", "paper", "measure", "statistic", "criterion")
    for i, e in enumerate(entries):
        where = f"claims[{i}]"
        if not isinstance(e, dict) or any(k not in e for k in need):
            raise InputError(where, f"each claim needs {list(need)}")
        cid = str(e["id"])
        if not cid.replace("_", "").isalnum() or cid.lower() != cid or cid in seen:
            raise InputError(f"{where}.id", f"{cid!r} must be a unique snake_case name")
        if e["statistic"] not in STATISTICS:
            raise InputError(f"{where}.statistic", f"unknown {e['statistic']!r}; use one of {list(STATISTICS)}")
        seen.add(cid)
        out.append(Claim(rig=rig, id=cid, source=str(e["source"]), statement=str(e["statement"]).strip(),
                         paper=str(e["paper"]), unit=str(e.get("unit", "")), measure=str(e["measure"]),
                         statistic=str(e["statistic"]), criterion=_criterion(e["criterion"], where),
                         args=dict(e.get("args") or {})))
    return out


def evaluate(claims: list[Claim], measures: Mapping[str, Measure], results: Path, cfg: dict,
             seed: int) -> pd.DataFrame:
    """The ledger rows of ``claims``: each claim's measure run on ``results`` (the rig's results
    folder) and ``cfg`` (its checked config), the statistic with its bootstrap interval (seeded
    from ``seed`` and the claim's id) and the verdict. Columns :data:`LEDGER_COLUMNS`."""
    rows = []
    for c in claims:
        if c.measure not in measures:
            raise InputError(f"claims.{c.id}.measure", f"unknown measure {c.measure!r}; the rig has {sorted(measures)}")
        ev = measures[c.measure](results, cfg, **c.args)
        if ev is None or np.asarray(ev.samples).size == 0:
            value = lo = hi = math.nan
            settings = ev.settings if ev is not None else "not run in this study"
        else:
            value, lo, hi = bootstrap_interval(ev.samples, c.statistic, seed_sequence(seed, c.rig, c.id))
            settings = ev.settings
        rows.append({"rig": c.rig, "claim": c.id, "source": c.source, "statement": c.statement,
                     "paper": c.paper, "measured": value, "ci_low": lo, "ci_high": hi, "unit": c.unit,
                     "criterion": f"{c.statistic} {c.criterion.text()}",
                     "verdict": verdict(c.criterion, lo, hi), "settings": settings})
    return pd.DataFrame(rows, columns=LEDGER_COLUMNS)


def ledger_for_people(df: pd.DataFrame) -> pd.DataFrame:
    """The ledger rows as people read them (Markdown, HTML): the verdict beside the claim, the
    measured value with its unit and 95 % interval to 3 significant digits, then the paper's value,
    the criterion, the statement, the source and the settings (the CSV keeps full precision)."""
    def num(v, unit=""):
        return "-" if not np.isfinite(v) else f"{v:.3g} {unit}".strip()

    return pd.DataFrame({
        "rig": df["rig"], "claim": df["claim"], "verdict": df["verdict"],
        "measured": [num(v, u) for v, u in zip(df["measured"], df["unit"])],
        "95 % interval": ["-" if not np.isfinite(lo) else f"[{lo:.3g}, {hi:.3g}]"
                          for lo, hi in zip(df["ci_low"], df["ci_high"])],
        "paper": df["paper"], "criterion": df["criterion"], "statement": df["statement"],
        "source": df["source"], "settings": df["settings"]}, columns=LEDGER_PEOPLE_COLUMNS)


def ledger_markdown(df: pd.DataFrame) -> str:
    """The ledger rows of one rig as a Markdown table for people (:func:`ledger_for_people`, the
    verdict in bold, no rig column)."""
    shown = ledger_for_people(df).drop(columns=["rig"])
    shown["verdict"] = [f"**{v}**" for v in shown["verdict"]]
    return frame_markdown(shown.astype(str).apply(lambda c: c.str.replace("|", "/", regex=False)))


def verdict_counts(df: pd.DataFrame) -> str:
    """'n reproduced, m not reproduced, k inconclusive' of a ledger."""
    counts = df["verdict"].value_counts()
    return ", ".join(f"{int(counts.get(v, 0))} {v}" for v in VERDICTS)


def evaluate_rig(rig, results: Path, cfg: dict) -> pd.DataFrame:
    """The ledger rows of a rig's declared claims (``rig.extra("claims")``: a module-like object
    with ``claims()`` and ``MEASURES``) on its results folder and config; no rows when it has none."""
    spec = rig.extra("claims")
    if spec is None:
        return pd.DataFrame(columns=LEDGER_COLUMNS)
    return evaluate(spec.claims(), spec.MEASURES, Path(results), cfg, seed=int(cfg.get("seed", 0) or 0))


def ledger_note(df: pd.DataFrame) -> str:
    """One paragraph on how the verdicts were reached, with the counts (per rig when there are
    several)."""
    rigs = list(dict.fromkeys(df["rig"]))
    per_rig = "" if len(rigs) < 2 else " (" + "; ".join(f"{r}: {verdict_counts(df[df['rig'] == r])}"
                                                        for r in rigs) + ")"
    return (f"{len(df)} claims: {verdict_counts(df)}{per_rig}. Measured: the statistic over the study's replicates, with its "
            "95 % percentile-bootstrap interval; reproduced when the whole interval meets the criterion, not reproduced "
            "when none of it does, inconclusive when it straddles the criterion or the study did not run the cells.")


def ledger_section(df: pd.DataFrame, heading: str = "## Claims") -> str:
    """The opening section of a rig's report.md: the verdict counts and the ledger rows (the
    paper's value, the measured statistic with its 95 % bootstrap interval over the replicates,
    the criterion, the verdict and the cells it comes from), as the rig's ``claims.csv`` holds them."""
    if df.empty:
        return f"{heading}\n\nThis rig declares no claims.\n"
    return f"{heading}\n\n{ledger_note(df)}\n\n{ledger_markdown(df)}"


def read_ledger(path) -> pd.DataFrame:
    """A ledger written by the ``claims`` rule (``results/<rig>/claims.csv``), columns :data:`LEDGER_COLUMNS`."""
    df = pd.read_csv(path)[LEDGER_COLUMNS]
    text = [c for c in LEDGER_COLUMNS if c not in ("measured", "ci_low", "ci_high")]
    return df.astype({c: object for c in text}).fillna({c: "" for c in text})
