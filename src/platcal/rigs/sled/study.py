"""The sled study's tables, figures and report (workflow/rules/sled.smk; docs/rocket-sled.md §8, §11).

The cases' replicates run as generic Monte Carlo cells (:mod:`.montecarlo`); their §8 metrics
are the extra columns of the tidy runs table, from which the summary makes the Table-1
analogue, the §11 check table and report.md. The figures show each case's replicate 0, whose
time series one small job per case writes (:func:`platcal.rigs.sled.series.write_series`).
"""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from ...io import atomic_write_text  # noqa: E402
from ...study.plots import save as save_figure  # noqa: E402
from ...study.claims import ledger_section  # noqa: E402
from ...study.tables import frame_markdown, write_table  # noqa: E402
from .config import load_config  # noqa: E402
from .montecarlo import CASES  # noqa: E402


def case_metrics(runs: pd.DataFrame, cases) -> dict[str, pd.DataFrame]:
    """Per case (in ``cases`` order), its replicates' §8 metrics and ``failed`` flag from the
    study's tidy runs table (one row per replicate, sorted)."""
    return {c: runs[runs["scheme"] == c].sort_values("replicate").reset_index(drop=True) for c in cases}


def rms(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x ** 2))) if np.isfinite(x).all() else float("nan")


TABLE1_COLUMNS = [
    ("yz_before_max_run_cm", "Y/Z before, run max (cm)"),
    ("y_after_a_max_run_cm", "Y after A (cm)"),
    ("z_after_a_max_run_cm", "Z after A (cm)"),
    ("y_after_b_max_run_cm", "Y after B (cm)"),
    ("z_after_b_max_run_cm", "Z after B (cm)"),
    ("x_naive_stop_cm", "X naive, stop (cm)"),
    ("x_constrained_stop_cm", "X constrained, stop (cm)"),
    ("x_naive_end_cm", "X naive, end (cm)"),
    ("x_constrained_end_cm", "X constrained, end (cm)"),
    ("phi_x_eff_err_arcsec", "phi_x eff err (arcsec)"),
    ("phi_y_eff_err_arcsec", "phi_y eff err (arcsec)"),
    ("phi_z_eff_err_arcsec", "phi_z eff err (arcsec)"),
    ("phi_y_true_err_arcsec", "phi_y true err (arcsec)"),
    ("phi_z_true_err_arcsec", "phi_z true err (arcsec)"),
]


def table1(mets: dict[str, pd.DataFrame], failed: dict[str, int] | None = None) -> pd.DataFrame:
    """Table-1 analogue: per case, 'RMS (max)' over the seeds of each metric; ``failed``: runs
    per case left out because their filters failed (:func:`split_failed`)."""
    rows = []
    for case, m in mets.items():
        row = {"case": case, "seeds": len(m), "failed runs": (failed or {}).get(case, 0)}
        for key, label in TABLE1_COLUMNS:
            v = m[key].to_numpy(float)
            row[label] = "-" if not np.isfinite(v).all() else f"{rms(v):.3g} ({v.max():.3g})"
        rows.append(row)
    return pd.DataFrame(rows)


