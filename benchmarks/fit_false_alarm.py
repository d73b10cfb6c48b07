"""False-alarm rate of the fit check (issue 25): clean records of a rig's default test, seeds 0..N-1,
identified as ``platcal identify`` does; the share whose fit check fails.

Each seed is the record ``platcal simulate --seed N`` writes (the Monte Carlo cell's replicate N)
kept in memory instead of a file; the centrifuge's and multiposition rig's clock-rate check
(after the filter, exit 2 in ``platcal identify``) counts as a flag too. Prints one line per flagged seed, the largest channel score
(1 = the limit) over the seeds and the rate with its 95 % upper confidence bound.

    python benchmarks/fit_false_alarm.py --rig centrifuge|multiposition|sled|lowprec_centrifuge [--seeds 100]

The sled and the low-precision centrifuge simulate and identify their seeds in batches (the
same filters as ``platcal identify``, on the clean grid instead of a record file).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy import stats as sps

from platcal.errors import InputError
from platcal.io import read_config
from platcal.rig import get_rig


def refusal(check, *args) -> str | None:
    """The message of a check run after the filter (the clock-rate check: an InputError, exit 2),
    None when it passes: a clean record it refuses is a false alarm as well."""
    try:
        check(*args)
    except InputError as exc:
        return f"refused: {exc}"
    return None


def centrifuge_fits(config: str, seeds: range):
    """The fit check of each seed's record of the default scheme (table1)."""
    from platcal.rigs.centrifuge.identify import (check_clock_rate, identify_input, record_clock, record_fit,
                                                  record_input)
    from platcal.rigs.centrifuge.record import sim_to_frame
    from platcal.rigs.centrifuge.simulate import simulate
    from platcal.study.montecarlo import replicate_seed

    study = get_rig("centrifuge").load_config(read_config(config))
    scheme = study.schemes["table1"]
    params = study.centrifuge.scheme_params(scheme)
    for n in seeds:
        sim = simulate(study.truth, scheme, params, study.noise,
                       [replicate_seed(study.seed, scheme.name, study.noise.sigma_a_ug, n)], sample_s=study.sample_s)
        df = sim_to_frame(sim, scheme)
        fin = record_input(study, scheme, df)
        est = identify_input(study, scheme, fin)
        yield n, record_fit(est, fin, study, scheme), refusal(check_clock_rate, study, scheme, est,
                                                              record_clock(study, df))


def multiposition_fits(config: str, seeds: range):
    """The fit check of each seed's record of the study's first scheme (``platcal simulate``'s default)."""
    from platcal.rigs.multiposition.commands import check_clock_rate, identify, innovation_buffer, record_fit
    from platcal.rigs.multiposition.filter import replicate_seeds, simulate
    from platcal.rigs.multiposition.record import read_record, to_frame

    cfg = get_rig("multiposition").load_config(read_config(config))
    scheme = cfg.scheme(None)
    for n in seeds:
        t, phi, z = simulate(cfg, scheme, replicate_seeds(cfg, scheme.name, [n]))
        path = f"/tmp/fit_false_alarm_multiposition_{n}.parquet"
        to_frame(scheme, t, phi[0], z[0]).to_parquet(path)
        rec, sch = read_record(path, scheme, ts=cfg.ts, max_gap_s=float(cfg.raw["record"]["max_gap_s"]))
        buf = innovation_buffer(rec)
        est, P, _, _ = identify(cfg, rec, None, buf)
        yield n, record_fit(cfg, sch, rec, buf), refusal(check_clock_rate, cfg, rec, est, np.sqrt(np.diag(P)))


