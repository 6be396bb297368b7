"""Time to first result: what a call compiles and imports (no wall-clock assertions).

Cold starts are dominated by numba compiling; these tests pin the structural choices that keep it
small: array-assignment shape errors without the formatted (unicode) message, the CLI importing a
subsystem only when its command runs, and the kernel modules sharing what does not depend on the
scheme or the model.
"""
import subprocess
import sys

import numba
import numpy as np
import pytest

from pfbench.backends import cache
from pfbench.backends.kernels import build


def test_shape_mismatch_raises_value_error_with_the_constant_message():
    # The check stays, its message is the generic target's constant one: no unicode formatting
    # compiled into a cold kernel (pfbench.backends.codegen). Mutations caught: an install() whose
    # patch no longer applies (a numba that renamed the overloads: the formatted message comes
    # back), and a replacement that does not raise.
    @numba.njit(cache=False)
    def assign(dst, src):
        dst[:] = src

    cache.install()
    dst = np.zeros((3, 2))
    assign(dst, np.ones((3, 2)))
    assert np.all(dst == 1.0)
    with pytest.raises(ValueError, match="^cannot assign slice from input of different size$"):
        assign(dst, np.ones((4, 2)))


def test_cli_import_leaves_subsystems_and_pandas_unloaded():
    # `pfbench run` must not pay for pandas (sweep store) or the benchmark code: the subsystem
    # groups are imported when their command is used. Mutation caught: importing them eagerly.
    code = ("import sys, pfbench.cli; "
            "print(sorted(m for m in ('pandas', 'pfbench.sweep', 'pfbench.bench', 'pfbench.mcu.cli') "
            "if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


def test_subsystem_commands_resolve_on_use():
    # Mutation caught: a lazy table whose entries no longer resolve to the subsystem's group.
    import click

    from pfbench.cli import SUBSYSTEMS, main

    ctx = click.Context(main)
    assert set(SUBSYSTEMS) <= set(main.list_commands(ctx))
    for name in SUBSYSTEMS:
        cmd = main.get_command(ctx, name)
        assert cmd is not None and cmd.name == name


def test_kernel_modules_share_what_does_not_depend_on_the_scheme_or_the_model():
    """The schemes of a model share one pass A (the model inlined: 40 % of a cold compile), and
    every model shares passes B and C (ordinary cached modules). Catches a scheme's module that
    compiles its own pass A, and the opposite fault: a pass A shared across models or tile layouts,
    which would run one model's (or layout's) code for another."""
    import pfbench
    from pfbench.backends import numba_resampling, numba_weights

    ob1 = pfbench.models.get("ob1")
    mods = [build("particle", ob1, s) for s in ("systematic", "multinomial", None)]
    assert mods[0]._pass_a is mods[1]._pass_a is mods[2]._pass_a
    assert build("particle", type(ob1), "systematic")._pass_a is not mods[0]._pass_a
    other = build("particle", pfbench.models.get("ob2"), "systematic")
    assert other._pass_a is not mods[0]._pass_a
    assert other._pass_b is mods[0]._pass_b is numba_weights.block_weights
    assert other._merge_gather is mods[0]._merge_gather is numba_resampling.merge_gather


def test_an_index_scheme_run_does_not_compile_the_merge():
    """The particle driver gets the merge (systematic/stratified resampling) by address; a
    multinomial run's kernel never calls it, so the run must not compile it (about 0.9 s of a cold
    start). Run in a fresh process with an empty cache. Catches: the merge always in the driver's
    list of calls."""
    code = ("import json, os, sys, tempfile\n"
            "d = tempfile.mkdtemp(); os.environ['PFBENCH_CACHE_DIR'] = d; os.environ['NUMBA_CACHE_DIR'] = d + '/nb'\n"
            "os.environ['PFBENCH_COMPILE_HELPER'] = '0'\n"
            "from pfbench import models\n"
            "from pfbench.filters import run_filter\n"
            "from pfbench.backends import numba_resampling\n"
            "m = models.get('ob1'); tr = m.simulate(5, seed=1)\n"
            "run_filter(m, tr.y, None, n_particles=50, seed=0, resampling='multinomial', n_threads=1)\n"
            "a = len(numba_resampling.merge_gather.overloads)\n"
            "run_filter(m, tr.y, None, n_particles=50, seed=0, resampling='systematic', n_threads=1)\n"
            "print(json.dumps([a, len(numba_resampling.merge_gather.overloads)]))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().splitlines()[-1] == "[0, 1]"
