"""Time the `particles` library's bootstrap filter on Ob1 ([Embedded] eq. 6), for `pfbench bench`.

Runs in its own environment (.venv-particles, created by `make bench`) because `particles`
pins an older NumPy. Prints one JSON line: {"ns_per_particle_step": ..., "version": ...}.
"""
import argparse
import json
import statistics
import time

import numpy as np
import particles
from particles import distributions as dists
from particles import state_space_models as ssm


class Ob1(ssm.StateSpaceModel):
    """x_k = 0.5x + 25x/(1+x^2) + 8cos(1.2(k-1)) + v, v~N(0,10); y = x^2/20 + n, n~N(0,1)."""

    def PX0(self):
        return dists.Dirac(loc=0.1)

    def PX(self, t, xp):
        return dists.Normal(loc=0.5 * xp + 25 * xp / (1 + xp ** 2) + 8 * np.cos(1.2 * (t - 1)),
                            scale=np.sqrt(10.0))

    def PY(self, t, xp, x):
        return dists.Normal(loc=x ** 2 / 20, scale=1.0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args()
    model = Ob1()
    _, y = model.simulate(a.steps)
    times = []
    for r in range(a.repeats):
        fk = ssm.Bootstrap(ssm=model, data=y)
        alg = particles.SMC(fk=fk, N=a.particles, resampling="systematic", ESSrmin=1.0,
                            store_history=False, collect=None, verbose=False)
        t0 = time.perf_counter()
        alg.run()
        times.append(time.perf_counter() - t0)
    ns = statistics.median(times) * 1e9 / (a.steps * a.particles)
    print(json.dumps({"ns_per_particle_step": ns, "version": getattr(particles, "__version__", "?"),
                      "numpy": np.__version__, "steps": a.steps, "particles": a.particles}))


if __name__ == "__main__":
    main()