def checks(mets: dict[str, pd.DataFrame], ranks: pd.DataFrame) -> pd.DataFrame:
    """The §11 'must show' items against the study's numbers (only those whose case ran)."""
    out = []

    def add(item, what, value, required, holds):
        out.append({"item": item, "check": what, "measured": value, "required": required,
                    "holds": "yes" if holds else "NO"})

    g = mets.get
    if g("default") is not None:
        m = g("default")
        yz = m["yz_before_max_run_cm"] / 100
        add(1, "run-phase max of abs(r_y), abs(r_z): RMS; max", f"{rms(yz):.2f} m; {yz.max():.2f} m", "1.5-3.0 m; > 3 m",
            1.5 <= rms(yz) <= 3.0 and yz.max() > 3)
        add(1, "stop time, run length, v_max", f"{m.stop_time_s[0]:.2f} s, {m.run_length_m[0]:.1f} m, "
            f"{m.v_max_m_s[0]:.1f} m/s", "25.90 s, 4075.8 +- 0.5 m, 294.2 m/s",
            abs(m.stop_time_s[0] - 25.9) < 1e-6 and abs(m.run_length_m[0] - 4075.8) <= 0.5
            and abs(m.v_max_m_s[0] - 294.2) < 0.05)
        worst = m[["y_after_a_max_run_cm", "z_after_a_max_run_cm", "y_after_a_max_static_cm"]].to_numpy().max()
        add(3, "metric A max over seeds (run and static)", f"{worst:.3f} cm", "<= 1 cm", worst <= 1)
        add(4, "metric B Y, 6 states, RMS", f"{rms(m.y_after_b_max_run_cm):.1f} cm", ">= 25 cm",
            rms(m.y_after_b_max_run_cm) >= 25)
        add(5, "phi_y / phi_z effective error RMS", f"{rms(m.phi_y_eff_err_arcsec):.2f} / "
            f"{rms(m.phi_z_eff_err_arcsec):.2f} arcsec", "<= 2.5 / <= 3 arcsec",
            rms(m.phi_y_eff_err_arcsec) <= 2.5 and rms(m.phi_z_eff_err_arcsec) <= 3)
        add(6, "X naive minus truth at the stop, RMS", f"{rms(m.x_naive_stop_cm):.1f} cm", "40-60 cm",
            40 <= rms(m.x_naive_stop_cm) <= 60)
        add(6, "X naive / constrained (realtime) at the end, RMS",
            f"{rms(m.x_naive_end_cm) / rms(m.x_constrained_end_cm):.1f}x", ">= 3x",
            rms(m.x_naive_end_cm) >= 3 * rms(m.x_constrained_end_cm))
    if g("paper_tuning") is not None:
        m = g("paper_tuning")
        worst = m[["y_after_a_max_run_cm", "z_after_a_max_run_cm", "y_after_a_max_static_cm"]].to_numpy().max()
        add(3, "metric A max, paper tuning", f"{worst:.1f} cm", "<= 30 cm", worst <= 30)
    if g("run7") is not None:
        m = g("run7")
        add(4, "metric B Y, 7 states, RMS; max", f"{rms(m.y_after_b_max_run_cm):.2f} cm; "
            f"{m.y_after_b_max_run_cm.max():.2f} cm", "<= 3 cm; <= 6 cm",
            rms(m.y_after_b_max_run_cm) <= 3 and m.y_after_b_max_run_cm.max() <= 6)
        add(4, "metric B Z, 7 states, RMS", f"{rms(m.z_after_b_max_run_cm):.1f} cm", "<= 30 cm",
            rms(m.z_after_b_max_run_cm) <= 30)
        add(5, "phi_x effective error RMS, 7 states", f"{rms(m.phi_x_eff_err_arcsec):.2f} arcsec", "<= 6 arcsec",
            rms(m.phi_x_eff_err_arcsec) <= 6)
    if g("post") is not None:
        m = g("post")
        add(6, "X constrained (post) at the stop / end, RMS", f"{rms(m.x_constrained_stop_cm):.1f} / "
            f"{rms(m.x_constrained_end_cm):.0f} cm", "<= 12 / <= 120 cm",
            rms(m.x_constrained_stop_cm) <= 12 and rms(m.x_constrained_end_cm) <= 120)
        add(6, "X naive / constrained (post) at the end, RMS",
            f"{rms(m.x_naive_end_cm) / rms(m.x_constrained_end_cm):.1f}x", ">= 3x",
            rms(m.x_naive_end_cm) >= 3 * rms(m.x_constrained_end_cm))
    if g("misalign0_post") is not None:
        m = g("misalign0_post")
        add(6, "X constrained (post), misalignment 0, at the stop, RMS", f"{rms(m.x_constrained_stop_cm):.2f} cm",
            "<= 3 cm", rms(m.x_constrained_stop_cm) <= 3)
    spec = {("run 7-state", "0"): "5/7 6/7 6/7 6/7 7/7", ("run 7-state", "Earth rate"): "6/7 7/7 7/7 7/7 7/7",
            ("run 7-state", "Earth rate + 0.01 rad/s about z"): "7/7 7/7 7/7 7/7 7/7",
            ("run 6-state", "0"): "4/6 6/6 6/6 6/6 6/6", ("run 6-state", "Earth rate"): "4/6 6/6 6/6 6/6 6/6",
            ("run 6-state", "Earth rate + 0.01 rad/s about z"): "4/6 6/6 6/6 6/6 6/6",
            ("stop 6-state", "Earth rate"): "6/6"}
    r = ranks.set_index(["model", "omega"])
    got = {key: " ".join(x for x in r.loc[key].tolist() if x) for key in spec if key in r.index}
    same = got == spec
    add(7, "observability table (the §11 rows; default trajectory only)", "identical" if same else str(got),
        "the §11 table exactly", same)
    return pd.DataFrame(out)


