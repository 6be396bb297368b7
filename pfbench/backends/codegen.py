"""Process-wide compile settings, applied once by :func:`pfbench.backends.cache.install` to every
function numba compiles in the process, pfbench's or not. Neither changes what code computes.

``keep_selects`` turns off LLVM's x86 "cmov converter", which turns a conditional move on a
loop-carried chain into a branch, assuming it predictable: the merge's running maximum over the
resampling marks (:func:`pfbench.backends.numba_resampling.merge_gather`) would mispredict about
as often as an ancestor changes. An LLVM that does not know the option ignores it.

``constant_shape_errors``: numba's CPU target formats both shapes of a mismatched array assignment
(f-strings, ``str.join``), unicode code compiled into the first cold kernel whose model assigns a
slice, for a branch only a bug takes; it raises the generic target's ValueError (a constant
message) instead.
"""
from __future__ import annotations


def keep_selects() -> None:
    """Turn LLVM's x86 cmov-to-branch conversion off for this process."""
    import llvmlite.binding as llvm

    llvm.set_option("pfbench", "-x86-cmov-converter=false")


def constant_shape_errors() -> bool:
    """Give numba's CPU target the generic target's constant-message shape error; False where this
    numba has no such pair of overloads (nothing changed)."""
    from numba.core.typing.templates import builtin_registry
    from numba.np import arrayobj

    key = getattr(arrayobj, "raise_with_shape_context", None)
    generic = getattr(arrayobj, "ol_raise_with_shape_context_generic", None)
    cpu = [t for t in builtin_registry.functions if key is not None and generic is not None
           and getattr(t, "key", None) is key and getattr(t, "metadata", {}).get("target") == "CPU"]
    for template in cpu:
        template._overload_func = staticmethod(generic)
    return bool(cpu)
