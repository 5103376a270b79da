#!/usr/bin/env bash
# The whole test suite, pass by pass, on a built tree (the README's test command ends with it; CI runs exactly that):
#   tests/run_all.sh                 every pass, in order, stopping at the first that fails
#   tests/run_all.sh mesa25 limits   only the named passes
#   tests/run_all.sh --list          the passes and what each runs
# DVS_PASSES="default install" selects passes as arguments do, when none are given (tests/fresh_machine.sh runs the
# README's command verbatim through fewer passes with it). DVS_BUILD_DIR (default build) is the build tree. Each pass
# prints its name and command before it starts and its time after; at the end (also after a failure) a table says
# which passes ran, how long each took and which failed.
# docs/testing.md says why each pass exists.
set -uo pipefail
cd "$(dirname "$0")/.."
B="${DVS_BUILD_DIR:-build}"
CT="ctest --test-dir $B --output-on-failure"
FAST="-LE robustness|cluster|install"    # everything but the slow labels, which run once
# The repeated passes (another driver, forced limits) also leave out the device-script smoke tests: they check the
# bash script and the bundle, which no driver or limit changes (the default pass runs them).
AGAIN="-LE robustness|cluster|install|devicescript"
OPS='^(Ops|Split|Paths/|KernelTuning|Resize|[A-Za-z]+Ops[./]|AttentionTest|LinearTest|Family/|ConvFamilies)'
# The unit tests the syncval pass runs besides the goldens: the op tests and every other kind of recording (the
# recorder, bounded submission, models, diffusion and geometry, the embedding API on an application's device, one
# ClipRun, one dvs run). Left out for time (docs/testing.md says what each cost): two op sweeps (the same kernels at
# more sizes; the splits they walk are the ones ForcedLimits.* walks among the goldens) and four ContextSharing tests
# whose device work is a whole run that the ClipRun and PipelineE2e tests record too (what they add is threads and
# lifetimes, not recordings; TwoContextsOnOneApplicationDeviceShareItsQueue stays: two contexts' submissions).
SYNCVAL_UNITS="${OPS%)}|GpuTest\.|BoundedSubmission|ModelsText|TinyModel|PointCloudSceneTest|SceneDeviceMemory|HostDevice\.|OwnDeviceTimeline|ContextSharing|DepthEstimatorTest\.TheDeviceForm|SyncValidationPass|DroppedBarrierSwitch|ClipRun\.TakesAndGives|PipelineCli\.RunWritesEveryOutput)"
SYNCVAL_SKIP='^(SplitConv\.BindingSplitsChannelGroupsRowsAndColumns|AttentionTest\.EveryHeadDimUpTo256|ContextSharing\.(CallsFromTwoThreads|ACallOnTheContextOfARunningJob|ScenesDestroyedUnderAJob|ASecondContextOnTheSameDevice)[A-Za-z]*)$'
SV=tests/run_with_sync_validation.sh
# Left out of the Mesa 25 pass, because Mesa 25.0's LLVM compiles shaders about ten times slower than 22.3 or 26.1
# do (AttentionTest.TiledFamilyOddSizes from a cold shader cache: 81 s against 7.5 s on 22.3): the op tests whose
# subject is a GPU kernel family (tiled, the coopmat twins, every flash kernel; ConvFamilies.CoopmatTwinOtherLayouts
# alone took 167 s), which run by value on 22.3 (default, gpu-ops) and on 26.1 (the coopmat pass runs every
# AttentionTest and ConvFamilies test), and the attention sweeps over head dims 1–256 (a compile per head dim, 150 s
# there), which run on 22.3 in the default and limits passes. Mesa 25 still runs every golden, every other op test
# (the split-key attention and head dim 64 among them) and the whole-pipeline tests on the CPU entry's kernels.
MESA25_SKIP='^(ConvFamilies\.(Coopmat|Tiled)[A-Za-z]*|AttentionTest\.(TiledFamily|CoopmatTwin)[A-Za-z]*|AttentionOps\.HalfOperandsGiveTheFloatResultOnEveryFlashKernel|HeadMajorAttentionOps\.SameBitsAsTokenMajorOnEveryFlashKernel|AttentionHeadsOps\.MatchesADoubleReferenceAtOddSizes|AttentionTest\.(EveryHeadDimUpTo256|HeadDimSweep|HeadDimsFromFourTo128|PaddedHeadDimWorkspaceAndBlockings)|conv_tiled_family)$'
# Left out of the limits pass: the whole runs whose subject is the embedding API, the job and cache logic or the
# command line (ClipRun, ContextSharing, the C API's whole run and its Python consumers, batches, jobs, caches,
# reproducibility). Their device work is the pipeline that PipelineE2e, RunFrames, RunOutputs and the goldens record
# under the same limits, and each took 20–160 s there (most of the binding=64KiB time is the validation layer
# checking thousands of split dispatches): 1000 s of the pass's 2000. The application's buffers still go through the
# split ops under the limits in DepthEstimatorTest.TheDeviceForm* and CApiDeviceCalls.ADepthEstimate*.
LIMITS_SKIP='^(ClipRun\.(SamplesThe|FloatFrames|ASecondIdentical|GivenPoses|RunsOnTheApplications|TakesAndGives|TheJobGives)[A-Za-z]*|ContextSharing\.[A-Za-z]*|CApiDeviceCalls\.AWholeRun[A-Za-z]*|c_api_(clip|careless)_python|(CliBatch|Jobs|LatentCache|InversionCacheKey|ReproducibleRun|PipelineCli)\.[A-Za-z]*)$'