def figures(ser: dict[str, pd.DataFrame], outdir: str | Path) -> dict[str, str]:
    """The figures a sled engineer expects; returns {name: file name}."""
    outdir = Path(outdir)
    names = {}
    d6 = ser.get("default")
    d7 = ser.get("run7")
    base = d6 if d6 is not None else next(iter(ser.values()))
    t_stop = base.t[base.a_z.notna()].max()
    # 1. Y/Z before and after
    fig, axs = plt.subplots(2, 2, figsize=(11, 7))
    for col, ax_ in zip(("y", "z"), axs[0]):
        ax_.plot(base.t, base[f"r_{col}"], label=f"navigation r_{col} (before)")
        ax_.axvline(t_stop, color="grey", ls=":", label="stop")
        ax_.set(xlabel="time (s)", ylabel=f"{col.upper()} position error (m)", title=f"{col.upper()} before, replicate 0")
        ax_.legend(fontsize=8)
    for col, ax_ in zip(("y", "z"), axs[1]):
        ax_.plot(base.t, 100 * base[f"a_{col}"], label="after A (nav - filter estimate)")
        ax_.plot(base.t, 100 * base[f"b_{col}"], label="after B, 6 states (nav - model)")
        if d7 is not None:
            ax_.plot(d7.t, 100 * d7[f"b_{col}"], label="after B, 7 states")
        ax_.axvline(t_stop, color="grey", ls=":")
        ax_.set(xlabel="time (s)", ylabel=f"{col.upper()} after (cm)", title=f"{col.upper()} after compensation, replicate 0")
        ax_.legend(fontsize=8)
    fig.tight_layout()
    names["yz"] = "yz_before_after.png"
    save_figure(fig, outdir / names["yz"], dpi=110, tight=False)
    # 2. X error naive / constrained / truth
    fig, ax_ = plt.subplots(figsize=(9, 5))
    ax_.plot(base.t, 100 * base.e_naive, label="naive navigation")
    ax_.plot(base.t, 100 * base.e_con, label="constrained (realtime, 6 states)")
    if "post" in ser:
        ax_.plot(ser["post"].t, 100 * ser["post"].e_con, label="constrained (post, 6 states)")
    ax_.plot(base.t, 100 * base.e_inst, "k--", label="instrument-only truth")
    ax_.axvline(t_stop, color="grey", ls=":", label="stop")
    ax_.set(xlabel="time (s)", ylabel="X error vs error-free run (cm)", title="Along-track (X) error, replicate 0")
    ax_.legend(fontsize=8)
    fig.tight_layout()
    names["x"] = "x_error.png"
    save_figure(fig, outdir / names["x"], dpi=110, tight=False)
    # 3. attitude estimates ± 3 sigma (run phase)
    src = d7 if d7 is not None else base
    run = src[src.a_z.notna()]
    axes = [a for a in ("x", "y", "z") if f"phi_{a}_hat" in run]
    fig, axs = plt.subplots(len(axes), 1, figsize=(9, 2.6 * len(axes)), sharex=True)
    for a, ax_ in zip(axes, np.atleast_1d(axs)):
        hat, sig = run[f"phi_{a}_hat"], run[f"phi_{a}_sigma"]
        ax_.plot(run.t, hat, label=f"phi_{a} estimate")
        ax_.fill_between(run.t, hat - 3 * sig, hat + 3 * sig, alpha=0.25, label="+-3 sigma")
        ax_.axhline(run[f"phi_{a}_eff"].iloc[0], color="k", ls="--", label="effective value")
        ax_.axhline(run[f"phi_{a}_true"].iloc[0], color="r", ls=":", label="true phi0")
        lo = min(run[f"phi_{a}_eff"].iloc[0], run[f"phi_{a}_true"].iloc[0]) - 60
        hi = max(run[f"phi_{a}_eff"].iloc[0], run[f"phi_{a}_true"].iloc[0]) + 60
        ax_.set(ylabel=f"phi_{a} (arcsec)", ylim=(lo, hi), title=f"run-filter phi_{a}, replicate 0 "
                f"({'7' if d7 is not None else '6'} states)")
        ax_.legend(fontsize=7, ncol=4)
    np.atleast_1d(axs)[-1].set_xlabel("time (s)")
    fig.tight_layout()
    names["attitude"] = "attitude.png"
    save_figure(fig, outdir / names["attitude"], dpi=110, tight=False)
    return names


