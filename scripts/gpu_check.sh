#!/usr/bin/env bash
# The GPU check: the renderer through EGL on a GPU driver, which CI (CPU only) cannot run.
#
#   bash scripts/gpu_check.sh OUT_DIR
#
# Needs the package's dependencies importable (pip install -e ., or PYTHONPATH) and an EGL vendor library
# for the GPU (NVIDIA: libEGL_nvidia, found through glvnd's libEGL). Writes into OUT_DIR:
#   platform.txt  the GL renderer and version EGL device 0 gives, and a sample's keys, shapes and timings
#                 through the default path (a render process) and through 2 DataLoader workers;
#   preview.png   `python -m sidar_torch preview` of the misaligned preset (look at it);
#   bench.txt     `python -m benchmarks.bench --parts views` (per view against kornia on the CPU; the
#                 benchmark renders in its own process, and EGL does not survive a fork, so its rows that
#                 fork workers after it rendered cannot run on EGL: render.context refuses them);
#   tests.txt     the render tests on EGL (tests/render: the default path's render process and DataLoader
#                 workers included). The stored digests were recorded on llvmpipe: a GPU rasterises edges,
#                 filters textures and rounds differently, so the tests that compare pixels with llvmpipe's
#                 bytes are expected to fail there, and so are those that open OSMesa itself where it is not
#                 installed (tests.txt lists every failure, one line each); any other failure is a defect of
#                 the EGL path. docs/rendering.md ("On a GPU") says what an H200 gave.
# Each step has its own time limit, so one that hangs leaves the others' files.
set -u
out=${1:?usage: bash scripts/gpu_check.sh OUT_DIR}
mkdir -p "$out"
export PYOPENGL_PLATFORM=egl PYTHONUNBUFFERED=1
python=${PYTHON:-python3}

timeout 120 "$python" - >"$out/platform.txt" 2>&1 <<'EOF'
import time
t0 = time.perf_counter()
import torch
from torch.utils.data import DataLoader
import sidar_torch
from sidar_torch import SidarDataset, load_config

config = load_config("misaligned", image_size=(384, 512))
ds = SidarDataset(config=config, seed=0)
for k in range(3):
    t = time.perf_counter()
    sample = ds.sample(k)
    print(f"sample {k} through the default path: {time.perf_counter() - t:.3f} s")
print({key: tuple(v.shape) for key, v in sample.items() if hasattr(v, "shape")})
print("rasteriser:", ds.renderer().rasteriser())
loader = DataLoader(SidarDataset(config=config, seed=1, length=8), batch_size=4, num_workers=2)
t = time.perf_counter()
batches = [batch["images"].shape for batch in loader]
print(f"2 DataLoader workers, 8 samples: {batches} in {time.perf_counter() - t:.2f} s")
print(f"all: {time.perf_counter() - t0:.1f} s")
EOF
echo "platform: exit $?" >>"$out/platform.txt"

timeout 90 "$python" -m sidar_torch preview --config misaligned --samples 3 --out "$out/preview.png" >"$out/preview.txt" 2>&1
echo "preview: exit $?" >>"$out/preview.txt"

timeout 150 "$python" -m benchmarks.bench --parts views --sizes 24x32 192x256 384x512 768x1024 --samples 24 \
    >"$out/bench.txt" 2>&1
echo "bench: exit $?" >>"$out/bench.txt"

per_test=$("$python" -c "import pytest_timeout" 2>/dev/null && echo "--timeout 120")  # where pytest-timeout is
timeout 180 "$python" -m pytest tests/render -m "not slow" -q -rf --tb=line -p no:cacheprovider -n 12 $per_test \
    >"$out/tests.txt" 2>&1
echo "tests: exit $?" >>"$out/tests.txt"
