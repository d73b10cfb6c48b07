"""How well the size check (platcal.sizes, issue 25 item 3) predicts a command's memory and time.

For each rig, ``platcal simulate`` then ``platcal identify`` then ``platcal inspect`` of a short and
a long run (the same config with one duration changed), each in a fresh process; the process's
peak resident memory (``ru_maxrss``) and CPU time (user + system) are compared with the rig's
estimate (``Rig.sizes``). The slopes between the two runs, bytes and CPU seconds per sample (per
byte of the record file for inspect), are what the data cost (the fixed cost of Python, numpy and
numba is the intercept); the estimate should be at or above them.

    NUMBA_NUM_THREADS=1 python benchmarks/size_estimate.py [--rig sled] [--scale 1]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from platcal.cli import build_parser
from platcal.io import read_yaml
from platcal.rig import rig_of

CASES = {  # rig: (config with {d} for the duration, simulate options, identify options, short, long durations)
    "centrifuge": ("rig: centrifuge\nschemes: {big: {dwell_s: {d}, positions: [[0, 0, 0], [90, 0, 0]]}}\n",
                   ["--scheme", "big"], ["--scheme", "big"], 60, 600),
    "multiposition": ("rig: multiposition\ngimbal: {beta_max_deg: 85}\n"
                      "schemes: {big: {dwell_s: {d}, positions: [[0, 0, 0], [180, 0, 0]]}}\n",
                      ["--scheme", "big"], ["--scheme", "big"], 60, 3600),
    "sled": ("rig: sled\ntrajectory: {static_after_s: {d}}\n", [], [], 60, 1200),
    "lowprec_centrifuge": ("rig: lowprec_centrifuge\nprofile: {rest_between_s: {d}}\n",
                           ["--platform", "P1", "--run", "run1"], [], 60, 3000),
}
PEAK = ("import resource, sys\nfrom platcal.cli import main\nrc = main(sys.argv[1:])\n"
        "u = resource.getrusage(resource.RUSAGE_SELF)\nprint(rc, u.ru_maxrss * 1024, u.ru_utime + u.ru_stime)")


def peak(argv: list[str]) -> tuple[int, float]:
    """Peak resident bytes and CPU seconds of ``platcal argv`` in a fresh process (exit status 0 or 3
    expected)."""
    out = subprocess.run([sys.executable, "-c", PEAK, *argv], capture_output=True, text=True, check=True)
    rc, rss, cpu = out.stdout.split()[-3:]
    if int(rc) not in (0, 3):
        raise SystemExit(f"platcal {' '.join(argv)} exited {rc}: {out.stderr[-400:]}")
    return int(rss), float(cpu)


def estimate(config: Path, argv: list[str]) -> tuple[float, float, float]:
    """``(samples, bytes, CPU seconds)`` the rig's size hook gives for ``platcal argv``."""
    raw = read_yaml(config.read_text())
    rig = rig_of(raw)
    args = build_parser(rig).parse_args(argv)
    sizes = rig.sizes(args.command, rig.load_config(raw), args)
    return sizes[0].samples if sizes else 0.0, sum(s.gigabytes for s in sizes) * 1e9, sum(s.hours for s in sizes) * 3600


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rig", choices=sorted(CASES), action="append")
    ap.add_argument("--scale", type=float, default=1.0, help="multiply the long durations")
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        for rig in a.rig or CASES:
            text, sim, ident, short, long_ = CASES[rig]
            for command in ("simulate", "identify", "inspect", "compensate"):
                pts = []
                for dur in (short, long_ * a.scale):
                    cfg = d / f"{rig}_{dur:g}.yaml"
                    cfg.write_text(text.replace("{d}", f"{dur:g}"))
                    rec = d / f"{rig}_{dur:g}.csv"
                    argv = {"simulate": ["simulate", "--config", str(cfg), *sim, "--out", str(rec)],
                            "identify": ["identify", "--config", str(cfg), *ident, "--data", str(rec),
                                         "--out", str(d / f"id_{dur:g}")],
                            "inspect": ["inspect", "--config", str(cfg), "--data", str(rec)],
                            "compensate": ["compensate", "--calibration", str(d / f"id_{dur:g}" / "calibration.yaml"),
                                           "--data", str(rec), "--out", str(d / "comp.csv")]}[command]
                    samples, est, est_s = estimate(cfg, argv)
                    if dur == short:   # a first run compiles numba's cache: not the data's cost
                        peak(argv + ["--max-memory-gb", "1000", "--max-hours", "1000"])
                    pts.append((samples, est, est_s, *peak(argv + ["--max-memory-gb", "1000", "--max-hours", "1000"])))
                (n0, e0, s0, p0, c0), (n1, e1, s1, p1, c1) = pts
                row = {"rig": rig, "command": command, "samples": [n0, n1], "peak_MB": [p0 / 1e6, p1 / 1e6],
                       "cpu_s": [c0, c1], "measured_B_per_sample": (p1 - p0) / (n1 - n0),
                       "estimated_B_per_sample": e1 / n1, "measured_cpu_s_per_sample": (c1 - c0) / (n1 - n0),
                       "estimated_cpu_s_per_sample": s1 / n1}
                rows.append(row)
                print(json.dumps(row), flush=True)
        if "centrifuge" in (a.rig or CASES):   # the design search: CPU per candidate position-second
            cfg = d / "design.yaml"
            cfg.write_text(CASES["centrifuge"][0].replace("{d}", "60"))
            pts = []
            for gens in (1, 1, 4):   # (the first run compiles numba's cache)
                argv = ["design", "--config", str(cfg), "--population", "8", "--generations", str(gens),
                        "--seed", "0", "--out", str(d / "design.yaml.out.yaml")]
                samples, est, est_s = estimate(cfg, argv)
                pts.append((samples, est_s, *peak(argv + ["--max-memory-gb", "1000", "--max-hours", "1000"])))
            (n0, s0, p0, c0), (n1, s1, p1, c1) = pts[1:]
            row = {"rig": "centrifuge", "command": "design", "samples": [n0, n1], "peak_MB": [p0 / 1e6, p1 / 1e6],
                   "cpu_s": [c0, c1], "measured_B_per_sample": (p1 - p0) / (n1 - n0), "estimated_B_per_sample": 0.0,
                   "measured_cpu_s_per_sample": (c1 - c0) / (n1 - n0), "estimated_cpu_s_per_sample": s1 / n1}
            rows.append(row)
            print(json.dumps(row), flush=True)
    for r in rows:
        print(f"{r['rig']:20s} {r['command']:9s} measured {r['measured_B_per_sample']:7.1f} B/sample, "
              f"estimated {r['estimated_B_per_sample']:7.1f} B/sample; measured {r['measured_cpu_s_per_sample']:.3g} "
              f"CPU s/sample, estimated {r['estimated_cpu_s_per_sample']:.3g} CPU s/sample "
              "(a sample of inspect, compensate: a byte of the record file; of design: a candidate position-second)")


if __name__ == "__main__":
    main()
