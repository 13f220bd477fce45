#!/usr/bin/env bash
# The VLM on a GPU, in under 8 minutes of machine time (issue 33): the real-size table's runs
# (random weights of the exact Qwen2.5-VL shapes, 640x480, 32 new tokens), the compiled decode
# (compile=auto against off, 3B bf16: target <= 0.30 s a frame p50) and the vlm node's result age
# with the model in its own process (target <= 1.2x inference), each logged and written as JSON.
#
# The GPU machine can fetch nothing, so the script brings its own wheels (bitsandbytes for nf4/int8,
# cyclonedds for the bus). Make the wheel folder here, where PyPI is reachable, then carry it along:
#
#   scripts/gpu_check.sh --prepare              # here: pip download into build/gpu_wheels (~50 MiB)
#   scripts/gpu_check.sh                        # on the GPU machine, from the repository root
#
# With the device tool: run(command="scripts/gpu_check.sh", carry=["build/gpu_wheels"], timeout_s=560)
# (build/ is ignored by git, so it must be named in carry). Results: $OUT (default runs/gpu_check,
# or the device tool's $OUT), one .json and one .log per step, and summary.txt. Steps run in order of
# value and are skipped, with a line saying so, once the budget (BUDGET_S, default 450 s) is spent.
# The machine needs python with torch (CUDA) and transformers; everything else it lacks is reported.
#
# Environment: PYTHON (python3), WHEELS (build/gpu_wheels), OUT, BUDGET_S, GPU_PYTHON_VERSION
# (--prepare: the GPU machine's python, default this python's), BNB_VERSION (0.50.2, the issue's).
set -uo pipefail

cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
WHEELS=${WHEELS:-build/gpu_wheels}
BNB_VERSION=${BNB_VERSION:-0.50.2}

