"""Shared fixtures."""
import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parent.parent / "README.md"


@pytest.fixture
def readme_model_file(tmp_path):
    """Save the README's "Your own model" class as a user's ``.py`` file under a fresh registry
    name; returns a function ``name -> path``."""
    def write(name: str) -> Path:
        section = README.read_text().split("## Your own model", 1)[1]
        code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
        code = code.split("\nm = ", 1)[0].replace('"my_growth"', f'"{name}"')
        path = tmp_path / f"{name}.py"
        path.write_text(code)
        return path
    return write


#: a user's model with a slip: y = log x + e with x a random walk from 1, so its log-likelihood is NaN
#: for every particle that wandered below 0 (and -inf, a valid zero likelihood, at exactly 0)
LOG_OF_STATE = """
import numpy as np
from pfbench.models import StateSpaceModel, register

@register("{name}")
class LogOfState(StateSpaceModel):
    n_x, n_y, n_noise = 1, 1, 1
    def params(self):
        return (0.5,)
    @staticmethod
    def initial(rng, n, p):
        return rng.normal(1.0, 0.5, (n, 1))
    @staticmethod
    def transition(x, u, t, noise, p):
        return x + p[0] * noise
    @staticmethod
    def log_likelihood(y, x, u, t, p):
        r = y[0] - np.log(x[:, 0])
        return -0.5 * r * r
    @staticmethod
    def observe(x, u, t, noise, p):
        return np.log(np.abs(x)) + noise
"""


@pytest.fixture
def log_of_state_file(tmp_path):
    """:data:`LOG_OF_STATE` saved as a user's ``.py`` file under a fresh registry name; returns a
    function ``name -> path``."""
    def write(name: str) -> Path:
        path = tmp_path / f"{name}.py"
        path.write_text(LOG_OF_STATE.format(name=name))
        return path
    return write


@pytest.fixture
def scripted_end_to_end(monkeypatch):
    """A function running ``pfbench.bench.scaling.run_end_to_end`` over 3 rounds, with run_filter
    calls that take no time and a clock advanced by the scripted seconds: whole runs on 1 thread
    10, 30, 10 and on 2 threads 5, 10, 10; of each, in the kernel (``elapsed_s``) 9, 28, 9 and 4, 7,
    9. Other processes are busy in round 2 only."""

    def run():
        import time as _time
        from types import SimpleNamespace

        from pfbench import filters
        from pfbench.bench import scaling

        clock = [0.0]
        script = {1: [(10.0, 9.0), (30.0, 28.0), (10.0, 9.0)], 2: [(5.0, 4.0), (10.0, 7.0), (10.0, 9.0)]}
        calls = []

        def fake_run(model, y, u, seed=0, n_threads=None, **kw):
            if y.shape[0] == 3:  # the warm-up
                return None
            calls.append(n_threads)
            wall, kernel = script[n_threads][sum(1 for c in calls if c == n_threads) - 1]
            clock[0] += wall
            return SimpleNamespace(elapsed_s=kernel)

        busy = iter([0.0, 0.0, 0.0, 100.0, 100.0, 100.0])  # round 2: others used every core
        monkeypatch.setattr(filters, "run_filter", fake_run)
        monkeypatch.setattr(_time, "perf_counter", lambda: clock[0])
        monkeypatch.setattr(_time, "process_time", lambda: 0.0)
        monkeypatch.setattr(scaling, "_busy_s", lambda: next(busy))
        res = scaling.run_end_to_end(rounds=3, threads=2)
        assert calls == [1, 2] * 3  # the engines alternate
        return res

    return run