def summarise(runs_file: str, series_files: dict[str, str], rank_csv: str, outdir: str | Path, raw: dict,
              claims: pd.DataFrame | None = None) -> None:
    """Table-1 analogue, §11 checks, figures and report.md under ``outdir`` from the tidy runs
    table of the Monte Carlo study (``results/sled/montecarlo/runs.parquet``); ``claims``: the
    rig's ledger rows (``results/sled/claims.csv``), which open the report."""
    outdir = Path(outdir)
    mets, failed = split_failed(case_metrics(pd.read_parquet(runs_file), raw["study"]["cases"]))
    ser = {c: pd.read_csv(p) for c, p in series_files.items()}
    ranks = pd.read_csv(rank_csv, dtype=str, keep_default_na=False)
    t1 = table1(mets, failed)
    write_table(t1, outdir / "table1", "Sled: Table-1 analogue, RMS (max) over the seeds",
                note="before/after metric A/B, X error against the instrument-only truth, attitude errors")
    chk = checks(mets, ranks)
    write_table(chk, outdir / "checks", "Sled: docs/rocket-sled.md §11 'what an implementation must show'")
    figs = figures(ser, outdir / "figures")
    atomic_write_text(outdir / "report.md", report_md(mets, t1, chk, ranks, figs, raw, failed, claims))


def split_failed(mets: dict[str, pd.DataFrame]) -> tuple[dict[str, pd.DataFrame], dict[str, int]]:
    """Per case, the seeds whose filters ran (column ``failed`` False) and the number that failed
    (non-finite navigation or estimates, covariance not positive definite): failed runs are
    counted in the tables and the report, never averaged in."""
    ok, failed = {}, {}
    for c, m in mets.items():
        bad = m["failed"].astype(bool) if "failed" in m else pd.Series(False, index=m.index)
        ok[c], failed[c] = m[~bad].reset_index(drop=True), int(bad.sum())
    return ok, failed


def raw_sigma_x(raw: dict) -> float:
    """phi_x sigma of the study's config, arcsec."""
    return load_config(raw).alignment_arcsec[0]


def _about_1cm(raw, m) -> str:
    a = m[["y_after_a_max_run_cm", "z_after_a_max_run_cm"]].to_numpy()
    return (
        f"- **What \"about 1 cm\" means.** Before the constraint the navigation drifts "
        f"{rms(m.yz_before_max_run_cm) / 100:.2f} m RMS (max {m.yz_before_max_run_cm.max() / 100:.2f} m) in Y/Z "
        f"during the run and up to {m.yz_before_max_all_cm.max() / 100:.1f} m with the static period. The paper's "
        f"\"Y and Z reduced to about 1 cm\" is metric A (navigation minus the filter's own position-error "
        f"estimate): here {rms(a[:, 0]):.3f} cm RMS, {a.max():.3f} cm at worst, i.e. far below 1 cm. It only says "
        "that the filter tracks its measurements, which any filter with small R does; it does not say "
        "the attitude is right.")


def _paper_tuning(raw, m) -> str:
    return (f"- With the paper's literal tuning (R = 1e6 I) metric A is {rms(m.y_after_a_max_run_cm):.1f} cm "
            f"RMS in Y (max {m.y_after_a_max_run_cm.max():.1f} cm): the same order as the paper's \"about "
            "1 cm\" (the paper's units are unknown, [D4]).")


