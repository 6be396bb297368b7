"""What compiled and stored results are keyed on beyond a model's own file: the user's code its
functions reach (a helper in a neighbour module, a constant imported from one)."""
import json
import os
import subprocess
import sys
import textwrap

from pfbench import sources

MODEL = textwrap.dedent('''
    import numpy as np
    from pfbench.models import StateSpaceModel, register
    from helpers_dep import drift
    from consts_dep import OFFSET

    @register("dep_growth")
    class DepGrowth(StateSpaceModel):
        n_x, n_y, n_noise = 1, 1, 1
        def params(self):
            return (1.0,)
        @staticmethod
        def initial(rng, n, p):
            return rng.normal(0.0, 1.0, (n, 1))
        @staticmethod
        def transition(x, u, t, noise, p):
            return drift(x) + OFFSET + p[0] * noise
        @staticmethod
        def log_likelihood(y, x, u, t, p):
            r = y[0] - x[:, 0]
            return -0.5 * r * r
        @staticmethod
        def observe(x, u, t, noise, p):
            return x + noise
''')
HELPER = textwrap.dedent('''
    from numba.extending import register_jitable

    @register_jitable
    def drift(x):
        return {gain} * x
''')


def _files(folder, gain=0.5, offset=0.0):
    (folder / "dep_model.py").write_text(MODEL)
    (folder / "helpers_dep.py").write_text(HELPER.format(gain=gain))
    (folder / "consts_dep.py").write_text(f"OFFSET = {offset}\n")
    os.utime(folder / "helpers_dep.py", ns=(1, 1 + int(gain * 1e9)))  # a new mtime whatever the clock
    return folder / "dep_model.py"


def _load(path):
    """The model class of ``path``, imported afresh with its neighbours (as a new process would)."""
    from pfbench.models import import_path

    for name in ("helpers_dep", "consts_dep"):
        sys.modules.pop(name, None)
    sys.path.insert(0, str(path.parent))
    try:
        return import_path(f"sources_test_{len(sys.modules)}", str(path)).DepGrowth
    finally:
        sys.path.remove(str(path.parent))


def test_digest_follows_an_imported_helper_and_constant(tmp_path, monkeypatch):
    """Catches a key of the model's own file only: the helper's file and the constant's value change
    the digest; the same code gives the same digest."""
    from pfbench import models

    monkeypatch.setattr(models, "_REGISTRY", dict(models._REGISTRY))  # the test's registrations go after it
    from pfbench.compare.run import _code_fingerprint
    from pfbench.sweep.core import code_fingerprint
    from pfbench.tasks import Task

    keys = []
    for edit in ({}, {"gain": 0.9}, {"gain": 0.9, "offset": 1.0}, {"gain": 0.9, "offset": 1.0}):
        _load(_files(tmp_path, **edit))
        # the model's digest, a sweep's code key and a comparison's (resumed stores are refused on a change)
        keys.append((sources.model_digest(models.model_class("dep_growth")), code_fingerprint("dep_growth"),
                     _code_fingerprint([], [Task("t", "dep_growth", 10)])))
    assert all(len({k[i] for k in keys[:3]}) == 3 for i in range(3)) and keys[2] == keys[3]


def _run(model_file, cache, backend="numba"):
    env = dict(os.environ, PFBENCH_CACHE_DIR=str(cache), PFBENCH_COMPILE_HELPER="0")
    r = subprocess.run([sys.executable, "-m", "pfbench", "--models", str(model_file), "run", "--model", "dep_growth",
                        "--particles", "200", "--steps", "20", "--backend", backend, "--json"], capture_output=True,
                       text=True, env=env, timeout=300, cwd=model_file.parent)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)["loglik"]


def test_numba_cache_is_not_stale_after_an_imported_file_changes(tmp_path):
    """A helper that the model imports from a neighbour file changed: the next numba run recompiles
    and gives the NumPy backend's log-likelihood of the new code (the same draws and arithmetic),
    where it reused the old machine code (the log-likelihood of before the edit). Catches a kernel
    cache that does not follow the user's files a model reaches; that the key follows a constant's
    value too is the digest test's above (the same key)."""
    model = _files(tmp_path)
    before = _run(model, tmp_path / "cache")
    _files(tmp_path, gain=0.9)
    after = _run(model, tmp_path / "cache")
    assert after != before and after == _run(model, tmp_path / "cache", backend="numpy")


def test_a_model_without_a_source_file_is_keyed_on_its_code_the_same_in_every_process():
    """A model class from exec'd code (no file to hash): its key follows the names its code reads
    (np.sin against np.cos) and is the same in processes with other string hash seeds (a frozenset
    constant). Catches a key of the instructions alone, or of a frozenset's seed-dependent order."""
    code = textwrap.dedent('''
        import numpy as np
        from pfbench.models import StateSpaceModel
        from pfbench.sources import model_digest
        class Exec(StateSpaceModel):
            @staticmethod
            def transition(x, u, t, noise, p):
                return np.sin(x) if t in {"a", "b", "c", "d"} else x
        print(model_digest(Exec))
    ''')
    keys = [subprocess.run([sys.executable, "-c", f"exec({src!r})"], capture_output=True, text=True, check=True,
                           env=dict(os.environ, PYTHONHASHSEED=str(seed))).stdout
            for src, seed in ((code, 1), (code, 2), (code.replace("np.sin", "np.cos"), 1))]
    assert keys[0] == keys[1] != keys[2]
