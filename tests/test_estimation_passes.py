"""Which estimators' runs another's gives on the way (:mod:`platcal.estimation.passes`, issue 22
item 4): the pairing and the snapshots' clocks, on toy runs."""

from itertools import count

from platcal.estimation.passes import pass_prefixes, run_with_takers, takers


def test_the_longest_run_of_the_same_filter_gives_the_shorter_ones():
    passes = {"a1": 1, "a2": 2, "a3": 3, "a3b": 3, "b1": 1, "b2": 2, "c1": 1}
    family = lambda name: name[0]  # noqa: E731
    same = lambda x, y: family(x) == family(y) and x != "b1"  # noqa: E731  (b1's kind hands no snapshots)
    prefixes = pass_prefixes(passes, same)
    assert prefixes == {"a1": ("a3", 1), "a2": ("a3", 2)}   # a3 listed before a3b; b1 runs itself
    assert takers(prefixes) == {"a3": {"a1": 1, "a2": 2}}


def test_a_run_hands_the_takers_their_passes_and_clocks():
    ticks = count()
    clock = lambda: float(next(ticks))  # noqa: E731

    def run(on_pass=None):
        for p in (1, 2, 3):
            if on_pass and p < 3:
                on_pass(p, f"after {p}")
        return "after 3"

    result, spent, taken = run_with_takers(run, {"one": 1, "two": 2, "also_two": 2}, clock)
    assert result == "after 3"
    assert taken == {"one": ("after 1", 1.0), "two": ("after 2", 2.0), "also_two": ("after 2", 3.0)}
    assert spent == 4.0


def test_without_takers_the_run_gets_no_callback():
    calls = []
    result, _, taken = run_with_takers(lambda **kw: calls.append(kw) or "done", {})
    assert result == "done" and taken == {} and calls == [{}]
