#!/usr/bin/env bash
# The CUDA checks of the batched path on a lent GPU machine (Python 3.12 with torch, numpy, scipy, OpenCV already
# there; doorloc's other run-time wheels carried in .whl/, see /work/.library/device/README.md):
# the batched path's parity on CUDA (tests/vision/test_batched.py) and frames/s of `doorloc batch`
# (bench/bench_throughput.py) on 1, 8 and all cores, one-frame vs batched on CPU and CUDA.
# With BEFORE=<another tree's src/> (carried), first the one-frame figures of bench/bench_speed.py on that
# quiet machine's CPU, this tree against BEFORE in the same run.
# Results: $OUT/throughput.json, $OUT/speed.json and $OUT/device.log. With many workers, give BATCH_SIZE
# small enough for several batches per worker in the steady state (bench_throughput counts from the
# end of the first 2 x workers batches).
set -u -o pipefail
OUT=${OUT:-/tmp/doorloc-device}; mkdir -p "$OUT"
{
  nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader; nproc
  if [ -d .whl ]; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
    export PYTHONPATH=/tmp/site
  fi
  export PYTHONPATH=${PYTHONPATH:+$PYTHONPATH:}$PWD/src OMP_NUM_THREADS=1 PYTHONUNBUFFERED=1
  python3 -c "import cv2, numpy, numba, torch; print('cv2', cv2.__version__, 'numpy', numpy.__version__, 'numba', numba.__version__, 'torch', torch.__version__, torch.cuda.is_available())"
  python3 -m doorloc.vision.warmup  # compile locate's kernels once, before anything is timed
  timeout "${TEST_TIMEOUT:-200}" python3 -m pytest -q -p no:cacheprovider tests/vision/test_batched.py -rs
  if [ -n "${BEFORE:-}" ]; then
    timeout "${SPEED_TIMEOUT:-240}" python3 bench/bench_speed.py --before "$BEFORE" --rounds "${ROUNDS:-3}" \
      --no-throughput --json "$OUT/speed.json"
  fi
  timeout "${BENCH_TIMEOUT:-330}" python3 bench/bench_throughput.py --frames "${FRAMES:-1296}" \
    --workers "${WORKERS:-1,8,all}" --devices none,cpu,cuda --batch-size "${BATCH_SIZE:-32}" \
    --json "$OUT/throughput.json"
} 2>&1 | tee "$OUT/device.log"
