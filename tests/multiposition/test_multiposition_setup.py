"""The multiposition workflow's set-up refuses bad scheme names before any job (issue 13 item 2)."""

import pytest
import yaml

from platcal.errors import InputError
from platcal.rig import rig_config
from platcal.rigs.multiposition.study import WorkflowSetup


@pytest.mark.parametrize("key", ["schemes", "rank_schemes"])
def test_unknown_scheme_name_is_refused_before_any_job(tmp_path, key):
    cfg = yaml.safe_load(open("config/multiposition.yaml"))
    cfg.setdefault("study", {})[key] = ["S8", "nope"]
    path = tmp_path / "mp.yaml"
    path.write_text(yaml.safe_dump(cfg))
    with pytest.raises(InputError) as exc:
        WorkflowSetup(rig_config({"rigs": {"multiposition": str(path)}}, "multiposition"))
    assert exc.value.field == f"study.{key}[1]"
    assert "nope" in str(exc.value) and "GA" in str(exc.value)


def test_config_that_is_not_utf8_is_refused(tmp_path):
    path = tmp_path / "mp.yaml"
    path.write_bytes(b"rig: multiposition\n\xff\xfe\x00")
    with pytest.raises(InputError) as exc:
        WorkflowSetup(rig_config({"rigs": {"multiposition": str(path)}}, "multiposition"))
    assert exc.value.field == "rigs.multiposition"


def test_default_config_passes():
    assert WorkflowSetup(rig_config({"rigs": {"multiposition": "config/multiposition.yaml"}}, "multiposition")).active


def test_skipped_updates_make_a_run_fail():
    """issue 13 item 3: a run whose updates were skipped (S not positive definite) is a failure."""
    import numpy as np
    from platcal.rigs.multiposition.commands import run_problems

    est, P = np.zeros(24), np.eye(24)
    assert run_problems(est, P, 1.0, 0) == []
    msg = run_problems(est, P, 1.0, 3)
    assert len(msg) == 1 and msg[0].startswith("3 measurement update(s) failed")
