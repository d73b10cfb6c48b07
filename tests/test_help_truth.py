"""Help that tells the truth (issue 25 item 5): on every rig of the registry, each option of each
command is given a value of every kind its ``--help`` promises, and the parser and the rig must
accept it.

The kinds come from the help itself: a numeric option's range (``platcal.rig.real`` / ``whole``:
its bounds are what the help shows), each of its ``choices``, and "a scheme YAML file", "a scheme
name of the config", "built in". Acceptance is checked without the long work: the command line is
parsed by the rig's own parser, and an option naming a scheme is resolved by the rig's size hook
(``Rig.sizes``, which resolves ``--scheme`` exactly as the command does) on a tiny config.
"""

import argparse

import pytest

from platcal.cli import COMMON, build_parser
from platcal.rig import get_rig, rig_names
from platcal.scheme import Scheme, dump_schemes

TINY = {"centrifuge": "rig: centrifuge\nschemes: {s: {dwell_s: 1, positions: [[0, 0, 0], [90, 0, 0]]}}\n",
        "multiposition": "rig: multiposition\nschemes: {s: {dwell_s: 1, positions: [[0, 0, 0], [90, 0, 0]]}}\n"}
REQUIRED = {"--out": "out", "--data": "rec.csv", "--calibration": "cal.yaml", "--scheme": "s", "--estimator": "x"}


def _subparser(parser: argparse.ArgumentParser, command: str) -> argparse.ArgumentParser:
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[command]


def _promised(action: argparse.Action, tmp_path) -> list[str]:
    """Values of every kind the option's help (and type) promises."""
    text = " ".join((action.help or "").split())
    kind = getattr(action.type, "kind", None)
    values = []
    if kind is not None:   # the range the help shows: its ends and a value inside
        values += ["1"] if "whole" in kind else ["0.5"]
        low = kind.split(">=")[1].split()[0] if ">=" in kind else None
        if low is not None:
            values.append(low)
    if action.choices:
        values += list(action.choices)
    if "YAML file" in text:
        f = tmp_path / "scheme.yaml"
        dump_schemes([Scheme(name="fromfile", positions=((0.0, 0.0, 0.0), (90.0, 0.0, 0.0)), dwell_s=1.0)], f)
        values.append(str(f))
    if "name of the config" in text:
        values.append("s")
    if "built in" in text:
        values.append(text.split("built in (")[1].split(",")[0])
    return values


CASES = [(rig, command) for rig in rig_names() for command in sorted(get_rig(rig).commands)]


@pytest.mark.parametrize("rig,command", CASES)
def test_every_option_accepts_what_its_help_promises(rig, command, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = get_rig(rig)
    cfg_text = TINY.get(rig, f"rig: {rig}\n")
    (tmp_path / "c.yaml").write_text(cfg_text)
    from platcal.io import read_yaml
    cfg = r.load_config(read_yaml(cfg_text))
    parser = _subparser(build_parser(r), command)
    base = ["--config", "c.yaml"] if command != "compensate" else []
    required = {a.option_strings[0]: REQUIRED.get(a.option_strings[0], "x")
                for a in parser._actions if a.required and a.option_strings}
    checked = 0
    for action in parser._actions:
        if not action.option_strings or action.option_strings[0] in ("-h", "--config") or action.nargs == 0:
            continue
        flag = action.option_strings[-1] if action.option_strings[0] == "-v" else action.option_strings[0]
        for value in _promised(action, tmp_path):
            argv = [command, *base, *[x for k, v in required.items() if k != flag for x in (k, v)], flag, value]
            args = build_parser(r).parse_args(argv)   # the parser accepts it (SystemExit otherwise)
            if flag == "--scheme" and r.sizes is not None and command in ("simulate", "identify", "observability"):
                r.sizes(command, cfg, args)   # the rig resolves it as the command does (InputError otherwise)
            checked += 1
    own = [o for o in r.options.get(command, ()) if o.kwargs.get("action") != "store_true"]
    common = [o for o in COMMON.get(command, ()) if o.kwargs.get("action") != "store_true"]
    assert checked >= sum(1 for o in own + common if "type" in o.kwargs or "choices" in o.kwargs)


def test_numeric_options_refuse_what_their_help_excludes():
    """Every option with a range refuses NaN, infinity and text (the other half of the promise)."""
    for rig in rig_names():
        r = get_rig(rig)
        for command in r.commands:
            parser = _subparser(build_parser(r), command)
            for action in parser._actions:
                kind = getattr(action.type, "kind", None)
                if kind is None:
                    continue
                for bad in ("nan", "inf", "text"):
                    with pytest.raises(argparse.ArgumentTypeError):
                        action.type(bad)
                assert kind in " ".join(action.help.split())   # the help states the range
