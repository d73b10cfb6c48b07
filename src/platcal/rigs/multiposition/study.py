"""The multiposition study of the Snakemake workflow: its set-up, the config of its rules and the
kernels' warm-up.

The rules are in ``workflow/rules/multiposition.smk``, their thin scripts
``workflow/scripts/multiposition_*.py``; results under ``results/multiposition/``. The Monte Carlo
cells are the generic runner's (``workflow/rules/montecarlo.smk``, hooks
:class:`.montecarlo.MultipositionMonteCarlo`, seeds there). The report's tables and figures are
:mod:`.report`'s: this module, which the workflow's start and most of the rig's jobs import, loads
no figure library, scipy.stats or sympy (issue 22 item 4).
"""

from __future__ import annotations

from ...study.montecarlo import chunk_sizes, package_code_hash
from .config import load_config
from .estimators import estimate, variant_choice
from .filter import covariance_only, simulate
from .montecarlo import check_scheme_names



def load(content: dict) -> object:
    """The validated rig config of a rule's config content (a mapping; InputError naming the field)."""
    return load_config(dict(content))


def spec_cell(cfg) -> tuple[str, float, str | None]:
    """The sweep's cell of §15 item 4: scheme S8 at sigma_a = 5 ug (§10's default) and the first
    estimator variant that is the EKF of §9 in one pass (None when the study has none)."""
    for name in cfg.raw["study"]["estimators"]:
        ch = variant_choice(cfg, name, field=f"study.estimators.{name}")
        if ch.estimator == "ekf" and ch.passes == 1:
            return "S8", 5.0, name
    return "S8", 5.0, None


def warm_batches(study: dict) -> list[int]:
    """The replicates per kernel call to warm up (docs/multiposition-1g.md §9): 2 when a cell runs
    a batch (the lanes kernel, :mod:`.filter_lanes`; one specialisation for every batch size), 1
    when a cell runs one replicate (the reference kernel, :func:`.filter._ekf_pass_one`). ``study``:
    the checked config's ``study`` section (``seeds``, ``batch``)."""
    sizes = chunk_sizes(int(study["seeds"]), int(study["batch"]))
    return [b for b, needed in ((2, max(sizes) > 1), (1, 1 in sizes)) if needed]


def warm_kernels(cfg) -> None:
    """Compile (or load) every numba kernel of the study once, on a tiny run, so that the jobs
    that follow load them from numba's cache instead of compiling them side by side: each
    estimator at the batch sizes the cells run (:func:`warm_batches`). The one-replicate
    reference kernel (an identify's) is warmed only when a cell runs one replicate: with the
    default 20 seeds in one batch no study job calls it (issue 22 item 4; the campaign's checks
    call the rig in batches of 20 replicates, the claims' noise-free check runs its one replicate
    in the lanes kernel)."""
    s = cfg.scheme("TET4")
    t, _, z = simulate(cfg, s, [0, 1])
    batches = warm_batches(cfg.raw["study"])
    for name in cfg.raw["study"]["estimators"]:
        choice = variant_choice(cfg, name, field=f"study.estimators.{name}")
        for b in batches:
            estimate(cfg, choice, s.angles_deg, t[:5], z[:b, :, :5])
    covariance_only(cfg, s.angles_deg, 1.0)
    covariance_only(cfg, s.angles_deg, 1.0, sequential=False)


# ------------------------------------------------------------------ workflow set-up

RULE_SECTIONS = {
    "lie_cache": ("rig", "observability"),
    "observability": ("rig", "site", "gimbal", "sampling", "noise", "truth", "filter", "observability", "schemes"),
    "design": ("rig", "seed", "site", "gimbal", "sampling", "noise", "truth", "filter", "observability", "design",
               "schemes"),
    "extension": ("rig", "site", "gimbal", "sampling", "noise", "truth", "filter", "observability", "extension",
                  "schemes"),
}
"""The config sections each of the rig's own rules reads (its Snakemake param, the rest left to the
schema's defaults): an edit elsewhere leaves the rule's outputs alone. The report reads everything."""
RULE_SCHEMES = {"design": ("S8", "TET4"), "extension": ("S8",)}
"""The named schemes a rule uses (the rank-table rule: ``study.rank_schemes``)."""


class WorkflowSetup:
    """What ``workflow/rules/multiposition.smk`` needs, from the rig's config content (a mapping,
    as :func:`platcal.rig.rig_config` reads a path or an inline entry of the study index).

    Validates the rig config (InputError naming the field) before any job runs. ``active`` is
    False when ``raw`` is None (the rig is not in the study: no targets). The Monte Carlo
    cells and their collection are the generic rules' (``montecarlo_cell``, ``collect``).
    """

    R = "results/multiposition/"

    def __init__(self, raw: dict | None, centrifuge: bool = False):
        self.centrifuge = centrifuge
        self.active = raw is not None
        self.code = package_code_hash(__package__) if self.active else ""
        if not self.active:
            self.cfg, self.study = None, {"schemes": [], "rank_schemes": [], "sigma_a_ug": []}
            self.design_k = []
            return
        self.cfg = load(raw)
        check_scheme_names(self.cfg)
        self.study = self.cfg.raw["study"]
        self.design_k = list(self.cfg.raw["design"]["positions"])

    @property
    def config(self) -> dict:
        """The whole validated config, defaults filled (the report's param; empty when inactive)."""
        return self.cfg.raw if self.active else {}

    def rule_config(self, rule: str) -> dict:
        """The config content rule ``rule`` depends on (:data:`RULE_SECTIONS`); the rank-table
        rule gets only the schemes it checks; empty when the rig is not in the study."""
        if not self.active:
            return {}
        raw = self.cfg.raw
        out = {k: raw[k] for k in RULE_SECTIONS[rule] if k in raw}
        if "schemes" in out:
            used = RULE_SCHEMES.get(rule, self.study["rank_schemes"])
            out["schemes"] = {k: v for k, v in raw["schemes"].items() if k in used}
        return out

    def observability(self) -> list[str]:
        return [f"{self.R}observability/{s}/observability.json" for s in self.study["rank_schemes"]]

    def centrifuge_json(self) -> list[str]:
        return [f"{self.R}centrifuge_table1/observability.json"] if self.active and self.centrifuge else []

    def targets(self) -> list[str]:
        if not self.active:
            return []
        r = self.R
        return [f"{r}tables/ranks.csv", f"{r}tables/montecarlo_summary.csv", f"{r}tables/design.csv",
                f"{r}tables/extension_sigma.csv", f"{r}figures/ranks.png", f"{r}figures/montecarlo.png",
                f"{r}figures/nees.png", f"{r}figures/extension.png",
                f"{r}figures/extension_draws.png", f"{r}montecarlo/coef.parquet", f"{r}report.md"]
