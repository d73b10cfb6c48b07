"""The lanes kernels are compiled with LLVM's SLP vectoriser on (:func:`platcal.estimation.lanes.slp_vectorize`),
whatever the process did before: numba rereads its ``NUMBA_*`` settings at a compile whenever the
environment changed since its last reading, which had put SLP back off for the first compile
inside the block (a process that imported numba before platcal, or set a ``NUMBA_*`` variable)."""

import json
import os
import subprocess
import sys
import textwrap

CHILD = textwrap.dedent("""
    import json
    import os
    import numba  # before platcal: platcal then sets NUMBA_CACHE_LOCATOR_CLASSES
    import numba.core.codegen as codegen
    import numpy as np
    from platcal.estimation.lanes import NoAliasCompiler, slp_vectorize

    os.environ["NUMBA_PLATCAL_TEST_CHANGED"] = "1"  # and one more change of the environment
    seen = []
    real = codegen.create_pass_builder

    def spy(*args, **kwargs):
        seen.append((int(kwargs.get("opt", 0)), bool(kwargs.get("slp_vectorize"))))
        return real(*args, **kwargs)

    codegen.create_pass_builder = spy

    def lanes(a, b, c):
        for l in range(4):
            a[l] = b[l] * c[l] + a[l]

    with slp_vectorize():
        kernel = numba.njit(pipeline_class=NoAliasCompiler)(lanes)
        kernel(np.ones(4), np.ones(4), np.ones(4))
    print(json.dumps(sorted(set(seen))))
""")


def test_the_first_compile_in_the_block_has_slp_on():
    out = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True, check=True,
                         env={k: v for k, v in os.environ.items() if k != "NUMBA_SLP_VECTORIZE"})
    seen = json.loads(out.stdout.strip().splitlines()[-1])
    full = [slp for opt, slp in seen if opt > 0]
    assert full and all(full), f"passes (opt level, SLP) at the compile: {seen}"
