#!/usr/bin/env bash
# The engine's speed figures on one quiet machine, in one call (about 7 minutes), from the
# repository root:  OUT=/some/dir bash scripts/engine_check.sh
# "2 cores" sections run under `taskset -c 0,1`; the others use every core. JSON goes to $OUT
# (e2e.json, busy.json, sweep.json, sweep16.json), the log to stdout. Every section is
# time-boxed, and a failing one does not stop the next.
#   1. cold first runs, 2 cores: the compile helper on / off, and a build without calls by address
#      (the passes compiled into the driver, no helper), Ob1 bootstrap and Ob5 MPF
#   2. end to end, 12 steps at N_p = 10^6, 1 vs 2 threads on 2 cores
#   3. default threads vs 1 thread with 2 x (cores) busy processes, 2 cores
#   4. a 45-second sweep on 1 and 2 workers (2 cores), then on 1, 2 and 16 workers
set -u
OUT=${OUT:-$PWD/engine-out}
mkdir -p "$OUT"
export PYTHONPATH=$PWD MPLBACKEND=Agg
PY=${PYTHON:-python3}
TWO="taskset -c 0,1"
t0=$(date +%s)
log() { echo "== $* ($(( $(date +%s) - t0 )) s)"; }
fresh() { export PFBENCH_CACHE_DIR=$(mktemp -d) NUMBA_CACHE_DIR=$(mktemp -d); }

log machine
nproc; $PY -c "import numba, numpy; print('numba', numba.__version__, 'numpy', numpy.__version__)"
# a variant of the package beside the checkout: the passes compiled into the driver (no calls by
# address, so no helper)
variant() {
  rm -rf "/tmp/$1"; mkdir -p "/tmp/$1"; cp -r pfbench "/tmp/$1/"; rm -f "/tmp/$1/pfbench/reproductions"
}
variant inline
sed -i -e 's/_call_a(_pass_a, settings.pass_a, /_pass_a(/' -e 's/_call_b(_pass_b, settings.pass_b, /_pass_b(/' \
  -e 's/_call_c(_merge_gather, settings.merge, /_merge_gather(/' /tmp/inline/pfbench/backends/numba_particle.py
sed -i 's/^            found = native_addresses(model, "particle", .*$/            found = [0, 0, 0]/; /^                                     f_tiles=column_major_tiles(model))$/d' \
  /tmp/inline/pfbench/backends/numba_backend.py
grep -c "_pass_a(p, brngs" /tmp/inline/pfbench/backends/numba_particle.py
grep -c "found = \[0, 0, 0\]" /tmp/inline/pfbench/backends/numba_backend.py

cold() {  # label PYTHONPATH helper(0/1) method model
  fresh
  local s e
  s=$(date +%s.%N)
  PYTHONPATH=$2 PFBENCH_COMPILE_HELPER=$3 timeout 120 $TWO $PY -m pfbench run --model "$5" --method "$4" \
    --steps 100 --particles 1000 --json > /dev/null 2> "$OUT/cold.err" || { echo "cold $1 failed"; tail -3 "$OUT/cold.err"; }
  e=$(date +%s.%N)
  $PY -c "print('cold', '$1', '$4', '$5', round($e - $s, 2), 's')"
}
log "1. cold first runs, 2 cores (alternating)"
for round in 1 2; do
  cold helper "$PWD" 1 bootstrap ob1
  cold one-process "$PWD" 0 bootstrap ob1
  cold inline /tmp/inline 0 bootstrap ob1
  cold helper "$PWD" 1 mpf ob5
  cold one-process "$PWD" 0 mpf ob5
done

fresh
log "2. end to end, N_p = 10^6, 12 steps, 1 vs 2 threads, 2 cores"
timeout 120 $TWO $PY -c "
import json, sys
from pfbench.bench import scaling
r = scaling.end_to_end(rounds=11)
print(scaling.end_to_end_text(r))
json.dump(r, open(sys.argv[1], 'w'))" "$OUT/e2e.json"

log "3. busy machine, 2 cores"
timeout 150 $TWO $PY -m pfbench bench --busy --out "$OUT/bench.json" | tail -8

log "4. sweep, 2 cores: 1 and 2 workers"
timeout 200 $TWO $PY -m pfbench bench --sweep --sweep-workers 1,2 --sweep-seconds 45 --repeats 1 --out "$OUT/bench.json" | tail -8
log "4. sweep, all cores: 1, 2 and 16 workers"
mkdir -p "$OUT/all"
timeout 150 $PY -m pfbench bench --sweep --sweep-workers 1,2,16 --sweep-seconds 45 --repeats 1 --out "$OUT/all/bench.json" | tail -8
cp "$OUT/all/sweep.json" "$OUT/sweep16.json" 2>/dev/null
log "done"
