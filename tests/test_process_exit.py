"""A process that imports platcal freezes the garbage collector at exit (issue 22 item 4): the
interpreter's collections at exit then skip the million objects numba's target leaves, 0.2-0.3 s
CPU per workflow job; the other exit handlers still run and the outputs are complete."""

import subprocess
import sys

PROBE = """
import atexit, gc, sys
# registered before platcal's: atexit runs handlers last-in first-out, so this one runs after it
atexit.register(lambda: print("frozen", gc.get_freeze_count() > 0, flush=True))
import platcal
out = open(sys.argv[1], "w")
out.write("written")
out.close()
print("body done", gc.get_freeze_count(), flush=True)
"""


def test_the_collector_is_frozen_at_exit_not_before(tmp_path):
    f = tmp_path / "out.txt"
    done = subprocess.run([sys.executable, "-c", PROBE, str(f)], capture_output=True, text=True, check=True)
    assert done.stdout.split("\n")[:2] == ["body done 0", "frozen True"]
    assert f.read_text() == "written"
