"""Tables, figures and report.md of the multiposition study (its Monte Carlo from the collected tidy tables)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from platcal.log import job_logger
from platcal.rigs.multiposition.report import report_job

sm = snakemake  # noqa: F821
report_job(sm.input, sm.output.report, sm.params.config, log=job_logger(sm.log[0]).info)
