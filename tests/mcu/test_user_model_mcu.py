"""A user's model from the README, named with `pfbench --models FILE.py`, runs on the emulated
Cortex-M4 through its own compiled code (`pfbench mcu emulate --model NAME`)."""
import json
import os
import subprocess
import sys

import pytest

from pfbench.mcu import toolchain

pytestmark = pytest.mark.mcu_tools


def test_readme_model_emulates_through_its_own_code(readme_model_file):
    why = toolchain.missing()
    if why:
        pytest.skip("Cortex-M4 toolchain/emulator missing: " + "; ".join(why))
    path = readme_model_file("user_growth_mcu")
    r = subprocess.run([sys.executable, "-m", "pfbench.cli", "--models", str(path), "mcu", "emulate",
                        "--model", "user_growth_mcu", "--configs", "4x32,8x32,4x64", "--json"],
                       capture_output=True, text=True, timeout=600, env=dict(os.environ, MPLBACKEND="Agg"))
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["model"] == "user_growth_mcu" and d["precision"] == "float"
    # the harness on the target and the same filter in float64 NumPy fed the target's random
    # numbers agree to float32 rounding (a relative 1e-6 measured; 1e-3 leaves room for an
    # occasional resampling tie flipped by rounding): the target ran THIS model's code
    assert d["tracking"]["crn_rel_diff"] < 1e-3
    # float literals compiled as float32: per-particle work is not soft-float double
    assert d["double_share"] < 0.05
    assert d["cycles_per_particle_step"] > 0
