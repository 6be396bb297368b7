"""Calling a compiled function through its address, so that the caller does not compile it again.

numba links the LLVM code of every jitted function a jitted caller calls into the caller's own
module, then optimises and emits the whole module again: the particle kernel's driver would
recompile pass A, the model inlined. :func:`caller` gives an intrinsic that calls an already
compiled function through the address of its native entry point instead, with numba's own calling
convention (the callee's exceptions reach the caller as through a direct call), and
:func:`entry_address` gives that address. The address is an ordinary run-time argument, so the
caller's machine code stays disk-cacheable; a call costs one indirect call.

The host compiles the callee for exactly the argument types of the call site and passes its
address (:func:`entry_address` registers those types); the call site, when it is compiled,
refuses argument types that the host did not register (a ``TypingError``), so a host that
computes them differently from the call site fails at compile time instead of calling code
compiled for other types. A host may also :func:`declare` the signature first and compile the
call site before the callee (the callee compiled in another process meanwhile).

Use: ``call17 = caller(17)`` at module level, then ``call17(f, address, a_1, ..., a_17)`` in
compiled code.
"""
from __future__ import annotations

import threading

from numba.core import cgutils, types
from numba.core.errors import TypingError
from numba.extending import intrinsic

_LOCK = threading.Lock()
#: (dispatcher, argument types) -> native entry address
_ADDRESSES: dict[tuple[object, tuple], int] = {}
#: dispatcher -> {argument types the host registered for it: the return type}
_REGISTERED: dict[object, dict[tuple, object]] = {}


def declare(dispatcher, argtypes: tuple, restype) -> None:
    """Register ``argtypes`` (numba types) as a signature a call site may use, returning ``restype``,
    before ``dispatcher`` is compiled for it: a call site can then be compiled while the callee is
    compiled elsewhere (:mod:`pfbench.backends.compile_helper`). :func:`entry_address` checks the
    compiled return type against ``restype``."""
    with _LOCK:
        _REGISTERED.setdefault(dispatcher, {})[tuple(argtypes)] = restype


def entry_address(dispatcher, argtypes: tuple) -> int:
    """Compile (or load from the disk cache) ``dispatcher`` for ``argtypes`` (numba types) and return
    the address of its native entry point, for a :func:`caller`; registers ``argtypes`` as a
    signature a call site may use. A return type other than the one :func:`declare` registered is
    a TypeError (a call site compiled for it would misread the result)."""
    argtypes = tuple(argtypes)
    key = (dispatcher, argtypes)
    with _LOCK:
        if key not in _ADDRESSES:
            dispatcher.compile(argtypes)
            cres = dispatcher.overloads[argtypes]
            restype = cres.signature.return_type
            declared = _REGISTERED.setdefault(dispatcher, {}).setdefault(argtypes, restype)
            if declared != restype:
                raise TypeError(f"{dispatcher.py_func.__qualname__} returns {restype}, declared {declared}")
            _ADDRESSES[key] = cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name)
        return _ADDRESSES[key]


def _typed(callee, address, argtypes: tuple):
    """Signature and code generation of a call of ``callee`` (a Dispatcher type) with ``argtypes``
    through ``address``; None (no match) for other argument kinds."""
    if not isinstance(callee, types.Dispatcher) or not isinstance(address, types.Integer):
        return None
    restype = _REGISTERED.get(callee.dispatcher, {}).get(argtypes)
    if restype is None:
        raise TypingError(f"native call of {callee.dispatcher.py_func.__qualname__} with argument types "
                          f"{argtypes} that the host did not compile (entry_address) or declare")

    def codegen(context, builder, signature, llargs):
        fnty = context.call_conv.get_function_type(restype, argtypes)
        fnptr = builder.inttoptr(llargs[1], fnty.as_pointer())
        status, result = context.call_conv.call_function(builder, fnptr, restype, argtypes, llargs[2:])
        with cgutils.if_unlikely(builder, status.is_error):
            context.call_conv.return_status_propagate(builder, status)
        return result

    return restype(callee, address, *argtypes), codegen


_CALLERS: dict[int, object] = {}


def caller(n_args: int):
    """The intrinsic ``call(callee, address, a_1, ..., a_n)``: ``callee(a_1, ..., a_n)`` through
    ``address`` (:func:`entry_address` of ``callee`` for these argument types). ``callee`` is the
    jitted function itself, which gives the call its types; it is not compiled into the caller.
    One intrinsic per number of arguments: the arguments pass straight through (a ``*args`` tuple
    would take and drop a reference to every array at each call)."""
    with _LOCK:
        if n_args not in _CALLERS:
            names = ", ".join(f"a{i}" for i in range(n_args))
            ns = {"_typed": _typed}
            exec(f"def call(typingctx, callee, address, {names}):\n"
                 f"    return _typed(callee, address, ({names}{',' if n_args == 1 else ''}))\n", ns)
            _CALLERS[n_args] = intrinsic(ns["call"])
        return _CALLERS[n_args]
