#!/usr/bin/env bash
# Every check and benchmark that needs a CUDA GPU, for a lent machine (../shared/gpu/README.md).
# Run from the project root after the wheels are installed into /tmp/site (warp-lang, plyfile,
# zstandard, yourdfpy, trimesh, tyro + docstring-parser + typeguard, gsplat; the robots' URDFs
# travel as a cmeel share folder put on PYTHONPATH):
#
#   benchmarks/gpu_session.sh OUT_DIR STAGE...      STAGE: all, or any of
#
#   gsplat   start gsplat's kernel build in the background (minutes; it outlives the call)
#   rates    MPC rates (benchmarks/gpu_rates.py: Panda MPPI K = 256 / 1024, reaching at 224 px;
#            $RATES_ARGS replaces its options)
#   metric   metric throughput on CUDA (benchmarks/metric_throughput.py)
#   tests    the metric / robots / planners / render / encoders tests (CPU and CUDA cases; or $TEST_PATHS)
#   bench    render, encoder and FK throughput on CUDA
#   arm      the arm study (E4 behind the wall) on CUDA, --quick
#   gtests   the gsplat comparison tests (wait for the build)
#   studies  the arm, base and reach studies at full size on CUDA (reach at 224 px)
#   kernel   issue #8's open GPU target in one go: Panda MPPI at K = 1024 plain and pruned (4 and 2
#            chunks: fewer, larger queries suit a GPU better), and the
#            query alone over lanes 1/4/8 x TierConfig.group_links off/on (the changes listed under
#            "changes_since" in benchmarks/results/gpu_rates.json have not run on a GPU yet)
#
# Each stage runs under its own time limit; its log and JSON go to /tmp/gpu-results, which is
# packed into OUT_DIR/results.tgz after every stage (so a stage that runs out of time still
# leaves the others' results). A one-line summary per stage goes to stdout.
set -u
out=${1:?output folder}
shift
stages=("$@")
[[ ${stages[*]} == all ]] && stages=(gsplat rates metric tests bench arm gtests)
res=/tmp/gpu-results
mkdir -p "$res" "$out"
export SPLATPLAN_WARP_CACHE=${SPLATPLAN_WARP_CACHE:-/tmp/warp-cache} PYTHONUNBUFFERED=1
export TORCH_CUDA_ARCH_LIST=${TORCH_CUDA_ARCH_LIST:-9.0} FAST_COMPILE=1 MAX_JOBS=${MAX_JOBS:-8}
py=${PYTHON:-python3}

stage() {  # stage NAME SECONDS CMD...
  local name=$1 limit=$2
  shift 2
  local t0=$SECONDS
  timeout "$limit" "$@" >"$res/$name.log" 2>&1
  local rc=$?
  echo "== $name: rc $rc in $((SECONDS - t0)) s"
  tail -n 4 "$res/$name.log" | cut -c1-300
  tar -C "$res" -czf "$out/results.tgz" .
}

nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader >"$res/device.txt" 2>&1
$py -c "import torch, warp; print('torch', torch.__version__, 'warp', warp.config.version)" >>"$res/device.txt" 2>&1
cat "$res/device.txt"
for s in "${stages[@]}"; do
  case $s in
    gsplat)  # gsplat compiles its CUDA kernels on first import: start it detached
      setsid nohup $py -c "from gsplat.cuda._backend import _C; print('gsplat built', _C is not None)" >"$res/gsplat_build.log" 2>&1 </dev/null & ;;
    rates) stage gpu_rates 300 $py benchmarks/gpu_rates.py --device cuda ${RATES_ARGS:---reach-backends warp,gsplat --lanes-sweep 1,2,4,8,16} --out "$res/gpu_rates.json" ;;
    metric) stage metric_throughput 120 $py benchmarks/metric_throughput.py --device cuda --out "$res/metric_throughput_cuda.json" ;;
    tests) stage tests 200 $py -m pytest -q -p no:cacheprovider -n 6 ${TEST_PATHS:-tests/metric tests/robots tests/planners tests/render tests/encoders} ;;
    bench)
      stage render 120 $py benchmarks/render.py --device cuda --sizes 64,224 --example '' --out "$res/render_cuda.json"
      stage encoders 120 $py benchmarks/encoders.py --device cuda --encoders thumbnail,dinov2-vits14 --out "$res/encoders_cuda.json"
      stage robots_fk 90 $py benchmarks/robots_fk.py --device cuda --out "$res/robots_fk_cuda.json" ;;
    arm) stage arm 200 $py -m splatplan.cli eval arm --quick --device cuda --out "$res/arm_cuda" ;;
    gtests)
      for _ in $(seq 60); do grep -q "gsplat built\|Error" "$res/gsplat_build.log" 2>/dev/null && break; sleep 5; done
      stage gsplat_tests 150 $py -m pytest -q -p no:cacheprovider tests/render/test_gsplat_backend.py ;;
    studies)
      stage reach_full ${STUDY_S:-300} $py -m splatplan.cli eval reach --device cuda --task-image-size 224 --out "$res/reach_gpu"
      stage arm_full ${STUDY_S:-300} $py -m splatplan.cli eval arm --device cuda --out "$res/arm_gpu"
      stage base_full ${STUDY_S:-300} $py -m splatplan.cli eval base --device cuda --out "$res/base_gpu" ;;
    kernel)
      stage gpu_kernel 300 $py benchmarks/gpu_rates.py --device cuda --samples 1024 --reach-encoders '' --tune-factors 0.25 --tune-lanes 1,4,8 --tune-group-links 0,1 --out "$res/gpu_kernel.json"
      stage gpu_kernel_pruned 200 $py benchmarks/gpu_rates.py --device cuda --samples 1024 --reach-encoders '' --prune-margin 40 --out "$res/gpu_kernel_pruned.json"
      stage gpu_kernel_pruned2 200 $py benchmarks/gpu_rates.py --device cuda --samples 1024 --reach-encoders '' --prune-margin 40 --prune-chunks 2 --out "$res/gpu_kernel_pruned2.json" ;;
    *) echo "unknown stage $s" ;;
  esac
done
tar -C "$res" -czf "$out/results.tgz" .
