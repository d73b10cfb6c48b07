"""Snakemake wrapper: results/campaign/ (plan, coefficients, alternatives, check, figures, report)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

from platcal.log import job_logger
from platcal.study.campaign import run_campaign

sm = snakemake  # noqa: F821
log = job_logger(sm.log[0])
plan, checks = run_campaign(sm.params.campaign, Path(sm.output[0]).parent)
log.info("plan cost %.6g, meets every target: %s", plan.plan["cost"].sum(), plan.meets)
for name, c in checks.items():
    log.info("Monte Carlo of %s: %d replicates, mean NEES %.4g", name, c.replicates, c.nees.mean())
