"""LLVM code-generation settings for everything pfbench compiles.

``keep_selects`` turns off LLVM's x86 "cmov converter", which rewrites a conditional move inside a
loop into a branch when the move sits on a loop-carried chain, assuming the branch is predictable.
In the particle kernels the conditions are data: the running maximum over the resampling marks
(:func:`pfbench.backends.numba_resampling.merge_gather`) would become one branch per particle that
mispredicts about as often as an ancestor changes.

The setting is an LLVM command-line option, so it holds for the whole process: every function
numba compiles after pfbench's backends are loaded, pfbench's or not. It changes how a select is
emitted, never what it computes, so results are bit-for-bit the same (the backend-agreement tests
run with it). An LLVM that does not know the option ignores it.
"""
from __future__ import annotations

_DONE = False


def keep_selects() -> None:
    """Turn LLVM's x86 cmov-to-branch conversion off for this process (idempotent)."""
    global _DONE
    if _DONE:
        return
    import llvmlite.binding as llvm

    llvm.set_option("pfbench", "-x86-cmov-converter=false")
    _DONE = True
