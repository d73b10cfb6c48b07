"""The tests' short centrifuge study as YAML text: the spec's defaults with three Table-1 positions
of 4 s each (scheme ``short``; docs/centrifuge-model.md §11), and section replacement for the
bad-input cases."""

SHORT_POSITIONS = [[45, 0, 167], [350, 0, 325], [209, 0, 182]]
"""The scheme's positions (alpha, beta, gamma in deg): the first three of Table 1."""


def short_config(passes: int = 1, extra: str = "") -> str:
    """The study with ``filter.passes = passes``, and the top-level sections ``extra`` appended."""
    return f"""
site: {{latitude_deg: 28.2}}
centrifuge: {{rate_deg_s: 180, g_level: 10}}
noise: {{sigma_a_ug: 10, arw_deg_rth: 0.001, sigma_set_arcsec: 10}}
filter: {{period_ms: 20, passes: {passes}}}
{extra}schemes:
  short: {{dwell_s: 4, positions: {SHORT_POSITIONS}}}
"""


def with_sections(base: str, text: str) -> str:
    """``base`` with its top-level sections named in ``text`` removed and ``text`` appended."""
    keys = {line.split(":")[0] for line in text.splitlines() if line and not line.startswith(" ")}
    out, skip = [], False
    for line in base.splitlines():
        if line and not line.startswith(" "):
            skip = line.split(":")[0] in keys
        if not skip:
            out.append(line)
    return "\n".join(out) + "\n" + text + "\n"
