"""platcal.numba_inline: numba's inline="always" without deep copies of the callee's fresh IR (issue 22 item 4)."""

import inspect
import json
import os
import subprocess
import sys
from types import SimpleNamespace

import numba
from numba.core import inline_closurecall as icc

from platcal import numba_inline
from platcal.jit import load_numba

# nested inline="always" callees with loops and branches, compiled in a fresh interpreter with
# numba as shipped ("plain") or patched; numba's block copies counted in its inliner's module
PROBE = """
import copy, hashlib, json, sys
import numpy as np
import numba
from numba.core import inline_closurecall as icc
from platcal import numba_inline
copies = [0]
def counted(x, memo=None):
    copies[0] += 1
    return copy.deepcopy(x, memo)
icc.copy = type(copy)("copy_counted")
icc.copy.deepcopy = counted
patched = sys.argv[1] == "patched" and numba_inline.install(numba)

@numba.njit(inline="always")
def leaf(a, i):
    s = 0.0
    for j in range(a.shape[1]):
        s += a[i, j] * a[j, i]
    return s

@numba.njit(inline="always")
def mid(a, out):
    for i in range(a.shape[0]):
        out[i] += leaf(a, i) if out[i] >= 0.0 else -leaf(a, i)

@numba.njit
def top(a, out):
    mid(a, out)
    mid(a, out)
    return out.sum()

a = np.arange(25.0).reshape(5, 5) / 7.0
out = np.array([0.0, -1.0, 2.0, -3.0, 4.0])
r = top(a, out)
asm = top.inspect_asm(top.signatures[0])
print(json.dumps({"patched": patched, "copies": copies[0], "asm": hashlib.sha256(asm.encode()).hexdigest(),
                  "r": r.hex(), "out": out.tobytes().hex()}))
"""


def _probe(mode):
    # one string-hash seed for both: numba orders some of a kernel's entry code by it
    run = subprocess.run([sys.executable, "-c", PROBE, mode], capture_output=True, text=True,
                         env=dict(os.environ, PYTHONHASHSEED="0"))
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout)


def test_same_machine_code_and_numbers_without_the_copies():
    plain, patched = _probe("plain"), _probe("patched")
    assert not plain["patched"] and patched["patched"] == (numba.__version__ in numba_inline.TESTED)
    if patched["patched"]:
        assert plain["copies"] > 0 and patched["copies"] == 0
    for key in ("asm", "r", "out"):
        assert plain[key] == patched[key], key


def test_load_numba_installs_the_patch_on_a_tested_numba():
    load_numba()
    installed = icc.InlineWorker.inline_function is numba_inline._inline_function
    assert installed == (numba.__version__ in numba_inline.TESTED)


def test_fresh_ir_source_drops_exactly_the_two_copies():
    source = inspect.getsource(icc.InlineWorker.inline_ir)
    fresh = numba_inline.fresh_ir_source(source)
    if numba.__version__ not in numba_inline.TESTED:
        return
    old, new = source.splitlines(), fresh.splitlines()
    changed = [(a.strip(), b.strip()) for a, b in zip(old, new) if a.strip() != b.strip()]
    assert len(old) == len(new) and len(changed) == 3, changed
    assert [a for a, _ in changed] == ["def inline_ir(self, caller_ir, block, i, callee_ir, callee_freevars,",
                                       "callee_ir = copy_ir(callee_ir)",
                                       "callee_ir_original = copy_ir(callee_ir)"]


def test_other_numba_left_alone():
    # an untested version, or an inline_ir without the expected copies: numba as shipped
    assert not numba_inline.install(SimpleNamespace(__version__="0.0.0"))
    assert numba_inline.fresh_ir_source("def inline_ir(self):\n    return 1\n") is None
    twice = "def inline_ir(self):\n" + "    callee_ir = copy_ir(callee_ir)\n" * 2 + \
        "    callee_ir_original = copy_ir(callee_ir)\n"
    assert numba_inline.fresh_ir_source(twice) is None
