"""GA scheme design: reproducibility for a fixed seed, scheme-file round trip, config errors."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from platcal.cli import main
from platcal.rigs.centrifuge.config import load_config
from platcal.rigs.centrifuge.design import decode, design_config, output_paths, run_design, write_design
from platcal.errors import InputError
from platcal.scheme import load_scheme_file

CONFIG = Path(__file__).resolve().parents[1] / "config" / "centrifuge.yaml"
SMALL = {"dwell_s": 2, "positions": 4, "population": 8, "generations": 3}


@pytest.fixture(scope="module")
def study():
    return load_config(CONFIG)


def test_decode_wraps_and_maps_g_levels():
    X = np.array([[0, 359, 10, 20, 0, 1]])
    ang, gl = decode(X, 2, 0.0, [10.0, 20.0])
    np.testing.assert_array_equal(ang[0], [[0, 0, 359], [10, 0, 20]])
    np.testing.assert_array_equal(gl[0], [10.0, 20.0])


def test_ga_is_reproducible_for_a_fixed_seed(study):
    dcfg = design_config(study.config, **SMALL, seed=5)
    a = run_design(study, dcfg)
    b = run_design(study, dcfg)
    assert a.scheme == b.scheme
    assert a.value == b.value
    pd.testing.assert_frame_equal(a.population, b.population)
    np.testing.assert_array_equal(a.history["best"], b.history["best"])
    assert len(a.history) == 3 and np.all(np.diff(a.history["best"]) <= 0)
    assert a.value == pytest.approx(a.criteria["J"])
    pos = np.array(a.scheme.positions)
    assert pos.shape == (4, 3) and np.all(pos[:, 1] == 0) and pos.min() >= 0 and pos.max() <= 359
    c = run_design(study, design_config(study.config, **SMALL, seed=6))
    assert c.population["J"].tolist() != a.population["J"].tolist()


def test_scheme_file_round_trip(study, tmp_path):
    dcfg = design_config(study.config, **SMALL, seed=1, g_levels=[10, 20], criterion="A", name="ga_two")
    res = run_design(study, dcfg)
    paths = write_design(res, tmp_path / "ga_two.yaml")
    back = load_scheme_file(paths["scheme"])
    assert back == {"ga_two": res.scheme}
    assert res.scheme.g_levels is not None and set(res.scheme.g_levels) <= {10.0, 20.0}
    pop = pd.read_csv(paths["population"])
    assert len(pop) == 8 and pop["A"].iloc[0] == pytest.approx(res.value)
    hist = pd.read_csv(paths["history"])
    assert list(hist["generation"]) == [1, 2, 3]
    # the written scheme is usable as a config scheme
    cfg = dict(study.config)
    cfg = yaml.safe_load(yaml.safe_dump({k: v for k, v in cfg.items()}))
    cfg["schemes"] = yaml.safe_load(paths["scheme"].read_text())["schemes"]
    from platcal.rigs.centrifuge.config import study_from_config
    assert study_from_config(cfg).schemes["ga_two"] == res.scheme


def test_design_config_errors_name_the_field(study, tmp_path, capsys):
    with pytest.raises(InputError) as e:
        design_config(study.config, criterion="E")
    assert e.value.field == "design.criterion"
    with pytest.raises(InputError) as e:
        design_config({**study.config, "design": {"popsize": 3}})
    assert e.value.field == "design"
    with pytest.raises(InputError) as e:
        design_config(study.config, dwell_s=0.01)
    assert e.value.field == "design.dwell_s"
    assert design_config(study.config)["name"] == "ga_J"
    assert main(["design", "--config", str(CONFIG), "--out", str(tmp_path / "x.txt")]) == 2
    assert "--out" in capsys.readouterr().err
    assert not output_paths(tmp_path / "x.yaml")["scheme"].exists()


def test_presets_of_the_workflow(study):
    from platcal.rigs.centrifuge.design import preset

    st, d = preset(study, "ga_A_n4")
    assert (d["criterion"], d["positions"], d["name"]) == ("A", 4, "ga_A_n4")
    st, d = preset(study, "ga_doo")
    assert d["estimate_doo"] is True and d["g_levels"] == [10, 20]
    assert st.truth[45:].tolist() == [0.05] * 3 and study.truth[45:].tolist() == [0.0] * 3
    with pytest.raises(InputError) as e:
        preset(study, "ga_Q")
    assert e.value.field == "--preset"