def sled_fits(config: str, seeds: range, batch: int = 10):
    """The fit check of each seed's record of the default case (``platcal simulate --seed N``)."""
    from platcal.rigs.sled.identify import identify, record_fit
    from platcal.rigs.sled.montecarlo import replicate_seeds
    from platcal.rigs.sled.record import check_plausible
    from platcal.rigs.sled.simulate import simulate

    cfg = get_rig("sled").load_config(read_config(config))
    for a in range(seeds.start, seeds.stop, batch):
        ns = list(range(a, min(a + batch, seeds.stop)))
        sb = simulate(cfg, replicate_seeds(cfg.raw, "default", ns))
        idn = identify(cfg, sb.traj, sb.f, sb.w)
        t = np.arange(sb.traj.n) * cfg.dt
        for s, n in enumerate(ns):
            # the checks before the filters (exit 2 in platcal identify) count as flags too
            yield n, record_fit(idn, s), refusal(check_plausible, cfg, sb.traj, sb.f[s], sb.w[s], t)


def lowprec_fits(config: str, seeds: range, batch: int = 5):
    """The fit check of each seed's record of the config's first platform and its first run
    (``platcal simulate --platform P --run R --seed N``), proposed method."""
    from platcal.rigs.lowprec_centrifuge.commands import record_fit
    from platcal.rigs.lowprec_centrifuge.montecarlo import SEED_KEY
    from platcal.rigs.lowprec_centrifuge.proposed import FilterResult, identify_proposed
    from platcal.rigs.lowprec_centrifuge.truth import simulate_batch
    from platcal.study.montecarlo import replicate_seed

    study = get_rig("lowprec_centrifuge").load_config(read_config(config))
    platform = study.platform_names()[0]
    run = study.run_names(platform)[0]
    noise = study.residuals["accel_noise_ug_rthz"]
    for a in range(seeds.start, seeds.stop, batch):
        ns = list(range(a, min(a + batch, seeds.stop)))
        rb = simulate_batch(study, platform, run, [replicate_seed(study.seed, SEED_KEY, noise, n) for n in ns], ns)
        fr = identify_proposed(rb.prof.t, rb.v_ind, rb.p_ind, rb.psi, rb.f_meas, rb.prof.schedule,
                               study.centrifuge.arm_m, study.latitude_deg, keep_innovations=True)
        for s, n in enumerate(ns):
            yield n, record_fit(FilterResult(x=fr.x[s:s + 1], P=fr.P[s:s + 1], n_windows=fr.n_windows[s:s + 1],
                                             mean_nis=fr.mean_nis[s:s + 1], failed_updates=fr.failed_updates[s:s + 1],
                                             innovations=fr.innovations[s:s + 1])), None


RIGS = {"centrifuge": (centrifuge_fits, "config/centrifuge.yaml"),
        "multiposition": (multiposition_fits, "config/multiposition.yaml"),
        "sled": (sled_fits, "config/sled.yaml"),
        "lowprec_centrifuge": (lowprec_fits, "config/lowprec_centrifuge.yaml")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rig", choices=sorted(RIGS), required=True)
    ap.add_argument("--config", default=None, help="the rig's config (default: its default study)")
    ap.add_argument("--seeds", type=int, default=100)
    args = ap.parse_args()
    fits, default = RIGS[args.rig]
    t0 = time.perf_counter()
    flagged, scores, nis = [], [], []
    for n, fc, refused in fits(args.config or default, range(args.seeds)):
        scores.append(max(c.score for c in fc.channels))
        nis.append(fc.nis_per_dof)
        if not fc.passed or refused:
            flagged.append(n)
            print(f"seed {n}: flagged: {refused or fc.message()}", flush=True)
    k, N = len(flagged), args.seeds
    upper = float(sps.beta.ppf(0.95, k + 1, N - k))  # one-sided 95 % Clopper-Pearson
    print(f"{args.rig}: {k} of {N} clean records flagged ({100 * k / N:.1f} %, 95 % upper bound {100 * upper:.1f} %); "
          f"largest channel score {max(scores):.3f} (median {np.median(scores):.3f}; > 1 fails); NIS per dof "
          f"{min(nis):.4f} .. {max(nis):.4f}; {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
