#!/usr/bin/env bash
# The engine's speed figures on one quiet multi-core machine, in one call (about 5 minutes), from
# the repository root:  OUT=/some/dir bash scripts/engine_check.sh
# "2 cores" sections run under `taskset -c 0,1`; the others use every core. JSON goes to $OUT
# (end_to_end.json, busy.json, sweep.json: `pfbench bench --document` renders them), the log to
# stdout. Every section is time-boxed, and a failing one does not stop the next. SECTIONS=13 runs sections 1 and 3 only (default: all).
#   1. cold first runs, 2 cores, each on fresh caches: the compile helper on (the default) and off
#      (PFBENCH_COMPILE_HELPER=0), alternating: Ob1 bootstrap, Ob5 MPF, and a new model (the
#      README's, from a user's file)
#   2. end to end, 12 steps at N_p = 10^6, 1 vs 2 threads on 2 cores (then 1 vs all on every core)
#   3. default threads vs 1 thread with 2 x (cores) busy processes, every core
#   4. a 40-second sweep on 1, 2 and all cores' workers
set -u
OUT=${OUT:-$PWD/engine-out}
mkdir -p "$OUT"
export PYTHONPATH=$PWD MPLBACKEND=Agg
PY=${PYTHON:-python3}
TWO="taskset -c 0,1"
ALL=$(nproc)
SECTIONS=${SECTIONS:-1234}
t0=$(date +%s)
log() { echo "== $* ($(( $(date +%s) - t0 )) s)"; }
fresh() { export PFBENCH_CACHE_DIR=$(mktemp -d) NUMBA_CACHE_DIR=$(mktemp -d); }

log machine
echo "cores: $ALL"; lscpu 2>/dev/null | grep -E "^(Model name|Thread\(s\) per core|Core\(s\) per socket|Socket\(s\)|NUMA node\(s\))"
$PY -c "import numba, numpy; print('numba', numba.__version__, 'numpy', numpy.__version__)"

USER_MODEL=$(mktemp -d)/my_growth.py  # the README's "Your own model", as a user saves it
$PY -c "
import re, sys
code = re.search(r'\`\`\`python\n(.*?)\`\`\`', open('README.md').read().split('## Your own model', 1)[1], re.S).group(1)
open(sys.argv[1], 'w').write(code.split('\nm = ', 1)[0])" "$USER_MODEL"

cold() {  # helper(0/1) method model
  fresh
  local s e extra=()
  [[ $3 == my_growth ]] && extra=(--models "$USER_MODEL")
  s=$(date +%s.%N)
  PFBENCH_COMPILE_HELPER=$1 timeout 120 $TWO $PY -m pfbench "${extra[@]}" run --model "$3" --method "$2" \
    --steps 100 --particles 1000 --json > /dev/null 2> "$OUT/cold.err" || { echo "cold $* failed"; tail -3 "$OUT/cold.err"; }
  e=$(date +%s.%N)
  $PY -c "print('cold', 'helper' if '$1' == '1' else 'one-process', '$2', '$3', round($e - $s, 2), 's')"
}
[[ $SECTIONS == *1* ]] && log "1. cold first runs, 2 cores (alternating)" && for round in 1 2; do
  cold 1 bootstrap ob1
  cold 0 bootstrap ob1
  cold 1 mpf ob5
  cold 0 mpf ob5
  cold 1 bootstrap my_growth
  cold 0 bootstrap my_growth
done

fresh  # one cache for the rest: each section compiles what it runs once
[[ $SECTIONS == *2* ]] && log "2. end to end, N_p = 10^6, 12 steps, 1 vs 2 threads, 2 cores" && \
  timeout 120 $TWO $PY -m pfbench bench --end-to-end --out "$OUT/bench.json" | tail -5
[[ $SECTIONS == *2* ]] && log "2b. end to end, N_p = 10^6, 12 steps, 1 vs $ALL threads, every core" && timeout 60 $PY -c "
import sys
from pfbench.bench import scaling
print(scaling.end_to_end_text(scaling.end_to_end(rounds=7, threads=int(sys.argv[1]))))" "$ALL"

[[ $SECTIONS == *3* ]] && log "3. busy machine, all $ALL cores" && timeout 150 $PY -m pfbench bench --busy --out "$OUT/bench.json" | tail -8

[[ $SECTIONS == *4* ]] && log "4. sweep, all cores: 1, 2 and $ALL workers" && timeout 200 $PY -m pfbench bench --sweep --sweep-workers "1,2,$ALL" --sweep-seconds 40 --repeats 1 \
  --out "$OUT/bench.json" | tail -8
rm -f "$OUT/bench.json" "$OUT/cold.err"
log "done"
