#!/usr/bin/env bash
# Posed stations on a GPU machine (docs/BENCHMARKS.md, "On a GPU"): their precision against
# the fp64 oracle and frame time at 1024², both instruments on the overhead and the
# SOFAST-like station, a phase-measuring case's stages, and an uncertainty budget on
# 8 Dask workers.
#     OUT=/tmp/gpu bash benchmarks/gpu_stations.sh
set -uo pipefail
source "$(dirname "$0")/gpu_setup.sh"

step "posed stations against the fp64 oracle (1024², a band of 16 rows)"
run 120 python3 benchmarks/station_precision.py --size 1024 --rows 16

step "one case of each instrument on each posed station (1024²)"
for station in overhead_station sofast_like_station; do
    for method in paper pmd; do
        extra=""
        if [ "$station" = sofast_like_station ] && [ "$method" = paper ]; then
            extra="--emitter stripes --period 1000 --step 25"
        fi
        /usr/bin/time -f "wall %e s" python3 -m glshade measure "examples/$station.toml" \
            --method "$method" --size 1024 $extra --json | cut -c1-240
    done
done

step "a phase-measuring case (1024²), its stages"
run 150 python3 benchmarks/pmd_case.py --size 1024 --repeats 3

if [ -f examples/budget.toml ]; then
    step "an uncertainty budget of the paper's station on 8 Dask workers"
    run 200 /usr/bin/time -f "wall %e s" python3 -m glshade budget examples/budget_station.toml \
        --uncertainty examples/budget.toml --workers 8 --no-progress -o "$OUT/budget"
fi
echo; echo "== done"
