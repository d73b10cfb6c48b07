"""Long logs in bounded memory (issue 22 item 3), low-precision centrifuge: the velocity's cubic
spline evaluated window by window (:func:`velocity_derivative` with overlapping windows) gives the
whole spline's values, and the identification of a record without fE, fN (f from that spline) its
estimates, with a small ``--chunk-rows`` and with the whole spline (``--chunk-rows 0``)."""

import json

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
import yaml

from platcal.cli import build_parser, main
from platcal.errors import InputError
from platcal.io import read_config
from platcal.rig import get_rig
from platcal.rigs.lowprec_centrifuge.montecarlo import SEED_KEY
from platcal.rigs.lowprec_centrifuge.record import (block_frame, record_frame, truth_json, velocity_derivative,
                                                   write_record)
from platcal.rigs.lowprec_centrifuge.stream import _unwrap_tail
from platcal.records import truth_path
from platcal.rigs.lowprec_centrifuge.truth import RecordBlock, RecordRun, simulate_batch
from platcal.sizes import DEFAULT_MAX_HOURS, DEFAULT_MAX_MEMORY_GB, check_sizes
from platcal.study.montecarlo import replicate_seed

SMALL = {"rig": "lowprec_centrifuge", "profile": {"rest_first_s": 10, "rest_between_s": 30},
         "runs": {"P1": {"run1": [5, 8]}, "P2": {"run1": [5, 8]}}}


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec")
    cfg = d / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(SMALL))
    assert main(["simulate", "--config", str(cfg), "--platform", "P1", "--run", "run1", "--seed", "3",
                 "--out", str(d / "rec.csv")]) == 0
    df = pd.read_csv(d / "rec.csv")
    df.drop(columns=["fE", "fN"]).to_csv(d / "nof.csv", index=False)
    (d / "nof.csv.truth.json").write_text((d / "rec.csv.truth.json").read_text())
    return d, str(cfg), df


@pytest.mark.parametrize("window,overlap", [(997, 64), (3001, 32)])
def test_windowed_spline_equals_whole(record, window, overlap):
    _, _, df = record
    t, v = df["t"].to_numpy(float), df[["VE", "VN"]].to_numpy(float)
    assert t.size > 4 * window
    whole = velocity_derivative(t, v, window=t.size)
    part = velocity_derivative(t, v, window=window, overlap=overlap)
    assert np.max(np.abs(part - whole)) <= 1e-12 * np.max(np.abs(whole))
    # too little overlap leaves the end effects: the test can tell (0.268 per knot, 4 knots: 5e-3)
    short = velocity_derivative(t, v, window=window, overlap=4)
    assert np.max(np.abs(short - whole)) > 1e-9 * np.max(np.abs(whole))


def test_identify_with_small_chunks_equals_whole_spline(record):
    d, cfg, _ = record
    out = {}
    for chunk in ("0", "1000"):
        assert main(["identify", "--config", cfg, "--data", str(d / "nof.csv"), "--out", str(d / f"id{chunk}"),
                     "--chunk-rows", chunk]) == 0
        out[chunk] = (pd.read_csv(d / f"id{chunk}" / "estimates.csv"),
                      json.loads((d / f"id{chunk}" / "summary.json").read_text()))
    (e0, s0), (e1, s1) = out["0"], out["1000"]
    np.testing.assert_allclose(e1["estimate"], e0["estimate"], rtol=1e-9, atol=0)
    np.testing.assert_allclose(e1["sigma"], e0["sigma"], rtol=1e-9, atol=0)
    assert s0["windows"] == s1["windows"]


def _identified(cfg, data, out, chunk, *extra):
    assert main(["identify", "--config", cfg, "--data", str(data), "--out", str(out), "--chunk-rows", chunk,
                 *extra]) == 0
    return pd.read_csv(out / "estimates.csv"), json.loads((out / "summary.json").read_text())


@pytest.mark.parametrize("suffix", ["csv", "parquet"])
def test_streamed_identify_equals_whole_read(record, suffix):
    """issue 22 item 3: the record processed chunk by chunk (chunks smaller than the spline's and
    the heading rate's context, and chunks that cut windows and spins) gives the whole read's
    estimates, sigmas, window count, levels and fit check."""
    d, cfg, df = record
    data = d / f"rec.{suffix}"
    if suffix == "parquet":
        df.to_parquet(data)
    e0, s0 = _identified(cfg, data, d / f"w_{suffix}", "0")
    for chunk in ("997", "50"):
        e1, s1 = _identified(cfg, data, d / f"c{chunk}_{suffix}", chunk)
        np.testing.assert_allclose(e1["estimate"], e0["estimate"], rtol=1e-9, atol=0)
        np.testing.assert_allclose(e1["sigma"], e0["sigma"], rtol=1e-9, atol=0)
        for key in ("windows", "levels_g", "samples_per_spin", "samples_per_phase", "samples"):
            assert s1[key] == s0[key], key
        assert s1["fit"]["verdict"] == s0["fit"]["verdict"]
        np.testing.assert_allclose(s1["fit"]["nis_per_dof"], s0["fit"]["nis_per_dof"], rtol=1e-9)


