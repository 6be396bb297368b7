#!/usr/bin/env bash
# GPU checks of `--backend cupy`, from the repository root on a machine with a CUDA GPU and CuPy:
#   OUT=/some/dir bash scripts/gpu_check.sh        (about 5-6 minutes; gpu.json goes to $OUT)
# Sections: the GPU, the GPU tests, one `pfbench run --backend cupy`, then scripts/gpu_bench.py
# (fused steps, copy bandwidth, Ob1 bootstrap ns per particle-step, numba on all cores, 10^9).
# Every section is time-boxed and a failure does not stop the next one.
set -u
OUT=${OUT:-$PWD/gpu-out}
mkdir -p "$OUT"
export PYTHONPATH=$PWD MPLBACKEND=Agg
export NUMBA_CACHE_DIR=${NUMBA_CACHE_DIR:-${TMPDIR:-/tmp}/pfbench-numba}
PY=${PYTHON:-python3}
t0=$(date +%s)
echo "== GPU"
nvidia-smi -L || echo "nvidia-smi failed"
$PY -c "import cupy, numpy; print('cupy', cupy.__version__, 'numpy', numpy.__version__)" || echo "no cupy"
echo "== GPU tests ($(( $(date +%s) - t0 )) s)"
timeout 170 $PY -m pytest -q -p no:cacheprovider tests/backends/test_array_backend.py 2>&1 | tail -25
echo "== pfbench run --backend cupy ($(( $(date +%s) - t0 )) s)"
timeout 60 $PY -m pfbench.cli run --model ob1 --backend cupy --particles 1000000 --steps 100 --json
echo
echo "== pfbench info ($(( $(date +%s) - t0 )) s)"
timeout 30 $PY -m pfbench.cli info | grep -iE "cupy|gpu|cores|cpu"
echo "== bench ($(( $(date +%s) - t0 )) s)"
left=$(( 330 - ($(date +%s) - t0) ))
[ "$left" -lt 60 ] && left=60
timeout $(( left + 20 )) $PY scripts/gpu_bench.py --out "$OUT/gpu.json" --budget-s "$left"
echo "== done in $(( $(date +%s) - t0 )) s; $OUT/gpu.json"
