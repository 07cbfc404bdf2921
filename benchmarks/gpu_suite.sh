#!/usr/bin/env bash
# The benchmarks on a GPU machine, in one run (docs/BENCHMARKS.md, "On a GPU"): the renderer
# core, one case, the paper's study (in this process and on Dask workers), cases per
# second of a sweep, a phase-measuring case (its sequence through each finish), what each
# finish leaves of the fringes, and the renderer comparison's data.
#
# On a bare machine with an NVIDIA driver but without glshade's packages: the wheels in
# .whl/ and libEGL's packages in .gl/ (see the device tool's notes) are installed first.
#     OUT=/tmp/gpu bash benchmarks/gpu_suite.sh
set -uo pipefail
source "$(dirname "$0")/gpu_setup.sh"
step "renderer core: glshade bench (1024², 2048²)"
run 90 python3 -m glshade bench --size 1024 --repeats 9 --reference-rows 32
run 90 python3 -m glshade bench --size 2048 --repeats 5 --reference-rows 16

step "renderer comparison data"
run 90 python3 benchmarks/renderer_compare.py save "$OUT/nvidia.npz"

step "one case: glshade measure (1024², paper's default), three runs"
for i in 1 2 3; do
    /usr/bin/time -f "wall %e s, peak RSS %M KiB" python3 -m glshade measure --json
done

step "the paper's study, 216 cases at 1024², in this process (15 analysis threads)"
run 150 /usr/bin/time -f "wall %e s, cpu %U+%S s, peak RSS %M KiB" \
    python3 -m glshade paper --workers 0 --threads 15 --out /tmp/study_inproc --no-progress
cp /tmp/study_inproc/results.csv "$OUT/paper_results_gpu.csv"

step "a phase-measuring case (1024²), its sequence through each finish"
run 150 python3 benchmarks/pmd_case.py --size 1024 --repeats 3

step "what each finish leaves of the fringes (512²)"
run 120 python3 benchmarks/finish_modulation.py --size 512

step "the paper's study on 8 Dask worker processes sharing the GPU"
run 120 /usr/bin/time -f "wall %e s, peak RSS %M KiB" \
    python3 -m glshade paper --workers 8 --out /tmp/study_dask --no-progress

step "cases per second: the study as a sweep (256²)"
run 150 python3 benchmarks/sweep_throughput.py --size 256 --workers 8
echo; echo "== done"
