#!/usr/bin/env bash
# Runs fuzz targets of a MARGLAB_FUZZ build from their seed corpus, deterministically (-seed=1),
# for SECONDS each, one after the other; exits 1 when a target found anything (the input is left in
# BUILD_DIR/fuzz-out/artifacts/). scripts/run_sanitizers.sh runs all of them for a fixed number of inputs in CI; a
# longer campaign runs them for longer (fuzz/README.md).
#   usage: fuzz/run_fuzzers.sh BUILD_DIR SECONDS [TARGET...]
#   (default: every target but fuzz_track_hdf5, the campaign through libhdf5 itself, which is run
#   by name and gates nothing: its findings are libhdf5's, contained by the trust boundary of
#   core/io/hdf5_trust.h — fuzz/README.md)
#   MARGLAB_FUZZ_FLAGS   extra libFuzzer flags; a campaign that should go on after a finding uses
#                        "-fork=1 -ignore_crashes=1 -ignore_ooms=1 -ignore_timeouts=1"
#   MARGLAB_FUZZ_RUNS    stop each target after this many inputs (libFuzzer -runs), SECONDS being
#                        only a cap: the same inputs on every machine, as CI needs (a time bound
#                        alone runs more inputs on a faster machine, so it may find more there)
#   MARGLAB_FUZZ_OUT     output folder (default: BUILD_DIR/fuzz-out), so that a campaign and the
#                        CI run of the same build keep their corpora and findings apart
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR="$1"
SECONDS_PER_TARGET="$2"
shift 2
TARGETS=("$@")
if ((${#TARGETS[@]} == 0)); then
  TARGETS=(dataset_text calib config sweep track_text track_content window)
fi
OUT="${MARGLAB_FUZZ_OUT:-$BUILD_DIR/fuzz-out}"
mkdir -p "$OUT/seeds" "$OUT/artifacts" "$OUT/logs"
# allocator_may_return_null: an allocation beyond ASan's limit returns NULL as malloc does in a
# release build (libhdf5 asks for absurd sizes from corrupted metadata and reports the failure).
# fuzz/asan.supp: out-of-bounds reads libhdf5 makes through libc calls are not marglab's findings.
# detect_stack_use_after_return=0 (the unit tests under ASan keep it): its fake stack frames moved
# from run to run and made fuzz_calib's path differ ("Reproducible runs" in fuzz/README.md).
export ASAN_OPTIONS="${ASAN_OPTIONS:-halt_on_error=1:abort_on_error=1:detect_leaks=1:allocator_may_return_null=1}:suppressions=$(pwd)/fuzz/asan.supp:detect_stack_use_after_return=0"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}"
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$(pwd)/fuzz/lsan.supp}"

# The shipped windows, decompressed: the binary seeds of fuzz_window. (fuzz_track_hdf5's seeds are
# committed in fuzz/corpus/track_hdf5: made at run time, they changed with every change of the
# front-end, and so did the fuzzing path — fuzz/README.md.)
make_seeds() {
  mkdir -p "$OUT/seeds/window"
  for w in kitti-00_ns-qr-sqrt-f32_000100 euroc-MH_01_easy_ns-qr-sqrt-f32_000600; do
    [ -s "$OUT/seeds/window/$w.win" ] || gzip -dc "datasets/windows/$w.win.gz" >"$OUT/seeds/window/$w.win"
  done
}
make_seeds

# Address-space randomisation off where the kernel allows it (setarch -R): libFuzzer's
# comparison-guided mutations take operands from the parsers' comparisons, pointers among them,
# so with random addresses two runs of one build from one seed took different paths
# (fuzz_window; fuzz/README.md, "Reproducible runs").
no_aslr=()
if setarch "$(uname -m)" -R true 2>/dev/null; then
  no_aslr=(setarch "$(uname -m)" -R)
else
  echo "fuzz: setarch -R not permitted here; runs may differ from one run to the next"
fi

failed=()
for t in "${TARGETS[@]}"; do
  corpus="$OUT/corpus/$t"  # new inputs go here; fresh each time so that a run is reproducible
  rm -rf "$corpus"
  mkdir -p "$corpus"
  dirs=("$corpus")
  for d in "fuzz/corpus/$t" "$OUT/seeds/$t"; do [ -d "$d" ] && dirs+=("$d"); done
  dict=()
  [ -f "fuzz/$t.dict" ] && dict=("-dict=fuzz/$t.dict")
  log="$OUT/logs/$t.log"
  # The folder of the input file: a path free of the process ID and of the checkout's location
  # (fuzz/fuzz_input.h), so that a run of one build from one seed is the same everywhere.
  export MARGLAB_FUZZ_TMP="$OUT/inputs/$t"
  mkdir -p "$MARGLAB_FUZZ_TMP"
  rm -f "$OUT/artifacts/$t-"*
  # A hang (> 10 s per input), > 2 GB of memory or a single allocation > 512 MB is a finding too.
  status=0
  # shellcheck disable=SC2086  # MARGLAB_FUZZ_FLAGS is a list of flags
  runs_flag=()
  per_target="MARGLAB_FUZZ_RUNS_$t"  # e.g. MARGLAB_FUZZ_RUNS_track_hdf5 overrides the count
  runs_n="${!per_target:-${MARGLAB_FUZZ_RUNS:-}}"
  [ -n "$runs_n" ] && runs_flag=("-runs=$runs_n")
  "${no_aslr[@]}" "$BUILD_DIR/fuzz/fuzz_$t" -seed=1 -max_total_time="$SECONDS_PER_TARGET" "${runs_flag[@]}" -timeout=10 \
    -rss_limit_mb=2048 -malloc_limit_mb=512 -print_final_stats=1 ${MARGLAB_FUZZ_FLAGS:-} \
    -artifact_prefix="$OUT/artifacts/$t-" "${dict[@]}" "${dirs[@]}" >"$log" 2>&1 || status=$?
  # The last status line: "#RUNS ... cov: E ft: F corp: ..." (also in fork mode).
  last=$(grep -E '^#[0-9]+' "$log" | tail -1)
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
  runs=${runs:-$(echo "$last" | grep -oE '^#[0-9]+' | tr -d '#')}
  cov=$(echo "$last" | grep -oE 'cov: [0-9]+ ft: [0-9]+')
  # Findings are crash-, leak-, timeout- and oom- inputs; a slow-unit- input (> 10 s once, kept by
  # libFuzzer for a look) is not one unless it also hit -timeout.
  found=0
  for kind in crash leak timeout oom; do
    if compgen -G "$OUT/artifacts/$t-$kind-*" >/dev/null; then found=1; fi
  done
  if [ "$status" -eq 0 ] && [ "$found" -eq 0 ]; then
    echo "fuzz_$t: ok, $runs executions (at most ${SECONDS_PER_TARGET} s), $cov, $(ls "$corpus" | wc -l) new corpus inputs"
  else
    echo "fuzz_$t: FOUND A PROBLEM after $runs executions ($cov; inputs in $OUT/artifacts/$t-*); the end of $log:"
    tail -40 "$log"
    failed+=("$t")
  fi
done
if ((${#failed[@]})); then
  echo "fuzz: problems found by ${failed[*]}"
  exit 1
fi
