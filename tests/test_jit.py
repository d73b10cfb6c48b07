"""platcal.jit's lazy kernels (issue 22 item 3): when numba is loaded, every loaded platcal module
gets numba's ``prange`` in place of the placeholder, whatever the order of ``sys.modules``."""

import subprocess
import sys

PROBE = """
import sys
import platcal.rigs.centrifuge.simulate, platcal.rigs.centrifuge.ekf, platcal.rigs.centrifuge.ukf
import platcal.jit as j
held = [n for n, m in list(sys.modules.items()) if m is not None and n.startswith('platcal.')
        and vars(m).get('prange') is j._PRANGE]
assert 'platcal.rigs.centrifuge.simulate' in held, held
numba = j.load_numba()
left = [n for n, m in list(sys.modules.items()) if m is not None and n.startswith('platcal.')
        and type(vars(m).get('prange')).__name__ == '_Prange']
assert left == [], left
assert type(j._PRANGE).__name__ == '_Prange' and j.prange is numba.prange
"""


def test_load_numba_replaces_prange_in_every_module():
    # a fresh interpreter: platcal.jit is loaded before the rig's modules (it used to replace its
    # own placeholder first, and every module after it in sys.modules kept the placeholder)
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