def _paper7(raw, m) -> str:
    return (
        f"- **The paper's own set-up** (7 states, P0 = I, Q = 1e-9 I, R = 1e6 I, realtime): metric B Y "
        f"{rms(m.y_after_b_max_run_cm):.2f} cm RMS ({m.y_after_b_max_run_cm.min():.2f}-"
        f"{m.y_after_b_max_run_cm.max():.2f} cm over the seeds), the paper's \"about 1 cm\"; it costs the "
        f"attitude, phi_y effective error {rms(m.phi_y_eff_err_arcsec):.1f} arcsec RMS "
        f"({m.phi_y_eff_err_arcsec.abs().min():.1f}-{m.phi_y_eff_err_arcsec.abs().max():.1f}), and X: "
        f"{rms(m.x_constrained_stop_cm):.0f} cm RMS at the stop ({m.x_constrained_stop_cm.min():.0f}-"
        f"{m.x_constrained_stop_cm.max():.0f} cm) against {rms(m.x_naive_stop_cm):.0f} cm uncompensated.")


def _six_states(raw, m6, m7) -> str:
    return (
        f"- **Where the 6-state choice costs accuracy.** Metric B (re-navigating with the final attitude "
        f"estimate) exposes the dropped roll angle: Y {rms(m6.y_after_b_max_run_cm):.1f} cm RMS with 6 states "
        f"against {rms(m7.y_after_b_max_run_cm):.2f} cm with 7 (max {m7.y_after_b_max_run_cm.max():.2f} cm); "
        f"Z is {rms(m6.z_after_b_max_run_cm):.1f} / {rms(m7.z_after_b_max_run_cm):.1f} cm either way, limited "
        "by the vertical accelerometer bias, which is not a state. The stacked whole-run observability "
        "matrix of the 7-state model has full rank even with no Earth rate, because a_x changes between the "
        "phases, so the paper's reason to drop phi_x is conservative for a boost/coast/brake profile. The "
        f"X channel does not care: phi_x does not enter the X compensation (X at the end "
        f"{rms(m6.x_constrained_end_cm):.0f} vs {rms(m7.x_constrained_end_cm):.0f} cm).")


def _unmodelled_roll(raw, m6, m7) -> str:
    t_s = float(m6.stop_time_s[0])
    return (
        f"- The 6-state metric B is the unmodelled roll alone: 0.5·g·phi_x·t_stop² with the drawn phi_x gives "
        f"{rms(0.5 * 9.80665 * m6.phi0_x_arcsec * np.pi / 648000 * t_s ** 2 * 100):.1f} cm RMS for these seeds "
        f"(their phi_x draws have RMS {rms(m6.phi0_x_arcsec):.1f} arcsec against sigma "
        f"{raw_sigma_x(raw):g} arcsec); the spec's 50.9 cm corresponds to draws near sigma.")


def _attitude(raw, m) -> str:
    return (
        f"- **Attitude.** phi_y / phi_z are estimated to {rms(m.phi_y_eff_err_arcsec):.2f} / "
        f"{rms(m.phi_z_eff_err_arcsec):.2f} arcsec RMS of their *effective* values (filter 1 sigma "
        f"{m.phi_y_sigma_arcsec.mean():.1f} arcsec) but only to {rms(m.phi_y_true_err_arcsec):.1f} / "
        f"{rms(m.phi_z_true_err_arcsec):.1f} arcsec of the true angles: the 5 arcsec accelerometer misalignment "
        "is inseparable from the attitude under the Y/Z constraint.")


def _x_channel(raw, m, mp) -> str:
    return (
        f"- **X.** Naive navigation minus the instrument-only truth: {rms(m.x_naive_stop_cm):.1f} cm RMS at the "
        f"stop, {rms(m.x_naive_end_cm):.0f} cm at the end. Constrained, realtime: "
        f"{rms(m.x_constrained_stop_cm):.1f} / {rms(m.x_constrained_end_cm):.0f} cm; post: "
        f"{rms(mp.x_constrained_stop_cm):.1f} / {rms(mp.x_constrained_end_cm):.0f} cm. Realtime loses at the "
        "stop because the early part of the run is compensated with a not-yet-converged attitude.")


