"""Stand-alone check (not a rule): Spearman of J and A against the error of ONE Monte Carlo draw.

docs/centrifuge-model.md §11 reports Spearman(J, actual RMS relative error) = 0.25 over 21 schemes. This
repeats that design (table1 + random_1..20, one replicate per scheme) for 8 draws, and pools
them. Run: python workflow/scripts/centrifuge_design_single_draw_check.py [config/centrifuge.yaml]
"""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
import sys
from dataclasses import replace

import numpy as np
from scipy.stats import spearmanr

from platcal.rigs.centrifuge.design import SchemeEvaluator, design_study_of
from platcal.rigs.centrifuge.design_study import random_schemes
from platcal.io import read_yaml
from platcal.rigs.centrifuge.observability import monte_carlo_errors

cfg = read_yaml(open(sys.argv[1] if len(sys.argv) > 1 else "config/centrifuge.yaml").read())
st = design_study_of(cfg)
schemes = [st.schemes["table1"]] + random_schemes(1, 20, 6, 60.0)
ev = SchemeEvaluator(st, 60.0)
J = np.array([ev.evaluate(s.angles_deg)["J"][0] for s in schemes])
A = np.array([ev.evaluate(s.angles_deg)["A"][0] for s in schemes])
fs = replace(st.filter, history_every_s=None)
R = 8
errs = np.array([monte_carlo_errors(st, s, R, filter_settings=fs)[:, :45] for s in schemes])
rms1 = np.sqrt(((errs / st.truth[:45] * 100) ** 2).mean(axis=2))  # (schemes, draws)
for r in range(R):
    sj = spearmanr(J, rms1[:, r])
    print(f"draw {r}: Spearman J {sj.statistic:.2f} (p {sj.pvalue:.2f}), A {spearmanr(A, rms1[:, r]).statistic:.2f}")
pooled = np.sqrt((rms1**2).mean(axis=1))
print(f"pooled over {R} draws: J {spearmanr(J, pooled).statistic:.2f}, A {spearmanr(A, pooled).statistic:.2f}")
