# The set-up every GPU benchmark script sources (benchmarks/gpu_suite.sh, gpu_stations.sh):
# on a bare machine with an NVIDIA driver, the wheels in .whl/ and libEGL's packages in .gl/
# are installed first; OUT is where the figures' data go.
OUT=${OUT:-/tmp/gpu_suite}
mkdir -p "$OUT"
if [ -d .gl ]; then for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig; fi
if [ -d .whl ]; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target /tmp/site .whl/*.whl || exit 1
    export PYTHONPATH=/tmp/site:$PWD/src
fi
export PYTHONUNBUFFERED=1 GLSHADE_MEMORY_BUDGET_MB=32768  # a 128 GiB machine: 15 threads, 8 workers
step() { echo; echo "== $*"; }
run() { timeout "$1" "${@:2}" || echo "(step ended with status $?)"; }


step machine
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader
echo "cores: $(nproc)"; python3 --version
if ! python3 -m glshade info; then
    export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
    python3 -m glshade info || exit 1
fi

