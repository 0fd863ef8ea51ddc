#!/usr/bin/env bash
# The GPU check (docs/benchmarks.md, 'GPU check'), prepared for a machine with one GPU. First the step itself,
# with no data needed (issue 35): operations per training step of gpu-short, eager and compiled
# (benchmarks/train_ops.py), and steps/s on a fixed batch of 64 and of 256 both ways (benchmarks/step_speed.py).
# Then, when stores are given (issue 28): gpu-short trained on a carried stage-1 feature store, and 30 steps of
# the base preset on a carried base-sized store, printing steps/s and peak GPU memory for each. From the
# repository root:
#
#   bash benchmarks/gpu_check.sh OUT_DIR [GPU_SHORT_STORE.tar.xz BASE_STORE.tar.xz [GPU_SHORT_STEPS]]
#
# Preparing the two stores here (CPU), small enough to travel (64 MiB in all, xz shrinks stores about 5x):
#   langtraj features build --config configs/gpu-short.yaml CORPUS/shards --out stores/gpu-short --workers 2
#   langtraj features build --config configs/base.yaml SOME_SHARDS --out stores/base --workers 2
#   tar -C stores -cJf gpu-short.tar.xz gpu-short; tar -C stores -cJf base.tar.xz base
# Packages the GPU machine may lack (shapely, google-crc32c, zstandard) go in .whl/ as cp312 wheels
# (see the device README); they are installed when that folder exists. GPU_CHECK_DEVICE=cpu runs the same
# chain on the CPU at small batches (how the script itself is tried), GPU_CHECK_BASE_STEPS the base steps (30),
# GPU_CHECK_STEP_STEPS the timed steps per setting of the step check (30).
set -euo pipefail
if [ $# -ne 1 ] && [ $# -lt 3 ]; then
  echo "usage: bash benchmarks/gpu_check.sh OUT_DIR [GPU_SHORT_STORE.tar.xz BASE_STORE.tar.xz [GPU_SHORT_STEPS]]" >&2
  exit 2
fi
out=$1 short_tar=${2:-} base_tar=${3:-} steps=${4:-4000}
device=${GPU_CHECK_DEVICE:-gpu}
python=${PYTHON:-python3}
if [ -d .whl ]; then
  "$python" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
  export PYTHONPATH=/tmp/site${PYTHONPATH:+:$PYTHONPATH}
fi
export PYTHONPATH=src${PYTHONPATH:+:$PYTHONPATH} PYTHONUNBUFFERED=1 HF_HUB_OFFLINE=1
mkdir -p "$out"
if [ "$device" = cpu ]; then
  torch_device=cpu batches="2 4" ops_batch=2
else
  torch_device=cuda batches="64 256" ops_batch=64
fi
for mode in --no-compile --compile; do
  "$python" benchmarks/train_ops.py --config configs/gpu-short.yaml --device "$torch_device" --batch "$ops_batch" \
    $mode | tee "$out/train_ops_${mode#--}.txt"
done
"$python" benchmarks/step_speed.py --config configs/gpu-short.yaml --device "$torch_device" --batches $batches \
  --steps "${GPU_CHECK_STEP_STEPS:-30}" --json "$out/step_speed.json"
if [ -z "$short_tar" ]; then
  exit 0
fi
stores=$(mktemp -d)
tar -xJf "$short_tar" -C "$stores"
tar -xJf "$base_tar" -C "$stores"
short_store=$(dirname "$(find "$stores" -name store.json -path '*gpu-short*' | head -1)")
base_store=$(dirname "$(find "$stores" -name store.json -path '*base*' | head -1)")
runs=$(mktemp -d)  # checkpoints stay on the machine; only the figures go to OUT_DIR
"$python" - "$short_store" "$base_store" "$out" "$steps" "$device" "$runs" "${GPU_CHECK_BASE_STEPS:-30}" <<'EOF'
"""Each run: a preset's training through `langtraj.training.run.train`, timed, with the GPU's peak memory."""
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import torch

from langtraj.training.config import load_config
from langtraj.training.run import train

short_store, base_store, out, steps, device, runs, base_steps = sys.argv[1:8]
cpu = device == "cpu"
results = {}
for name, preset, store, max_steps in (
    ("gpu-short", "configs/gpu-short.yaml", short_store, int(steps)),
    ("base", "configs/base.yaml", base_store, int(base_steps)),
):
    config = load_config(preset)
    config = replace(config, val=replace(config.val, wosac_scenes=0), checkpoint_every_steps=max(max_steps // 4, 1))
    if cpu:
        config = replace(config, accelerator="cpu", devices=1, precision="32-true", num_workers=0, batch_size=2)
    if torch.cuda.is_available():
        torch.cuda.reset_peak_memory_stats()
    start = time.perf_counter()
    last = train(config, store, Path(runs) / name, max_steps=max_steps, progress=False)
    seconds = time.perf_counter() - start
    peak = torch.cuda.max_memory_allocated() / 2**30 if torch.cuda.is_available() else None
    results[name] = {"steps": max_steps, "seconds": seconds, "steps_per_s": max_steps / seconds,
                     "peak_gib": peak, "checkpoint": str(last), "device": torch.cuda.get_device_name() if
                     torch.cuda.is_available() else "cpu"}  # fmt: skip
    memory = "no GPU" if peak is None else f"peak GPU memory {peak:.2f} GiB"
    print(f"{name}: {max_steps} steps in {seconds:.0f} s ({max_steps / seconds:.2f} steps/s, startup included), {memory}")
(Path(out) / "gpu_check.json").write_text(json.dumps(results, indent=2))
EOF
