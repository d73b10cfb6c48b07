"""`platcal observability` of a rule's config content (no config path: the content is the param)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
import sys
import tempfile
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import yaml

from platcal.cli import main

sm = snakemake  # noqa: F821
with tempfile.TemporaryDirectory() as d, open(sm.log[0], "w") as log, redirect_stdout(log), redirect_stderr(log):
    cfg = Path(d) / "config.yaml"
    cfg.write_text(yaml.safe_dump(dict(sm.params.config)), encoding="utf-8")
    status = main(["observability", "--config", str(cfg), "--scheme", "table1", "--out", str(Path(sm.output[0]).parent)])
sys.exit(status)
