"""numba's ``inline="always"`` without its two deep copies of the callee's fresh IR (issue 22 item 4).

A patch of numba's internals, for the numba versions in :data:`TESTED` only (any other version is
left alone: the kernels compile as numba ships them, just more slowly).

Why: numba inlines an ``inline="always"`` callee at every call site by running the callee's
untyped passes afresh (``InlineWorker.inline_function``) and handing that new IR to
``InlineWorker.inline_ir``, which deep-copies it block by block, because the IR "gets mutated",
then deep-copies the copy, to return an unmutated one. ``inline_function`` built the IR for this
call alone and nobody else holds it, and numba's only caller of ``inline_function``
(``InlineInlinables``) discards the returned copy; yet each block's copy also copies the callee's
whole variable scope, so the copies grow with blocks x variables, at every level of nested inlining
(a callee's own inlined callees are copied again with it). In the rigs' cold compile (each rig's
``warm_kernels``, fresh numba cache) those copies were most of the time numba spent inlining
(benchmarks/results_issue22_inline.txt). Known upstream: numba/numba#8989; NVIDIA/numba-cuda#689
makes the same change in numba-cuda's copy of this code.

What: ``inline_function`` calls numba's own ``inline_ir`` source with its two ``copy_ir`` calls
removed (rebuilt from numba's installed source, compiled in numba's module). The IR that reaches
type inference is the same, hence the same machine code and the same numbers
(``tests/test_numba_inline.py``). ``inline_ir`` itself, which numba's overload inliner calls with
IR it keeps and reuses, is unchanged.
"""

from __future__ import annotations

import inspect
import textwrap

TESTED = ("0.68.1",)
"""numba versions whose ``InlineWorker.inline_ir`` this patch was checked against."""

_COPIES = ("callee_ir = copy_ir(callee_ir)\n", "callee_ir_original = copy_ir(callee_ir)\n")
"""The two statements of numba's ``inline_ir`` that copy the callee's IR (the second's result is
only returned)."""


def fresh_ir_source(source: str) -> str | None:
    """numba's ``inline_ir`` source as ``_inline_fresh_ir``, without its two copies of the callee's
    IR (:data:`_COPIES`); None unless each occurs exactly once as a statement of its body."""
    source = textwrap.dedent(source)
    lines = source.splitlines(keepends=True)
    hits = [[i for i, line in enumerate(lines) if line.strip() + "\n" == stmt] for stmt in _COPIES]
    if any(len(h) != 1 for h in hits) or not source.startswith("def inline_ir("):
        return None
    (copy_at,), (orig_at,) = hits
    indent = lines[copy_at][:len(lines[copy_at]) - len(lines[copy_at].lstrip())]
    lines[copy_at] = indent + "pass  # fresh IR, this call's alone: mutated in place\n"
    indent = lines[orig_at][:len(lines[orig_at]) - len(lines[orig_at].lstrip())]
    lines[orig_at] = indent + "callee_ir_original = None  # InlineInlinables discards it\n"
    return "def _inline_fresh_ir(" + "".join(lines)[len("def inline_ir("):]


def install(numba) -> bool:
    """Patch ``numba``'s ``InlineWorker.inline_function`` as the module docstring says, when
    numba's version is in :data:`TESTED` and its ``inline_ir`` has the expected copies; returns
    whether the patch is in place. Idempotent."""
    # numba's internals imported with numba itself (platcal.jit.load_numba imports it on first use)
    from numba.core import inline_closurecall as icc

    worker = icc.InlineWorker
    if numba.__version__ not in TESTED:
        return False
    if getattr(worker, "_inline_fresh_ir", None) is not None:
        return True
    source = fresh_ir_source(inspect.getsource(worker.inline_ir))
    calls = inspect.getsource(worker.inline_function)
    if source is None or "callee_ir = self.run_untyped_passes(function)" not in calls \
            or "return self.inline_ir(caller_ir, block, i, callee_ir, freevars," not in calls:
        return False
    space: dict = {}
    exec(compile(source, f"<numba {numba.__version__} inline_ir, copies removed>", "exec"), vars(icc), space)
    worker._inline_fresh_ir = space["_inline_fresh_ir"]
    worker.inline_function = _inline_function
    return True


def _inline_function(self, caller_ir, block, i, function, arg_typs=None):
    """numba's ``InlineWorker.inline_function``, the callee's fresh IR inlined without copies."""
    callee_ir = self.run_untyped_passes(function)
    return self._inline_fresh_ir(caller_ir, block, i, callee_ir, function.__code__.co_freevars,
                                 arg_typs=arg_typs)