def _misalign0(raw, m) -> str:
    return (f"- With zero accelerometer misalignment (post) the constrained X error is "
            f"{rms(m.x_constrained_stop_cm):.2f} cm RMS at the stop and {rms(m.x_constrained_end_cm):.0f} cm "
            "at the end: the residual of the default case is the misalignment M_zx, which the constraint "
            "cannot see.")


def _stop_filter(raw, m) -> str:
    return (f"- The stop filter's by-product g(phi_y_run - phi_y_stop) is {rms(m.nabla_x_hat_ug):.0f} ug "
            f"RMS; against the static X accelerometer error it is off by {rms(m.nabla_x_err_ug):.0f} ug RMS "
            "(it contains g·M_zx). It is reported, not used for X ([D6]).")


READING = (
    (("default",), _about_1cm),
    (("paper_tuning",), _paper_tuning),
    (("paper7",), _paper7),
    (("default", "run7"), _six_states),
    (("default", "run7"), _unmodelled_roll),
    (("default",), _attitude),
    (("default", "post"), _x_channel),
    (("misalign0_post",), _misalign0),
    (("default",), _stop_filter),
)
"""The report's reading, in order: the cases a sentence reads (each a frame of its replicates'
metrics) and the function that writes it from ``(raw config, *frames)``; a sentence whose cases
the study did not run is left out."""


def report_md(mets, t1, chk, ranks, figs, raw, failed: dict[str, int] | None = None,
              claims: pd.DataFrame | None = None) -> str:
    """results/sled/report.md: the rig's claims ledger rows first (``claims``; none: no section),
    tables inline, figures linked, the reading of the numbers."""
    g = mets.get
    n = len(next(iter(mets.values())))
    n_failed = sum((failed or {}).values())
    lines = ["# Rig 3: rocket-sled one-dimensional motion constraint", "",
             f"Spec: docs/rocket-sled.md (Wei & Gao 2020). {n} seeds per case; numbers are RMS (max) over the seeds.",
             "", f"Failed runs (non-finite navigation or estimates, covariance not positive definite): {n_failed}"
             + (f", left out of the numbers: {', '.join(f'{c} {k}' for c, k in failed.items() if k)}" if n_failed
                else "."), ""]
    if claims is not None:
        lines += [ledger_section(claims), ""]
    lines += ["## Cases", ""]
    lines += [f"- `{c}`: {CASES[c][1]}" for c in mets]
    lines += ["", "## Table-1 analogue", "", frame_markdown(t1), "## Checks of §11", "", frame_markdown(chk),
              "## Observability ranks (§8)", "", frame_markdown(ranks), "## Figures", "",
              f"![Y/Z before and after](figures/{figs['yz']})", "",
              f"![X error](figures/{figs['x']})", "", f"![attitude](figures/{figs['attitude']})", "",
              "## Reading", ""]
    for cases, sentence in READING:
        frames = [g(c) for c in cases]
        if all(f is not None for f in frames):
            lines.append(sentence(raw, *frames))
    bad = chk[chk.holds != "yes"]
    lines += ["", "## The spec's reference numbers", "",
              f"{len(chk) - len(bad)} of {len(chk)} §11 checks hold (the ledger above judges the paper's claims)."
              + ("" if bad.empty else " Checks that do not hold: " + "; ".join(f"item {r.item} {r.check}: {r.measured} "
                                                                     f"(required {r.required})"
                                                                     for r in bad.itertuples()) + "."),
              "The spec's reference numbers (independent implementation, other random streams): Y/Z before "
              "217.5 cm RMS; metric A 0.021 cm; B Y 50.9 (6 states) / 1.3 cm (7); attitude 1.6 / 2.0 arcsec; "
              "X naive 48.6 / 531 cm, realtime 21.1 / 125 cm, post 9.1 / 95 cm, misalignment 0 post 1.7 / 30 cm.",
              "", f"Config: `{json.dumps(raw, sort_keys=True)}`", ""]
    return "\n".join(lines)
