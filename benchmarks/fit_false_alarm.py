"""False-alarm rate of the fit check (issue 25): clean records of a rig's default test, seeds 0..N-1,
identified as ``platcal identify`` does; the share whose fit check fails.

Each seed is the record ``platcal simulate --seed N`` writes (the Monte Carlo cell's replicate N)
kept in memory instead of a file. Prints one line per flagged seed, the largest channel score
(1 = the limit) over the seeds and the rate with its 95 % upper confidence bound.

    python benchmarks/fit_false_alarm.py --rig centrifuge [--seeds 100]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy import stats as sps

from platcal.cli import read_config
from platcal.rig import get_rig


def centrifuge_fits(config: str, seeds: range):
    """The fit check of each seed's record of the default scheme (table1)."""
    from platcal.rigs.centrifuge.identify import identify_input, record_fit, record_input
    from platcal.rigs.centrifuge.record import sim_to_frame
    from platcal.rigs.centrifuge.simulate import simulate
    from platcal.study.montecarlo import replicate_seed

    study = get_rig("centrifuge").load_config(read_config(config))
    scheme = study.schemes["table1"]
    params = study.centrifuge.scheme_params(scheme)
    for n in seeds:
        sim = simulate(study.truth, scheme, params, study.noise,
                       [replicate_seed(study.seed, scheme.name, study.noise.sigma_a_ug, n)], sample_s=study.sample_s)
        fin = record_input(study, scheme, sim_to_frame(sim, scheme))
        yield n, record_fit(identify_input(study, scheme, fin), fin, study, scheme)


def multiposition_fits(config: str, seeds: range):
    """The fit check of each seed's record of the study's first scheme (``platcal simulate``'s default)."""
    from platcal.rigs.multiposition.commands import identify, innovation_buffer, record_fit
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
        identify(cfg, rec, None, buf)
        yield n, record_fit(cfg, sch, rec, buf)


RIGS = {"centrifuge": (centrifuge_fits, "config/centrifuge.yaml"),
        "multiposition": (multiposition_fits, "config/multiposition.yaml")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rig", choices=sorted(RIGS), required=True)
    ap.add_argument("--config", default=None, help="the rig's config (default: its default study)")
    ap.add_argument("--seeds", type=int, default=100)
    args = ap.parse_args()
    fits, default = RIGS[args.rig]
    t0 = time.perf_counter()
    flagged, scores, nis = [], [], []
    for n, fc in fits(args.config or default, range(args.seeds)):
        scores.append(max(c.score for c in fc.channels))
        nis.append(fc.nis_per_dof)
        if not fc.passed:
            flagged.append(n)
            print(f"seed {n}: flagged: {fc.message()}", flush=True)
    k, N = len(flagged), args.seeds
    upper = float(sps.beta.ppf(0.95, k + 1, N - k))  # one-sided 95 % Clopper-Pearson
    print(f"{args.rig}: {k} of {N} clean records flagged ({100 * k / N:.1f} %, 95 % upper bound {100 * upper:.1f} %); "
          f"largest channel score {max(scores):.3f} (median {np.median(scores):.3f}; > 1 fails); NIS per dof "
          f"{min(nis):.4f} .. {max(nis):.4f}; {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
