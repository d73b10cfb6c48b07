"""Configuration: defaults from the schema, YAML number parsing, field-named errors."""

from pathlib import Path

import numpy as np
import pytest

from platcal.rigs.centrifuge.config import SCHEMA_RESOURCE, load_config, schema, study_from_config, validate_config
from platcal.errors import InputError
from platcal.io import read_yaml
from platcal.schema import load_schema
from platcal.model.instruments import INDEX
from platcal.rigs.centrifuge.catalogue import load_catalogue
from platcal.scheme import TABLE1_POSITIONS

ROOT = Path(__file__).resolve().parents[1]
ONE = {"schemes": {"s": {"dwell_s": 1, "positions": [[0, 0, 0]]}}}


def test_default_config_is_the_papers_setting():
    st = load_config(ROOT / "config" / "centrifuge.yaml")
    sch = st.schemes["table1"]
    assert sch.positions == tuple(tuple(float(a) for a in p) for p in TABLE1_POSITIONS)
    assert sch.dwell_s == 60
    np.testing.assert_array_equal(st.truth[:45], load_catalogue().truth)
    assert st.filter.period_s == 0.02 and st.keep_every == 4 and st.sample_s == 0.005
    assert st.filter.p0_sigma[INDEX["k0_x"]] == 1e4  # written 1.0e4 in YAML
    assert st.centrifuge.latitude_deg == 28.2 and st.centrifuge.rate_deg_s == 180


def test_minimal_config_gets_spec_defaults():
    cfg = validate_config(ONE)
    assert cfg["noise"] == {"sigma_a_ug": 10, "arw_deg_rth": 0.001, "sigma_set_arcsec": 10}
    assert cfg["filter"]["passes"] == 1 and cfg["filter"]["period_ms"] == 20
    st = study_from_config(ONE)
    assert st.filter.sigma_a_ug == 10 and st.filter.arw_deg_rth == 0.001
    p0 = dict(zip(st.filter.state_names, st.filter.p0_sigma))
    assert p0["DF_x"] == 10 and p0["DIS_y"] == 0.2 and p0["k1_z"] == 2e3 and p0["theta_oz"] == 600
    assert "DOO_x" not in p0 and len(st.filter.p0_sigma) == 45


def test_truth_overrides_and_doo_states():
    st = study_from_config({**ONE, "truth": {"DF_x": 1.5, "DOO_z": 0.02}, "filter": {"estimate_doo": True}})
    assert st.truth[INDEX["DF_x"]] == 1.5 and st.truth[INDEX["DOO_z"]] == 0.02
    assert len(st.filter.state_names) == 51 and st.filter.state_names[45] == "DOO_x"


@pytest.mark.parametrize("cfg, field", [
    ({"noise": {"arw_deg_rth": -0.1}}, "noise.arw_deg_rth"),
    ({"filter": {"p0": {"DQ": 1}}}, "filter.p0.DQ"),
    ({"filter": {"period_ms": 7}}, "filter.period_ms"),
    ({"centrifuge": {"rate_deg_s": "fast"}}, "centrifuge.rate_deg_s"),
    ({"schemes": {"s": {"dwell_s": 1.0012, "positions": [[0, 0, 0]]}}}, "schemes.s.dwell_s"),
    ({"schemes": {"s": {"dwell_s": 1, "positions": [[0, -90, 0]]}}}, "schemes.s.positions[1]"),
    ({"schemes": {"s": {"dwell_s": 1, "positions": [[0, 0, 0]], "g_levels": [1, 2]}}}, "schemes.s.g_levels"),
])
def test_errors_name_the_field(cfg, field):
    with pytest.raises(InputError) as err:
        study_from_config({**ONE, **cfg})
    assert err.value.field == field


def test_schema_parsed_once_and_every_caller_gets_its_own_copy():
    # the parse is cached per process (a study's check validates once per cell), but a caller
    # that extends its schema (with_mapping_schema adds the record keys) must not change the next
    pkg = "platcal.rigs.centrifuge"
    text = (ROOT / "src" / "platcal" / "rigs" / "centrifuge" / SCHEMA_RESOURCE).read_text(encoding="utf-8")
    first = load_schema(pkg, SCHEMA_RESOURCE)
    assert repr(first) == repr(read_yaml(text))  # the one YAML reader's parse, types included
    first["properties"]["noise"]["properties"]["sigma_a_ug"]["default"] = -1.0
    first["properties"].pop("filter")
    again = load_schema(pkg, SCHEMA_RESOURCE)
    assert again is not first and repr(again) == repr(read_yaml(text))
    with_record = schema()
    with_record["properties"]["record"]["properties"]["extra"] = {"type": "string"}
    assert "extra" not in schema()["properties"]["record"]["properties"]
    assert validate_config(ONE)["noise"]["sigma_a_ug"] == read_yaml(text)["properties"]["noise"]["properties"][
        "sigma_a_ug"]["default"]
