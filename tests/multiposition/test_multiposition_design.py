"""A-optimal GA design inside the gimbal range (small, reproducible run)."""

from platcal.io import read_yaml
from platcal.rigs.multiposition import design as de
from platcal.rigs.multiposition.config import load_config

SMALL = read_yaml("rig: multiposition\ngimbal: {beta_max_deg: 20}\n"
                  "design: {grid_deg: 45, population: 8, generations: 3, info_step_s: 5}\n")


def test_ga_small_run_in_range_and_reproducible():
    cfg = load_config(SMALL)
    g = de.grid(cfg)
    assert abs(g[:, 1]).max() <= 20 and len(g) == 8 * 1 * 8
    r1 = de.run_design(cfg, 4)
    r2 = de.run_design(cfg, 4)
    assert r1["scheme"].positions == r2["scheme"].positions
    assert r1["scheme"].n_positions == 4
    rows = de.compare(cfg, [r1["scheme"], cfg.scheme("TET4")])
    assert all(r["A"] > 0 for r in rows)
