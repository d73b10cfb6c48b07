"""Plan a calibration campaign across rigs: the least rig cost that meets every target (issue 23).

A campaign file (schema ``study/data/campaign.schema.yaml``) names the platform (the shared
:class:`~platcal.model.platform.PlatformModel`, truth overrides, prior sigmas), the target sigma
of every coefficient, the rigs available (config, costs, schemes, dwells, repeats) and the
papers' own plans to compare with. A *test* is one (rig, scheme, dwell) run; a *plan* is how
many times each candidate test is run.

Information across rigs. Each rig's campaign hook (:class:`platcal.rig.CampaignHooks`) gives
the Fisher information of one test about its states. Tests of one rig add their information on
the rig's states; the rig's nuisance states (not named in the platform model) are marginalised
once per rig with their prior (Schur complement,
:func:`platcal.estimation.information.marginal_information`), since a nuisance such as a mount
misalignment is the same in every test on that rig. The rigs' marginal informations then add
on the platform's names, with the platform prior::

    I = P0^-1 + sum_rigs S_r(sum_{tests j on r} n_j F_j),      sigma = sqrt(diag(I^-1))

so the posterior of one test is the prior of the next and the order does not change the end.

Search. The counts ``n_j`` in ``0..max_repeats`` are the integer variables of a two-objective
NSGA-II (pymoo, rounded SBX/PM): cost (tests' hours x rate, plus each used rig's set-up once)
and the worst coefficient's sigma/target. Every evaluated plan is kept; the Pareto front is
their non-dominated set and the chosen plan the cheapest with sigma/target <= 1 everywhere.
The same search restricted to one rig gives the cheapest single-rig plans.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from pymoo.algorithms.moo.nsga2 import NSGA2
from pymoo.core.problem import Problem
from pymoo.operators.crossover.sbx import SBX
from pymoo.operators.mutation.pm import PM
from pymoo.operators.repair.rounding import RoundingRepair
from pymoo.optimize import minimize
from scipy import stats

from ..errors import InputError
from ..estimation.information import marginal_information
from ..estimation.lanes import LANES
from ..io import atomic_to_csv, atomic_write_text, check_writable
from ..sizes import DEFAULT_MAX_HOURS, DEFAULT_MAX_MEMORY_GB, Size, check_sizes
from .campaign_file import Campaign, RigOffer, load_campaign
from .montecarlo import chunks, replicate_seed
from .plots import save, styled
from .tables import frame_markdown, write_table

import matplotlib.pyplot as plt  # noqa: E402  (after .plots, which selects the Agg backend)

# ------------------------------------------------------------------ candidate tests and their information

@dataclass(frozen=True)
class Test:
    """One candidate test: ``hours`` of rig time (mounting, positions, data; no set-up) and its
    ``cost`` (hours x the rig's rate)."""

    rig: str
    scheme: str
    dwell_s: float
    positions: int
    hours: float
    cost: float


@dataclass(frozen=True)
class RigInformation:
    """The candidate tests of one rig: their Fisher information ``info`` (m_r, n_r, n_r) on the
    rig's states ``names``, normalised by ``scale`` (the platform prior sigma of a platform
    coefficient, the rig's prior sigma of a nuisance state); ``keep`` marks the platform's
    coefficients and ``index`` their positions in the platform model."""

    rig: str
    columns: np.ndarray
    names: tuple[str, ...]
    info: np.ndarray
    scale: np.ndarray
    keep: np.ndarray
    index: np.ndarray
    rig_prior: np.ndarray
    """(n_r,) the rig's own prior sigma of its states (its nuisance states start from it)."""


@dataclass(frozen=True)
class Candidates:
    """Every candidate test of a campaign and the information of each rig's."""

    tests: tuple[Test, ...]
    rigs: tuple[RigInformation, ...]
    setup_cost: np.ndarray
    """(n_rigs,) set-up hours x rate of each rig, paid once by a plan that uses it."""
    max_repeats: np.ndarray
    n_coef: int

    def index(self, rig: str, scheme: str, dwell_s: float) -> int:
        for j, t in enumerate(self.tests):
            if (t.rig, t.scheme) == (rig, scheme) and abs(t.dwell_s - dwell_s) < 1e-9:
                return j
        raise KeyError((rig, scheme, dwell_s))


def test_of(offer: RigOffer, scheme: str, dwell_s: float) -> Test:
    """The rig time and cost of one test (hours: per test + per position + the data)."""
    k = offer.rig.campaign.positions(offer.cfg, scheme)
    hours = offer.hours_per_test + k * offer.hours_per_position + k * dwell_s / 3600.0
    return Test(offer.name, scheme, float(dwell_s), k, hours, hours * offer.cost_per_hour)


def candidates(campaign: Campaign, extra=()) -> Candidates:
    """The campaign's candidate tests (each rig's schemes x dwells, plus ``extra`` (rig, scheme,
    dwell) of the reference plans) and each one's information from its rig's hook."""
    truth = campaign.truth()
    pl = campaign.platform
    tests, blocks = [], []
    for offer in campaign.rigs:
        wanted = [(s, d) for s in offer.schemes for d in offer.dwells]
        wanted += [(s, float(d)) for r, s, d in extra if r == offer.name and (s, float(d)) not in wanted]
        start = len(tests)
        infos = []
        for s, d in wanted:
            tests.append(test_of(offer, s, d))
            infos.append(offer.rig.campaign.information(offer.cfg, s, d, truth))
        names = infos[0].names
        keep = np.array([n in pl.names for n in names])
        if not keep.any():
            raise InputError(f"rigs.{offer.name}", "none of the rig's states is a coefficient of the platform")
        index = np.array([pl.index(n) for n in names if n in pl.names])
        scale = np.asarray(infos[0].prior_sigma, float).copy()
        scale[keep] = campaign.prior_sigma[index]
        F = np.stack([ti.information for ti in infos]) * np.outer(scale, scale)
        blocks.append(RigInformation(offer.name, np.arange(start, len(tests)), names, F, scale, keep, index,
                                     np.asarray(infos[0].prior_sigma, float)))
    setup = np.array([o.setup_hours * o.cost_per_hour for o in campaign.rigs])
    reps = np.concatenate([np.full(len(b.columns), o.max_repeats) for b, o in zip(blocks, campaign.rigs)])
    return Candidates(tuple(tests), tuple(blocks), setup, reps, len(pl.names))


def posterior_information(cands: Candidates, counts: np.ndarray) -> np.ndarray:
    """Normalised information (B, n, n) about the platform's coefficients (coefficient / prior
    sigma) after plans ``counts`` (B, m): the prior (identity) plus each rig's marginal
    information (module docstring)."""
    counts = np.atleast_2d(np.asarray(counts, float))
    out = np.broadcast_to(np.eye(cands.n_coef), (counts.shape[0], cands.n_coef, cands.n_coef)).copy()
    for b in cands.rigs:
        c = counts[:, b.columns]
        if not c.any():
            # no plan of the batch uses the rig (every plan of a single-rig search, for the other
            # rigs): its marginal information is exactly +-0, and adding it changes no value
            continue
        F = np.einsum("bj,jkl->bkl", c, b.info)
        out[:, b.index[:, None], b.index[None, :]] += marginal_information(F, b.keep, np.ones(len(b.names)))
    return out


def planned_sigma(campaign: Campaign, cands: Candidates, counts: np.ndarray) -> np.ndarray:
    """Posterior 1-sigma (B, n) of every coefficient after plans ``counts`` (B, m), its unit."""
    info = posterior_information(cands, counts)
    var = np.diagonal(np.linalg.inv(info), axis1=-2, axis2=-1)
    return np.sqrt(var) * campaign.prior_sigma


def plan_cost(cands: Candidates, counts: np.ndarray) -> np.ndarray:
    """Cost (B,) of plans ``counts`` (B, m): the tests' costs and each used rig's set-up once."""
    counts = np.atleast_2d(np.asarray(counts, float))
    cost = counts @ np.array([t.cost for t in cands.tests])
    for r, b in enumerate(cands.rigs):
        cost = cost + (counts[:, b.columns].sum(axis=1) > 0) * cands.setup_cost[r]
    return cost


def worst_ratio(campaign: Campaign, sigma: np.ndarray) -> np.ndarray:
    """The largest sigma / target over the coefficients (B,)."""
    return (np.atleast_2d(sigma) / campaign.target_sigma).max(axis=1)


# ------------------------------------------------------------------ search

class _PlanProblem(Problem):
    """Integer counts of the candidate tests ``cols``; objectives cost and worst sigma/target;
    every evaluated plan archived with its sigma/target per coefficient (the Pareto front is
    taken over all of them, without computing their sigmas again)."""

    def __init__(self, campaign: Campaign, cands: Candidates, cols: np.ndarray):
        upper = cands.max_repeats[cols].astype(float)
        super().__init__(n_var=cols.size, n_obj=2, xl=np.zeros(cols.size), xu=upper, vtype=int)
        self.campaign, self.cands, self.cols = campaign, cands, cols
        self.archive: list[np.ndarray] = []
        self.ratios: list[np.ndarray] = []

    def full(self, x) -> np.ndarray:
        counts = np.zeros((len(x), len(self.cands.tests)), int)
        counts[:, self.cols] = np.clip(np.rint(x), 0, self.xu).astype(int)
        return counts

    def _evaluate(self, x, out, *args, **kwargs):
        counts = self.full(x)
        ratio = planned_sigma(self.campaign, self.cands, counts) / self.campaign.target_sigma
        self.archive.append(counts)
        self.ratios.append(ratio)
        out["F"] = np.column_stack([plan_cost(self.cands, counts), ratio.max(axis=1)])


def initial_plans(upper: np.ndarray, size: int, rng: np.random.Generator) -> np.ndarray:
    """A start population: each allowed test alone (once and at its most repeats), then random
    counts up to ``size`` rows (at least ``size``)."""
    m = upper.size
    rows = [np.zeros(m, int)]
    for j in np.flatnonzero(upper > 0):
        for c in sorted({1, int(upper[j])}):
            r = np.zeros(m, int)
            r[j] = c
            rows.append(r)
    while len(rows) < size:
        rows.append(rng.integers(0, upper + 1))
    return np.array(rows)


@dataclass(frozen=True)
class SearchResult:
    """Every plan evaluated (``counts`` (E, m), ``cost``, ``worst`` and ``mean`` sigma/target
    over the coefficients (E,)), deduplicated."""

    counts: np.ndarray
    cost: np.ndarray
    worst: np.ndarray
    mean: np.ndarray

    def cheapest_meeting(self) -> int | None:
        """Index of the cheapest plan with worst sigma/target <= 1 (fewest tests on a tie)."""
        ok = np.flatnonzero(self.worst <= 1.0)
        if ok.size == 0:
            return None
        return int(ok[np.lexsort((self.counts[ok].sum(axis=1), self.cost[ok]))[0]])

    def best(self) -> int:
        """Index of the plan with the smallest worst sigma/target (on a tie, e.g. a coefficient
        no plan of the search sees, the smallest mean sigma/target, then the cheapest)."""
        return int(np.lexsort((self.cost, self.mean, self.worst))[0])

    def front(self) -> np.ndarray:
        """Indices of the Pareto-optimal plans (cost, worst sigma/target), by cost."""
        order = np.lexsort((self.worst, self.cost))
        keep, best = [], np.inf
        for i in order:
            if self.worst[i] < best:
                keep.append(i)
                best = self.worst[i]
        return np.array(keep, int)


def search(campaign: Campaign, cands: Candidates, rigs: tuple[str, ...] | None = None) -> SearchResult:
    """NSGA-II over the counts of the candidate tests of ``rigs`` (all when None)."""
    cols = np.concatenate([b.columns for b in cands.rigs if rigs is None or b.rig in rigs])
    opt = campaign.optimiser
    rng = np.random.default_rng(opt["seed"])
    problem = _PlanProblem(campaign, cands, cols)
    start = initial_plans(cands.max_repeats[cols], opt["population"], rng)
    algorithm = NSGA2(pop_size=len(start), sampling=start.astype(float),
                      crossover=SBX(prob=0.9, eta=3.0, vtype=float, repair=RoundingRepair()),
                      mutation=PM(eta=3.0, vtype=float, repair=RoundingRepair()), eliminate_duplicates=True)
    minimize(problem, algorithm, ("n_gen", opt["generations"]), seed=opt["seed"], verbose=False)
    # each plan's sigmas as its evaluation computed them: a plan's row of planned_sigma does not
    # depend on the batch it is in, and computing the archive's again was a fifth of the search
    # (issue 22 item 4)
    counts, first = np.unique(np.concatenate(problem.archive), axis=0, return_index=True)
    ratio = np.concatenate(problem.ratios)[first]
    return SearchResult(counts, plan_cost(cands, counts), ratio.max(axis=1), ratio.mean(axis=1))


# ------------------------------------------------------------------ the plan and its tables

def plan_sequence(campaign: Campaign, cands: Candidates, counts: np.ndarray) -> list[int]:
    """The tests of a plan in the order they are run: the cheaper rig first (its results are the
    prior of the dearer one), each rig's tests in candidate order, repeats side by side."""
    rate = {o.name: o.cost_per_hour for o in campaign.rigs}
    order = sorted(range(len(cands.tests)), key=lambda j: (rate[cands.tests[j].rig], j))
    return [j for j in order for _ in range(int(counts[j]))]


def describe(cands: Candidates, counts: np.ndarray) -> str:
    """A plan in one line: ``rig:scheme@dwell_s x count`` joined by ``+``."""
    parts = [f"{t.rig}:{t.scheme}@{t.dwell_s:g}s" + (f" x{int(c)}" if c > 1 else "")
             for t, c in zip(cands.tests, counts) if c > 0]
    return " + ".join(parts) or "(no test)"


def cumulative_counts(n_tests: int, sequence: list[int]) -> np.ndarray:
    """(S + 1, m) counts after 0, 1, ..., S tests of ``sequence``."""
    out = np.zeros((len(sequence) + 1, n_tests), int)
    for s, j in enumerate(sequence):
        out[s + 1] = out[s]
        out[s + 1, j] += 1
    return out


def plan_table(campaign: Campaign, cands: Candidates, sequence: list[int]) -> pd.DataFrame:
    """plan.csv: the tests in order with their rig time and cost (a rig's set-up on its first
    test) and the worst sigma/target once the test is done."""
    steps = cumulative_counts(len(cands.tests), sequence)
    worst = worst_ratio(campaign, planned_sigma(campaign, cands, steps[1:])) if sequence else np.array([])
    rows, used = [], set()
    for s, j in enumerate(sequence):
        t = cands.tests[j]
        offer = campaign.offer(t.rig)
        setup = 0.0 if t.rig in used else offer.setup_hours
        used.add(t.rig)
        rows.append({"step": s + 1, "rig": t.rig, "scheme": t.scheme, "dwell_s": t.dwell_s, "positions": t.positions,
                     "setup_hours": setup, "hours": t.hours + setup, "cost": (t.hours + setup) * offer.cost_per_hour,
                     "worst_sigma_over_target": float(worst[s])})
    return pd.DataFrame(rows, columns=["step", "rig", "scheme", "dwell_s", "positions", "setup_hours", "hours", "cost",
                                       "worst_sigma_over_target"])


def progress_table(campaign: Campaign, cands: Candidates, sequence: list[int]) -> pd.DataFrame:
    """sigma and sigma/target of every coefficient after each test (step 0: the prior)."""
    sig = planned_sigma(campaign, cands, cumulative_counts(len(cands.tests), sequence))
    pl = campaign.platform
    return pd.DataFrame([{"step": s, "name": n, "group": g, "unit": u, "sigma": float(sig[s, i]),
                          "sigma_over_target": float(sig[s, i] / campaign.target_sigma[i])}
                         for s in range(sig.shape[0])
                         for i, (n, g, u) in enumerate(zip(pl.names, pl.groups, pl.units))])


def rms_interval(rms: np.ndarray, replicates: int, level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """The ``level`` confidence interval of the true RMS error (the sigma the replicates' errors are
    drawn with) from the RMS over ``replicates`` zero-mean Gaussian errors: R rms^2 / sigma^2 is
    chi-square with R degrees of freedom. At 50 replicates it spans about 0.83-1.25 x rms, so a
    planned sigma 20 % off can still be within it."""
    lo, hi = stats.chi2.ppf([(1 + level) / 2, (1 - level) / 2], replicates)
    return rms * np.sqrt(replicates / lo), rms * np.sqrt(replicates / hi)


def coefficient_table(campaign: Campaign, planned: np.ndarray, check: Check | None = None) -> pd.DataFrame:
    """coefficients.csv: target, prior and planned sigma, the Monte Carlo's RMS error with its 95 %
    interval (:func:`rms_interval`; NaN when not run), ``planned_in_ci`` (the planned sigma inside
    that interval: the Cramer-Rao check with the replicates' sampling error) and ``meets``
    (achieved_rms <= target; empty without a Monte Carlo)."""
    pl = campaign.platform
    nan = np.full(len(pl.names), np.nan)
    ach, lo, hi = (nan, nan, nan) if check is None else (check.achieved_rms,
                                                         *rms_interval(check.achieved_rms, check.replicates))
    ran = ~np.isnan(ach)
    return pd.DataFrame({"name": pl.names, "unit": pl.units, "group": pl.groups, "target_sigma": campaign.target_sigma,
                         "prior_sigma": campaign.prior_sigma, "planned_sigma": planned,
                         "planned_over_target": planned / campaign.target_sigma, "achieved_rms": ach,
                         "achieved_rms_ci_low": lo, "achieved_rms_ci_high": hi,
                         "achieved_over_planned": ach / planned,
                         "planned_in_ci": pd.array([bool(a <= p <= b) if r else None
                                                    for a, p, b, r in zip(lo, planned, hi, ran)], dtype="boolean"),
                         "meets": pd.array([bool(a <= t) if r else None
                                            for a, t, r in zip(ach, campaign.target_sigma, ran)], dtype="boolean")})


def reference_counts(campaign: Campaign, cands: Candidates, tests: list[dict]) -> np.ndarray:
    counts = np.zeros(len(cands.tests), int)
    for t in tests:
        counts[cands.index(t["rig"], t["scheme"], float(t["dwell_s"]))] += int(t["count"])
    return counts


def alternative_row(campaign: Campaign, cands: Candidates, name: str, kind: str, counts: np.ndarray) -> dict:
    sig = planned_sigma(campaign, cands, counts)[0]
    ratio = sig / campaign.target_sigma
    i = int(np.argmax(ratio))
    return {"name": name, "kind": kind, "tests": describe(cands, counts), "cost": float(plan_cost(cands, counts)[0]),
            "meets_targets": bool(ratio.max() <= 1.0), "worst_sigma_over_target": float(ratio.max()),
            "worst_coefficient": campaign.platform.names[i]}


@dataclass(frozen=True)
class Plan:
    """A planned campaign: the candidates, the search, the chosen counts (None: no plan meets
    every target; then the plan with the least worst sigma/target is shown) and the tables."""

    campaign: Campaign
    cands: Candidates
    result: SearchResult
    counts: np.ndarray
    meets: bool
    sequence: list[int]
    plan: pd.DataFrame
    progress: pd.DataFrame
    alternatives: pd.DataFrame
    front: pd.DataFrame
    options: dict
    """name -> counts (m,) of each row of ``alternatives`` (the plan's included)."""


def make_plan(campaign: Campaign) -> Plan:
    """Search the campaign's tests for the cheapest plan meeting every target, and the
    alternatives (the cheapest single-rig plans, the reference plans)."""
    extra = [(t["rig"], t["scheme"], float(t["dwell_s"])) for tests in campaign.references.values() for t in tests]
    cands = candidates(campaign, extra)
    res = search(campaign, cands)
    pick = res.cheapest_meeting()
    meets = pick is not None
    counts = res.counts[res.best() if pick is None else pick]
    seq = plan_sequence(campaign, cands, counts)
    options = {"plan": ("plan", counts)}
    for offer in campaign.rigs:
        single = search(campaign, cands, (offer.name,))
        k = single.cheapest_meeting()
        name = f"cheapest {offer.name} only" if k is not None else f"best {offer.name} only (none meets)"
        options[name] = ("single_rig", single.counts[single.best() if k is None else k])
    for name, tests in campaign.references.items():
        options[name] = ("reference", reference_counts(campaign, cands, tests))
    alts = [alternative_row(campaign, cands, name, kind, c) for name, (kind, c) in options.items()]
    idx = res.front()
    front = pd.DataFrame({"cost": res.cost[idx], "worst_sigma_over_target": res.worst[idx],
                          "tests": [describe(cands, res.counts[i]) for i in idx]})
    return Plan(campaign, cands, res, counts, meets, seq, plan_table(campaign, cands, seq),
                progress_table(campaign, cands, seq), pd.DataFrame(alts), front,
                {name: c for name, (_, c) in options.items()})


# ------------------------------------------------------------------ the Monte Carlo check

def hand_on(x: np.ndarray, P: np.ndarray, index: np.ndarray, x_new: np.ndarray, P_new: np.ndarray):
    """The platform's estimate (B, n) and covariance (B, n, n) after a test that returned the
    posterior ``x_new`` (B, k), ``P_new`` (B, k, k) of the coefficients ``index`` (k,).

    The others are updated through their prior correlation with those (the Gaussian update of
    states the test does not see: ``G = P_ba P_aa^-1``, ``x_b += G (x_a' - x_a)``,
    ``P_bb -= G (P_aa - P_aa') G^T``, ``P_ba' = G P_aa'``); exact for a linear Gaussian model.
    Returns new arrays.
    """
    n = x.shape[1]
    a = np.asarray(index)
    b = np.setdiff1d(np.arange(n), a)
    x, P = x.copy(), P.copy()
    Paa = P[:, a[:, None], a[None, :]]
    Pba = P[:, b[:, None], a[None, :]]
    G = np.swapaxes(np.linalg.solve(Paa, np.swapaxes(Pba, 1, 2)), 1, 2)
    x[:, b] += np.einsum("bij,bj->bi", G, x_new - x[:, a])
    Pbb = P[:, b[:, None], b[None, :]] - G @ (Paa - P_new) @ np.swapaxes(G, 1, 2)
    P[:, b[:, None], b[None, :]] = 0.5 * (Pbb + np.swapaxes(Pbb, 1, 2))
    P[:, b[:, None], a[None, :]] = G @ P_new
    P[:, a[:, None], b[None, :]] = np.swapaxes(G @ P_new, 1, 2)
    P[:, a[:, None], a[None, :]] = P_new
    x[:, a] = x_new
    return x, P


def run_sequence(campaign: Campaign, cands: Candidates, sequence: list[int], seeds: list[list]) -> tuple:
    """Simulate and identify the tests of ``sequence`` in order, each rig's filter started from
    the previous posterior (the platform's prior, mean 0, first; a rig's nuisance states from
    its own prior, mean 0); ``seeds[s]`` the B SeedSequences of step s. Returns the platform's
    estimate (B, n) and covariance (B, n, n), engineering units."""
    B, n = len(seeds[0]), cands.n_coef
    x = np.zeros((B, n))
    P = np.broadcast_to(np.diag(campaign.prior_sigma**2), (B, n, n)).copy()
    truth = campaign.truth()
    blocks = {b.rig: b for b in cands.rigs}
    for s, j in enumerate(sequence):
        t = cands.tests[j]
        blk = blocks[t.rig]
        offer = campaign.offer(t.rig)
        k, idx = blk.keep, blk.index
        px = np.zeros((B, len(blk.names)))
        px[:, k] = x[:, idx]
        pP = np.broadcast_to(np.diag(blk.rig_prior**2), (B,) + (len(blk.names),) * 2).copy()
        pP[:, np.flatnonzero(k)[:, None], np.flatnonzero(k)[None, :]] = P[:, idx[:, None], idx[None, :]]
        xr, Pr = offer.rig.campaign.identify(offer.cfg, t.scheme, t.dwell_s, truth, px, pP, seeds[s])
        x, P = hand_on(x, P, idx, xr[:, k], Pr[:, np.flatnonzero(k)[:, None], np.flatnonzero(k)[None, :]])
    return x, P


@dataclass(frozen=True)
class Check:
    """The Monte Carlo check of a plan: per replicate the NEES of the n coefficients
    (``nees`` (R,), dof n), per coefficient the RMS error ``achieved_rms`` (n,) and the
    filter's own mean sigma ``filter_sigma`` (n,)."""

    replicates: int
    nees: np.ndarray
    achieved_rms: np.ndarray
    filter_sigma: np.ndarray
    seconds: float


# The check's replicates per rig call: whole blocks of the rigs' state-major filter kernels
# (platcal.estimation.lanes), whose short last block runs its idle lanes anyway: at 10 a batch
# paid for 12 (the centrifuge's EKF 0.97 s CPU at B = 10, 0.99 at 12; issue 22 item 4)
CHECK_BATCH = 5 * LANES


def check_plan(campaign: Campaign, cands: Candidates, sequence: list[int], replicates: int, label: str = "plan",
               batch: int = CHECK_BATCH) -> Check:
    """Run the plan ``replicates`` times (batches of ``batch``; replicate r of step s draws from
    the runner's ``replicate_seed(seed, '<campaign>/<label>/<s>', 0, r)``, so its numbers do not
    depend on the batch size)."""
    t0 = time.perf_counter()
    seed = int(campaign.montecarlo["seed"])
    truth = campaign.platform.truth
    errs, nees, sig = [], [], []
    for part in chunks(replicates, batch):
        seeds = [[replicate_seed(seed, f"{campaign.name}/{label}/{s}", 0.0, r) for r in part]
                 for s in range(len(sequence))]
        x, P = run_sequence(campaign, cands, sequence, seeds)
        e = x - truth
        errs.append(e)
        nees.append(np.einsum("bi,bi->b", e, np.linalg.solve(P, e[..., None])[..., 0]))
        sig.append(np.sqrt(np.diagonal(P, axis1=1, axis2=2)))
    e = np.concatenate(errs)
    return Check(replicates, np.concatenate(nees), np.sqrt((e**2).mean(axis=0)), np.concatenate(sig).mean(axis=0),
                 time.perf_counter() - t0)


# ------------------------------------------------------------------ figures and outputs

@styled
def front_figure(plan: Plan, path) -> None:
    """Cost against the worst sigma/target: every plan evaluated, the Pareto front, the chosen
    plan and the alternatives."""
    res, alts = plan.result, plan.alternatives
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ax.scatter(res.cost, res.worst, s=4, color="0.8", label="plans evaluated")
    ax.step(plan.front["cost"], plan.front["worst_sigma_over_target"], where="post", color="C0", label="Pareto front")
    for k, (marker, color) in {"single_rig": ("s", "C1"), "reference": ("^", "C2"), "plan": ("*", "C3")}.items():
        a = alts[alts["kind"] == k]
        ax.scatter(a["cost"], a["worst_sigma_over_target"], marker=marker, s=80 if k == "plan" else 40, color=color,
                   zorder=3, label={"single_rig": "single-rig plans", "reference": "papers' schemes",
                                    "plan": "chosen plan"}[k])
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.set_yscale("log")
    ax.set_xlabel("campaign cost (rig hours x rate)")
    ax.set_ylabel("worst coefficient sigma / target")
    ax.set_title(f"campaign {plan.campaign.name}: cost vs accuracy")
    ax.legend(fontsize=7)
    save(fig, path)


@styled
def progress_figure(plan: Plan, path) -> None:
    """sigma/target of every coefficient after each test of the plan (log scale)."""
    pr = plan.progress
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for i, (group, part) in enumerate(pr.groupby("group", sort=True)):
        for j, (_, one) in enumerate(part.groupby("name", sort=False)):
            ax.plot(one["step"], one["sigma_over_target"], color=f"C{i}", lw=0.8, alpha=0.7,
                    label=group if j == 0 else None)
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    labels = ["prior"] + [f"{r.rig}:{r.scheme}@{r.dwell_s:g}s" for r in plan.plan.itertuples()]
    ax.set_xticks(range(len(labels)), labels, rotation=30, ha="right", fontsize=7)
    ax.set_yscale("log")
    ax.set_ylabel("sigma / target")
    ax.set_title("each coefficient's sigma / target after each test")
    ax.legend(fontsize=7)
    save(fig, path)


def check_table(name: str, check: Check, planned: np.ndarray, target: np.ndarray, names) -> dict:
    """One row of check.csv: the Monte Carlo of a plan against its planned sigmas and targets."""
    ratio = check.achieved_rms / planned
    lo, hi = rms_interval(check.achieved_rms, check.replicates)
    return {"name": name, "replicates": check.replicates, "mean_nees": float(check.nees.mean()),
            "nees_dof": planned.size, "mean_nees_over_dof": float(check.nees.mean() / planned.size),
            "share_meeting_target": float((check.achieved_rms <= target).mean()),
            "share_rms_within_20pct_of_planned": float((np.abs(ratio - 1.0) <= 0.2).mean()),
            "share_planned_in_rms_ci95": float(((lo <= planned) & (planned <= hi)).mean()),
            "worst_rms_over_planned": float(ratio.max()),
            "worst_rms_over_planned_coefficient": names[int(np.argmax(ratio))], "seconds": check.seconds}


def report_markdown(plan: Plan, coefs: pd.DataFrame, checks: pd.DataFrame | None) -> str:
    """report.md of a campaign: the plan, its cost, the alternatives, planned vs achieved per
    coefficient, the Monte Carlo summary and the figures."""
    camp = plan.campaign
    lines = [f"# Calibration campaign `{camp.name}`", "",
             "The cheapest sequence of tests, across rigs, whose planned 1-sigma meets every coefficient's "
             "target (`platcal plan`, issue 23). Planned sigmas: the rigs' Fisher informations added on the "
             "platform's coefficient names, nuisance states marginalised per rig; search: NSGA-II over the "
             "test counts (cost vs worst sigma/target).", "",
             "## The plan", "",
             ("Meets every target (planned)." if plan.meets else
              "**No plan found meets every target**; shown: the plan with the least worst sigma/target."),
             f"Cost {plan.plan['cost'].sum():.6g} for {plan.plan['hours'].sum():.4g} rig hours.", "",
             frame_markdown(plan.plan), "", "## Alternatives", "",
             "The cheapest single-rig plans (or the best one rig can do when none meets) and the papers' own "
             "schemes, run once as published.", "", frame_markdown(plan.alternatives), ""]
    if checks is not None:
        lines += ["## Monte Carlo check", "",
                  "Each test simulated and identified on its rig in order, each filter started from the "
                  "previous posterior; errors over the replicates against the planned sigmas.", "",
                  frame_markdown(checks), ""]
    lines += ["## Planned vs achieved per coefficient", "", frame_markdown(coefs), "",
              "## Figures", "", "![cost vs accuracy](front.png)", "",
              "![sigma/target after each test](progress.png)", ""]
    return "\n".join(lines)


def write_plan(plan: Plan, out_dir, checks: dict[str, Check] | None = None) -> pd.DataFrame:
    """Write plan, coefficients and alternatives (csv, md, html), front.csv, progress.csv,
    check.csv (with a Monte Carlo), front.png, progress.png and report.md into ``out_dir``, each
    file atomically; returns the coefficients table."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    planned = planned_sigma(plan.campaign, plan.cands, plan.counts)[0]
    checks = checks or {}
    check = checks.get("plan")
    coefs = coefficient_table(plan.campaign, planned, check)
    total = plan.plan["cost"].sum()
    verdict = ("meets every target" if plan.meets else
               "NO plan found meets every target; shown: the plan with the least worst sigma/target")
    write_table(plan.plan, out / "plan", f"Campaign {plan.campaign.name}: the plan",
                f"{verdict}; cost {total:.6g}, {plan.plan['hours'].sum():.4g} rig hours")
    write_table(coefs, out / "coefficients", "Planned sigma (and Monte Carlo RMS error) per coefficient",
                "units: the unit column; meets = achieved_rms <= target_sigma; achieved_rms_ci_*: its 95 % "
                "interval over the replicates (chi-square); planned_in_ci: planned_sigma inside it")
    write_table(plan.alternatives, out / "alternatives", "The plan and its alternatives",
                "single-rig plans: the cheapest that meets every target, else the best it can do")
    table = None
    if checks:
        camp = plan.campaign
        table = pd.DataFrame([check_table(name, c, planned_sigma(camp, plan.cands, plan.options[name])[0],
                                          camp.target_sigma, camp.platform.names) for name, c in checks.items()])
        write_table(table, out / "check", "Monte Carlo check of the plan (and of its alternatives)",
                    "NEES over the n coefficients (dof n); share_meeting_target: achieved RMS <= target")
    atomic_to_csv(plan.front, out / "front.csv", index=False)
    atomic_to_csv(plan.progress, out / "progress.csv", index=False)
    front_figure(plan, out / "front.png")
    progress_figure(plan, out / "progress.png")
    atomic_write_text(out / "report.md", report_markdown(plan, coefs, table))
    return coefs


# ------------------------------------------------------------------ sizes (issue 25 item 3)

# Measured by benchmarks/size_estimate_more.py on the default campaign (load 7-8 on 2 cores),
# each rounded up about 2x for the load's noise; numba's first compile (about 45 s of the rigs'
# information hooks on a cold cache) is a fixed cost, not counted, as platcal.sizes says.
INFORMATION_SECONDS_PER_TEST_SECOND = 2e-4
"""CPU s the rigs' information hooks take per candidate test-second (positions x dwell_s): 0.7 s
for the default campaign's 12 candidates, 9240 test-seconds, 7.6e-5. Their memory is not counted
(each hook runs one test at a time)."""
SEARCH_SECONDS_PER_PLAN = 1e-3
"""CPU s per plan the search evaluates (pymoo and :func:`planned_sigma`): 5.4e-4 and 6.4e-4
(population 20 x 5 generations), 1.1e-4 .. 3.3e-4 for :func:`planned_sigma` alone on 500 and
4000 plans."""
SEARCH_VALUES_PER_PLAN = 18000
"""float64 values held per plan of a batch :func:`planned_sigma` judges at once (the (n, n)
information and the rigs' blocks): the peak grows by 9100 and 9700 values a plan between 500 and
4000 plans (45 coefficients). A search judges one generation at a time; its archive keeps each
plan's counts and sigma/target only (:func:`search`)."""
CHECK_SECONDS_PER_TEST_SECOND = 6e-4
"""CPU s the Monte Carlo check takes per replicate test-second (replicates x positions x dwell_s
of the plan's tests): 2.3e-4 .. 3.1e-4 on 10 and 30 replicates of a 2-test plan (1680 test-seconds)."""


def search_sizes(campaign: Campaign) -> list[Size]:
    """The work of planning ``campaign`` before its Monte Carlo check (:mod:`platcal.sizes`): the
    candidates' information (every rig's schemes x dwells, positions x dwell_s test-seconds, the
    rig with the most named) and the searches (the plan's and one per rig: population x
    generations plans each, one search's archive held at once, one generation judged at once)."""
    per_rig = {o.name: sum(o.rig.campaign.positions(o.cfg, s) * d for s in o.schemes for d in o.dwells)
               for o in campaign.rigs}
    most = max(per_rig, key=per_rig.get)
    opt = campaign.optimiser
    plans = float(opt["population"]) * float(opt["generations"])
    searches = 1 + len(campaign.rigs)
    # candidate tests: the rigs' schemes x dwells and at most one more per reference test
    tests = sum(len(o.schemes) * len(o.dwells) for o in campaign.rigs) + sum(map(len, campaign.references.values()))
    # the first generation is the start population (initial_plans: each test alone, twice)
    batch = max(float(opt["population"]), 1.0 + 2.0 * tests)
    # an archived plan: its counts and sigma/target (n values), held in pieces, concatenated and
    # sorted (np.unique) at the end: three copies
    archived = 3.0 * (tests + len(campaign.platform.names))
    return [Size(f"rigs.{most}.dwell_s", sum(per_rig.values()), 0, 1,
                 f"the candidate tests' information, {len(per_rig)} rig(s)' schemes x dwells",
                 INFORMATION_SECONDS_PER_TEST_SECOND, unit="candidate test-seconds"),
            Size("optimiser.generations", plans, archived, 1,
                 f"population {opt['population']} x {opt['generations']} generations, {searches} searches",
                 SEARCH_SECONDS_PER_PLAN, runs=searches, unit="plans"),
            Size("optimiser.population", batch, SEARCH_VALUES_PER_PLAN, 1,
                 f"a generation of population {opt['population']} judged at once", unit="plans")]


def check_size(cands: Candidates, sequences: dict[str, list[int]], replicates: int, field: str) -> Size:
    """The Monte Carlo check's work (:mod:`platcal.sizes`): ``replicates`` x the test-seconds
    (positions x dwell_s) of every plan checked (``sequences``, name -> tests in order)."""
    test_s = sum(cands.tests[j].positions * cands.tests[j].dwell_s for seq in sequences.values() for j in seq)
    return Size(field, test_s, 0, 1, f"{len(sequences)} plan(s) of {test_s:g} test-seconds",
                CHECK_SECONDS_PER_TEST_SECOND, runs=replicates, unit="test-seconds")


def run_campaign(source, out_dir, replicates: int | None = None, max_memory_gb: float = DEFAULT_MAX_MEMORY_GB,
                 max_hours: float = DEFAULT_MAX_HOURS) -> tuple[Plan, dict[str, Check]]:
    """Validate the campaign (InputError naming the field, before any work), plan it, check the
    plan by Monte Carlo (``replicates``; None: the campaign's, 0: none), and its alternatives too
    with ``montecarlo.alternatives``, and write the outputs. The planning's memory and time
    (:func:`search_sizes`) are checked against ``max_memory_gb`` and ``max_hours`` before it
    starts, the Monte Carlo check's (:func:`check_size`) once the plans are known, before it
    runs; nothing is written when either is refused."""
    check_writable(out_dir, "--out", folder=True)
    if replicates is not None and replicates < 0:
        raise InputError("--replicates", "must be >= 0 (0: no Monte Carlo check)")
    camp = load_campaign(source)
    n = int(camp.montecarlo["replicates"] if replicates is None else replicates)
    check_sizes(search_sizes(camp), max_memory_gb, max_hours)
    plan = make_plan(camp)
    checks = {}
    names = list(plan.options) if camp.montecarlo["alternatives"] else ["plan"]
    sequences = {name: plan_sequence(camp, plan.cands, plan.options[name]) for name in (names if n > 0 else [])}
    sequences = {name: seq for name, seq in sequences.items() if seq}
    field = "montecarlo.replicates" if replicates is None else "--replicates"
    check_sizes([check_size(plan.cands, sequences, n, field)], max_memory_gb, max_hours)
    for name, seq in sequences.items():
        checks[name] = check_plan(camp, plan.cands, seq, n, label="plan" if name == "plan" else name)
    write_plan(plan, out_dir, checks)
    return plan, checks


def plan_command(args) -> int:
    """``platcal plan --campaign FILE --out DIR [--replicates N] [--max-memory-gb G] [--max-hours H]``:
    validate and size (exit 2 naming the field, before any work), plan, write the outputs."""
    plan, checks = run_campaign(args.campaign, args.out, args.replicates, args.max_memory_gb, args.max_hours)
    for name, check in checks.items():
        print(f"Monte Carlo of {name} ({check.replicates} replicates): mean NEES {check.nees.mean():.4g} (dof "
              f"{plan.cands.n_coef}); coefficients meeting their target "
              f"{(check.achieved_rms <= plan.campaign.target_sigma).sum()}/{plan.cands.n_coef}")
    print(f"plan: {describe(plan.cands, plan.counts)}; cost {plan.plan['cost'].sum():.6g}; "
          f"meets every target: {plan.meets}; written to {args.out}")
    return 0
