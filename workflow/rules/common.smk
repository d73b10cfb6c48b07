# The study index, each rig's validated config (field named before any job runs), code hashes.
from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

from platcal.errors import InputError
from platcal.rig import get_rig, rig_config
from platcal.study.montecarlo import code_hash, compute_code_hash, noise_label

# config/config.yaml is the index: rigs: {name: config path or inline mapping}
validate(config, "../schemas/config.schema.yaml")
RIGS = list(config["rigs"])
CODE_ALL = code_hash()  # the whole package: the aggregate rules' param


def checked_config(rig):
    """The rig's config validated by the rig (defaults filled); a bad value stops the run here."""
    try:
        raw = rig_config(config, rig)
        hooks = get_rig(rig).montecarlo
        return hooks.check(raw) if hooks is not None else raw
    except InputError as exc:
        raise WorkflowError(f"invalid configuration: {exc.field}: {exc.message} (rigs.{rig})")