def test_streamed_traditional_equals_whole_read(tmp_path):
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump({**SMALL, "traditional": {"levels_g": [5, 8], "hold_s": 20, "rest_last_s": 10}}))
    assert main(["simulate", "--config", str(cfg), "--platform", "P1", "--run", "traditional", "--seed", "1",
                 "--out", str(tmp_path / "t.csv")]) == 0
    e0, s0 = _identified(str(cfg), tmp_path / "t.csv", tmp_path / "w", "0", "--method", "traditional")
    e1, s1 = _identified(str(cfg), tmp_path / "t.csv", tmp_path / "c", "333", "--method", "traditional")
    np.testing.assert_allclose(e1["estimate"], e0["estimate"], rtol=1e-12, atol=0)
    assert s1["samples_per_plateau"] == s0["samples_per_plateau"] and s1["levels_g"] == s0["levels_g"]


def test_unwrap_continued_over_chunks_is_numpys():
    rng = np.random.default_rng(5)
    psi = np.mod(np.cumsum(rng.uniform(-3.5, 3.5, 5000)), 2 * np.pi)
    parts, prev, corr = [], None, 0.0
    for a in range(0, psi.size, 613):
        out, corr = _unwrap_tail(prev, corr, psi[a:a + 613])
        prev = float(psi[a + out.size - 1])
        parts.append(out)
    assert np.array_equal(np.concatenate(parts), np.unwrap(psi))


def test_streamed_bad_input_still_refused(record, tmp_path, capsys):
    """A record that starts while spinning is refused after its other checks, as the whole read did."""
    d, cfg, df = record
    moving = np.flatnonzero(df["schedule"].to_numpy() != "static")
    bad = df.iloc[moving[0]:].reset_index(drop=True)
    bad.to_csv(tmp_path / "bad.csv", index=False)
    for chunk in ("0", "500"):
        assert main(["identify", "--config", cfg, "--data", str(tmp_path / "bad.csv"), "--out",
                     str(tmp_path / "o"), "--chunk-rows", chunk]) == 2
        assert "starts while spinning" in capsys.readouterr().err
        assert not (tmp_path / "o" / "estimates.csv").exists()


def test_simulate_writes_the_record_of_the_whole_batch(record, tmp_path):
    """simulate navigates the INS without the sensitivity variants (less memory): the CSV text is
    that of the batch with them (today's record)."""
    d, cfg, _ = record
    study = get_rig("lowprec_centrifuge").load_config(read_config(cfg))
    ss = replicate_seed(study.seed, SEED_KEY, study.residuals["accel_noise_ug_rthz"], 3)
    rb = simulate_batch(study, "P1", "run1", [ss], [3], keep_phi=True, sens=True)
    write_record(record_frame(rb), truth_json(rb, study), tmp_path / "with_sens.csv")
    assert (tmp_path / "with_sens.csv").read_bytes() == (d / "rec.csv").read_bytes()
    assert (tmp_path / "with_sens.csv.truth.json").read_text() == (d / "rec.csv.truth.json").read_text()


def test_a_streamed_identify_is_not_sized_as_the_whole_record(tmp_path):
    """A 2 GB record (about 17 h at 100 Hz) passes the default memory limit streamed (it holds two
    chunks and its windows) and is refused read whole (``--chunk-rows 0``), naming --data."""
    data = tmp_path / "big.csv"
    with open(data, "wb") as fh:
        fh.truncate(2_000_000_000)   # sparse: only its size is read
    rig = get_rig("lowprec_centrifuge")
    cfg = rig.load_config({"rig": "lowprec_centrifuge"})
    base = ["identify", "--config", "c.yaml", "--data", str(data), "--out", "o"]
    check_sizes(rig.sizes("identify", cfg, build_parser(rig).parse_args(base)), DEFAULT_MAX_MEMORY_GB,
                DEFAULT_MAX_HOURS)
    with pytest.raises(InputError) as e:
        check_sizes(rig.sizes("identify", cfg, build_parser(rig).parse_args(base + ["--chunk-rows", "0"])),
                    DEFAULT_MAX_MEMORY_GB, DEFAULT_MAX_HOURS)
    assert e.value.field == "--data"