# name | what it proves | command (words split on spaces; a quoted regex stays one word through PASS_ARGS; a word
# && between two commands runs the second after the first passed)
PASS_NAMES=(default slow install mesa25 limits gpu-golden gpu-ops coopmat syncval sanitized)
declare -A PASS_WHAT PASS_CMD
PASS_WHAT[default]="Mesa 22.3 (Debian 12's lavapipe): unit, golden and device-script tests"
PASS_CMD[default]="$CT -j2 $FAST"
PASS_WHAT[slow]="once: kills and reruns, injected faults, many processes, flat memory, the Slurm array job"
PASS_CMD[slow]="$CT -j2 -L robustness|cluster"
PASS_WHAT[install]="once: cmake --install to a temporary prefix, consumers built against it (C, C++, ctypes, preview)"
PASS_CMD[install]="$CT -L install"
PASS_WHAT[mesa25]="the same tests on Mesa 25.0 (Vulkan 1.4, bookworm-backports)"
PASS_CMD[mesa25]="tests/run_on_mesa25.sh $CT -j2 $AGAIN -E $MESA25_SKIP"
PASS_WHAT[limits]="the same tests with the device limits forced down, so every op takes its split paths"
PASS_CMD[limits]="tests/run_with_forced_limits.sh $CT -j2 $AGAIN -E $LIMITS_SKIP"
PASS_WHAT[gpu-golden]="the golden tests with the GPU tuning entry forced (the kernels a GPU runs, by value)"
PASS_CMD[gpu-golden]="tests/run_with_tuning.sh gpu $CT -j2 -L golden"
PASS_WHAT[gpu-ops]="the op tests with the GPU tuning entry forced"
PASS_CMD[gpu-ops]="tests/run_with_tuning.sh gpu $CT -j2 -R $OPS"
PASS_WHAT[coopmat]="Mesa 26.1 (cooperative matrix): the tensor-core kernels a GPU runs, by value (op and golden tests)"
PASS_CMD[coopmat]="tests/run_coopmat_pass.sh $B"
PASS_WHAT[syncval]="goldens, op tests and every kind of recording under synchronization validation, GPU entry forced"
PASS_CMD[syncval]="$SV $CT -j2 -L golden && $SV $CT -j2 -L unit -R $SYNCVAL_UNITS -E $SYNCVAL_SKIP"
PASS_WHAT[sanitized]="a clang ASan+UBSan build: every fuzz harness for a while, the readers' and glue tests"
PASS_CMD[sanitized]="tests/run_sanitized.sh"

if [ "${1:-}" = "--list" ]; then
  for p in "${PASS_NAMES[@]}"; do printf '%-11s %s\n            %s\n' "$p" "${PASS_WHAT[$p]}" "${PASS_CMD[$p]}"; done
  exit 0
fi
if [ "${1:-}" = "--help" ] || [ "${1:-}" = "-h" ]; then
  sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'
  exit 0
fi
selected=("$@")
if [ ${#selected[@]} -eq 0 ] && [ -n "${DVS_PASSES:-}" ]; then read -r -a selected <<< "${DVS_PASSES//,/ }"; fi
if [ ${#selected[@]} -eq 0 ]; then selected=("${PASS_NAMES[@]}"); fi
for p in "${selected[@]}"; do
  if [ -z "${PASS_CMD[$p]+x}" ]; then
    echo "tests/run_all.sh: no pass named '$p' (tests/run_all.sh --list shows them: ${PASS_NAMES[*]})" >&2
    exit 2
  fi
done
if [ ! -f "$B/CTestTestfile.cmake" ]; then
  echo "tests/run_all.sh: no build tree in '$B' (build first: cmake -S . -B build && cmake --build build, or set DVS_BUILD_DIR)" >&2
  exit 2
fi

summary=()
status=0
print_summary() {
  echo
  echo "== tests/run_all.sh: summary"
  printf '%s\n' "${summary[@]}"
}
for p in "${selected[@]}"; do
  echo
  echo "== pass '$p': ${PASS_WHAT[$p]}"
  echo "== $ ${PASS_CMD[$p]}"
  start=$(date +%s)
  # The command is one string of plain words; read -a splits it without glob or brace expansion. A word && ends
  # one command: the next runs only when it passed.
  read -r -a words <<< "${PASS_CMD[$p]} &&"
  cmd=()
  rc=0
  for w in "${words[@]}"; do
    if [ "$w" != "&&" ]; then cmd+=("$w"); continue; fi
    "${cmd[@]}"
    rc=$?
    cmd=()
    if [ $rc -ne 0 ]; then break; fi
  done
  secs=$(( $(date +%s) - start ))
  line="$(printf '  %-11s %-6s %4d min %02d s' "$p" "$([ $rc -eq 0 ] && echo ok || echo FAILED)" $((secs / 60)) $((secs % 60)))"
  summary+=("$line")
  echo "== pass '$p': $([ $rc -eq 0 ] && echo passed || echo "FAILED (exit $rc)") in $((secs / 60)) min $((secs % 60)) s"
  if [ $rc -ne 0 ]; then status=$rc; break; fi
done
print_summary
exit $status
