"""tracemalloc's peak of a CLI command, for the tests that check memory does not grow with a record."""

import tracemalloc

from platcal.cli import main


def traced_peak(args: list[str]) -> int:
    """The traced peak (bytes) of ``platcal <args>``, run a second time: the first, untraced run
    compiles or loads the kernels, so the peak is the command's, not the compiler's."""
    assert main(args) == 0
    tracemalloc.start()
    try:
        assert main(args) == 0
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