STREAM_CFG = {**SMALL, "traditional": {"levels_g": [5, 8], "hold_s": 20, "rest_last_s": 10}}


@pytest.mark.parametrize("run,extra", [("run1", []), ("traditional", []), ("run1", ["--noise-free"])])
def test_streamed_simulate_equals_whole(tmp_path, run, extra):
    """issue 22 item 3: simulate written chunk by chunk (blocks that cut spins, the fine truth's
    w'' context and the noise streams) gives the whole simulation's CSV text, truth side file
    (its final errors known only at the end) and Parquet values."""
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(STREAM_CFG))
    files = {}
    for chunk in ("0", "997", "50"):
        for suffix in ("csv", "parquet"):
            out = tmp_path / f"r{chunk}.{suffix}"
            assert main(["simulate", "--config", str(cfg), "--platform", "P1", "--run", run, "--seed", "2",
                         "--chunk-rows", chunk, "--out", str(out), *extra]) == 0
            files[chunk, suffix] = out
    whole_csv = files["0", "csv"].read_bytes()
    assert len(whole_csv.splitlines()) > 3 * 997   # several blocks of 997 rows
    whole_truth = json.loads((tmp_path / "r0.csv.truth.json").read_text())
    for chunk in ("997", "50"):
        assert files[chunk, "csv"].read_bytes() == whole_csv, chunk
        for suffix in ("csv", "parquet"):
            assert json.loads(truth_path(files[chunk, suffix]).read_text()) == whole_truth
        pd.testing.assert_frame_equal(pd.read_parquet(files[chunk, "parquet"]), pd.read_parquet(files["0", "parquet"]),
                                      check_exact=True)
    assert pq.ParquetFile(files["997", "parquet"]).num_row_groups > 1
    assert whole_truth["final_errors"]["dVE"] == pd.read_csv(files["0", "csv"])["truth_dVE"].iloc[-1]


def test_record_run_is_the_monte_carlos_replicate(record):
    """The streamed record (:class:`RecordRun`, small blocks) is, array for array, replicate 1 of
    the Monte Carlo's batch (:func:`simulate_batch` with the floor and the four variants, as a
    study cell runs it): a simulated record still is a run of the study."""
    _, cfg, _ = record
    study = get_rig("lowprec_centrifuge").load_config(read_config(cfg))
    seeds = [replicate_seed(study.seed, SEED_KEY, study.residuals["accel_noise_ug_rthz"], r) for r in range(3)]
    rb = simulate_batch(study, "P2", "run1", seeds, [0, 1, 2], keep_phi=True, floor=True, sens=True)
    run = RecordRun(study, "P2", "run1", seeds[1], rows=1234)
    blocks = list(run.blocks())
    assert len(blocks) > 5
    got = {f: np.concatenate([getattr(b, f) for b in blocks]) for f in RecordBlock.__dataclass_fields__}
    want = {"t": rb.prof.t, "schedule": rb.prof.schedule, "theta": rb.kin.theta, "err": rb.err[1], "phi": rb.phi[1],
            "v_ind": rb.v_ind[1], "f_meas": rb.f_meas[1], "p_ind": rb.p_ind[1], "psi": rb.psi[1]}
    for f, v in want.items():
        assert np.array_equal(got[f], v), f
    assert np.array_equal(run.final, rb.final[1])
    for f in ("k0_ug", "scale_ppm", "drift_deg_h", "phi0_rad", "gyro_g"):
        assert np.array_equal(getattr(run.draws, f)[0], getattr(rb.draws, f)[1]), f


def test_record_run_internal_block_does_not_change_the_record(record):
    """:class:`RecordRun` simulating 777 samples at a time (``work``: spans that divide neither
    the 4321-sample blocks nor the run) gives the record of one span per block, CSV byte for byte,
    and the same final errors (issue 22 item 3)."""
    _, cfg, _ = record
    study = get_rig("lowprec_centrifuge").load_config(read_config(cfg))
    seed = replicate_seed(study.seed, SEED_KEY, study.residuals["accel_noise_ug_rthz"], 3)
    runs = {work: RecordRun(study, "P1", "run1", seed, rows=4321, work=work) for work in (4321, 777)}
    text = {}
    for work, run in runs.items():
        blocks = list(run.blocks())
        assert len(blocks) > 2 and blocks[-1].t.size % 777
        text[work] = "".join(block_frame(b.t, b.schedule, b.theta, b.err, b.phi, b.v_ind, b.f_meas, b.p_ind,
                                         b.psi).to_csv(index=False, header=i == 0) for i, b in enumerate(blocks))
    assert runs[777].work == 777 and runs[4321].work == 4321
    assert text[777] == text[4321]
    assert np.array_equal(runs[777].final, runs[4321].final)
