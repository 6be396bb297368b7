"""The compiled kernel is cached on disk: a second process start does not recompile."""
import json
import os
import subprocess
import sys

SCRIPT = """
import json, pfbench
from pfbench.backends.numba_backend import kernel_module
m = pfbench.models.get("ob1"); tr = m.simulate(5, seed=0)
pfbench.run_filter(m, tr.y, method="bootstrap", n_particles=8, backend="numba", seed=0)
st = kernel_module(m).run_group.stats
print(json.dumps({"hits": sum(st.cache_hits.values()), "misses": sum(st.cache_misses.values())}))
"""


def test_second_process_loads_kernel_from_disk(tmp_path):
    env = dict(os.environ, PFBENCH_CACHE_DIR=str(tmp_path / "pf"), NUMBA_CACHE_DIR=str(tmp_path / "nb"))
    runs = []
    for _ in range(2):
        r = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env,
                           timeout=600)
        assert r.returncode == 0, r.stderr
        runs.append(json.loads(r.stdout.strip().splitlines()[-1]))
    assert runs[0]["misses"] >= 1
    assert runs[1]["misses"] == 0 and runs[1]["hits"] >= 1