if [[ "${1:-}" == "--prepare" ]]; then
    pyver=${GPU_PYTHON_VERSION:-$("$PY" -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')}
    mkdir -p "$WHEELS"
    # Binary wheels for the GPU machine's python and any manylinux x86_64; no dependencies (torch,
    # numpy and packaging are there already; cyclonedds' CLI extras are not needed).
    "$PY" -m pip download --no-deps --only-binary=:all: --python-version "$pyver" \
        --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \
        --platform manylinux_2_24_x86_64 --platform manylinux_2_28_x86_64 \
        -d "$WHEELS" "bitsandbytes==$BNB_VERSION" "cyclonedds>=11,<12" || exit 1
    echo "wheels for python $pyver in $WHEELS:"
    ls -l "$WHEELS"
    echo "carry $WHEELS to the GPU machine (device tool: carry=[\"$WHEELS\"]) and run scripts/gpu_check.sh there"
    exit 0
fi

OUT=${OUT:-runs/gpu_check}
BUDGET_S=${BUDGET_S:-450}
mkdir -p "$OUT"
START=$(date +%s)
SUMMARY="$OUT/summary.txt"
: >"$SUMMARY"
say() { echo "$*" | tee -a "$SUMMARY"; }

# -- the machine and the wheels ------------------------------------------------------------------
say "gpu_check $(date -u +%FT%TZ) on $(hostname)"
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader 2>&1 | tee -a "$SUMMARY"
SITE=build/gpu_site
if ! "$PY" -c 'import bitsandbytes, cyclonedds' 2>/dev/null; then
    if ls "$WHEELS"/*.whl >/dev/null 2>&1; then
        "$PY" -m pip install --quiet --no-index --no-deps --find-links "$WHEELS" --target "$SITE" \
            bitsandbytes cyclonedds >"$OUT/pip.log" 2>&1 || say "pip install from $WHEELS failed (see pip.log)"
    else
        say "no wheels in $WHEELS: run scripts/gpu_check.sh --prepare where PyPI is reachable and carry $WHEELS"
    fi
fi
export PYTHONPATH="$PWD/src:$PWD/$SITE${PYTHONPATH:+:$PYTHONPATH}"
export PYTORCH_CUDA_ALLOC_CONF=${PYTORCH_CUDA_ALLOC_CONF:-expandable_segments:True}
export GO2VLM_IFACE=lo ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-171}
export XDG_STATE_HOME=${XDG_STATE_HOME:-$(mktemp -d)}
"$PY" - <<'EOF' 2>&1 | tee "$OUT/modules.txt" | tee -a "$SUMMARY"
import importlib
for name in ("torch", "transformers", "bitsandbytes", "cyclonedds", "mujoco"):
    try:
        m = importlib.import_module(name)
        print(f"{name} {getattr(m, '__version__', '?')}")
    except Exception as exc:  # noqa: BLE001
        print(f"{name} MISSING ({type(exc).__name__}: {exc})")
import torch
print("cuda", torch.cuda.is_available(), torch.cuda.get_device_name(0) if torch.cuda.is_available() else "")
EOF
has() { grep -q "^$1 " "$OUT/modules.txt" && ! grep -q "^$1 MISSING" "$OUT/modules.txt"; }

# step NAME MIN_S MAX_S CMD...: run CMD if at least MIN_S of the budget is left, for at most MAX_S
step() {
    local name=$1 min_s=$2 max_s=$3
    shift 3
    local left=$((BUDGET_S - ($(date +%s) - START)))
    if ((left < min_s)); then
        say "SKIP $name: ${left}s of the budget left, it needs ${min_s}s"
        return
    fi
    ((max_s > left)) && max_s=$left
    local t0=$(date +%s)
    timeout --kill-after=10 "$max_s" "$@" >"$OUT/$name.log" 2>&1
    local rc=$?
    say "$name: rc $rc in $(($(date +%s) - t0))s ($*)"
    grep -E "^ *(none|nf4|int8) |inference p50|results|^ *(seed|vlm)_" "$OUT/$name.log" | tail -8 | tee -a "$SUMMARY"
}

BENCH=(benchmarks/bench_vlm.py --random-weights --device cuda --new-tokens 32 --sections latency)
CKPT3B=${GO2VLM_CACHE:-$HOME/.cache/go2vlm}/random-3b-tall-vall

# 1. the compiled decode, the target: 3B bf16 compile=auto (on) then off (the table's row)
step 3b_bf16_compiled 150 220 "$PY" "${BENCH[@]}" --arch 3b --dtype bf16 --quantization none --compile auto \
    --frames 20 --out "$OUT/3b_bf16_compiled.json"
step 3b_bf16_eager 45 90 "$PY" "${BENCH[@]}" --arch 3b --dtype bf16 --quantization none --compile off \
    --frames 20 --out "$OUT/3b_bf16_eager.json"
# 2. the node's result age, the model in its own process, a camera at 10 Hz in the node's process
if has cyclonedds; then
    step node_age_3b_bf16 60 100 "$PY" benchmarks/bench_vlm_node.py --graph camera --backend transformers \
        --model "$CKPT3B" --param dtype=bf16 --param max_new_tokens=32 --cases alone,process,inproc \
        --frames 10 --duration 20 --json "$OUT/node_age_3b_bf16.json"
    if has mujoco; then  # the packaged graph with the sim, the stand-in model
        step node_age_standin_goal_sim 60 90 "$PY" benchmarks/bench_vlm_node.py --graph goal_sim \
            --duration 20 --frames 10 --json "$OUT/node_age_standin_goal_sim.json"
    else
        say "SKIP node_age_standin_goal_sim: no mujoco on this machine"
    fi
else
    say "SKIP node age: no cyclonedds (the wheels were not carried?)"
fi
# 3. the rest of the table: 3B nf4, 7B bf16 and nf4, 3B int8 (10 frames)
if has bitsandbytes; then
    step 3b_nf4 45 90 "$PY" "${BENCH[@]}" --arch 3b --dtype bf16 --quantization nf4 --frames 20 \
        --out "$OUT/3b_nf4.json"
fi
step 7b_bf16 90 150 "$PY" "${BENCH[@]}" --arch 7b --dtype bf16 --quantization none --compile off --frames 20 \
    --out "$OUT/7b_bf16.json"
if has bitsandbytes; then
    step 7b_nf4 45 90 "$PY" "${BENCH[@]}" --arch 7b --dtype bf16 --quantization nf4 --frames 20 \
        --out "$OUT/7b_nf4.json"
    step 3b_int8 60 90 "$PY" "${BENCH[@]}" --arch 3b --dtype bf16 --quantization int8 --frames 10 \
        --out "$OUT/3b_int8.json"
else
    say "SKIP nf4/int8 rows: no bitsandbytes"
fi
say "done in $(($(date +%s) - START))s; results in $OUT"
