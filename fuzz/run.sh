#!/usr/bin/env bash
# Run every fuzz target for SECONDS each, from the committed seeds.
#
#   fuzz/run.sh SECONDS [TARGET...]
#
# Each target starts from a scratch copy of fuzz/corpus-seeds/<target>/ in
# fuzz/corpus/<target>/ (ignored by git; emptied first) with the dictionary
# fuzz/dict/<target>.dict, and prints executions, coverage (libFuzzer's
# `cov`: instrumented edges reached) and findings (new crash/oom/timeout
# files under fuzz/artifacts/<target>/). Exits non-zero when anything was
# found, so a short run works as a smoke test.
#
# Toolchain: `cargo +nightly` when a nightly toolchain is installed, else
# the default (stable) toolchain with RUSTC_BOOTSTRAP=1 (cargo-fuzz needs a
# few unstable flags; the sanitizer is off, `-s none`: the readers contain
# no `unsafe`, and stable has no sanitizer runtime). cargo-fuzz itself is
# installed with `cargo install cargo-fuzz --locked` when missing.
# Environment: FUZZ_TARGET_DIR (default fuzz/target); FUZZ_STABLE=1 uses
# the default toolchain even when nightly exists; FUZZ_SEED=N fixes
# libFuzzer's random seed (CI); FUZZ_RUNS=N stops each target after N
# inputs (with FUZZ_SEED: the same inputs on every machine, whatever its
# speed); FUZZ_TIMEOUT=S (default 10) is how long one input may run before
# it counts as a hang: raise it for long runs on a loaded or niced machine,
# where a starved process is not a hang; RAYON_NUM_THREADS (default 1 per
# target).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
cd "$here"
seconds="${1:?usage: fuzz/run.sh SECONDS [TARGET...]}"
shift
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  targets=(ply obj off stl xyz nrrd vtk shell svm odf udf
    recon_levelset recon_svm recon_convection distance feature_field extract normals eval)
fi
# One thread per fuzzing process (the algorithms use rayon): runs stay
# reproducible and leave the other cores alone.
export RAYON_NUM_THREADS="${RAYON_NUM_THREADS:-1}"

if ! cargo fuzz --version >/dev/null 2>&1; then
  cargo install cargo-fuzz --locked
fi
if rustup run nightly rustc --version >/dev/null 2>&1 && [ -z "${FUZZ_STABLE:-}" ]; then
  cargo=(cargo +nightly)
else
  cargo=(cargo)
  export RUSTC_BOOTSTRAP=1
fi
target_dir="${FUZZ_TARGET_DIR:-$here/target}"
flags=(-O -a -s none --target-dir "$target_dir")

echo "toolchain: $("${cargo[@]}" --version) ${RUSTC_BOOTSTRAP:+(RUSTC_BOOTSTRAP=1)}"
"${cargo[@]}" fuzz build "${flags[@]}" 2>"$here/target-build.log" ||
  { tail -n 30 "$here/target-build.log"; exit 2; }

printf '%-6s %12s %8s %11s %6s %7s  %s\n' target executions exec/s seed-edges edges corpus findings
status=0
for t in "${targets[@]}"; do
  corpus="$here/corpus/$t"
  artifacts="$here/artifacts/$t"
  rm -rf "$corpus"
  mkdir -p "$corpus" "$artifacts"
  # The structured (algorithm) targets have no seed files or dictionary:
  # any bytes decode to a valid input.
  if [ -d "$here/corpus-seeds/$t" ]; then cp "$here/corpus-seeds/$t/"* "$corpus/"; fi
  dict=()
  if [ -f "$here/dict/$t.dict" ]; then dict=(-dict="$here/dict/$t.dict"); fi
  before=$(ls "$artifacts" | wc -l)
  log="$here/corpus/$t.log"
  # -timeout: a single input taking longer is a hang finding.
  # -rss_limit_mb / -malloc_limit_mb: an allocation beyond 1 GiB from a
  # tiny input is a finding (inputs are at most -max_len bytes).
  "${cargo[@]}" fuzz run "${flags[@]}" "$t" "$corpus" -- \
    -max_total_time="$seconds" "${dict[@]}" -max_len=65536 \
    -timeout="${FUZZ_TIMEOUT:-10}" -rss_limit_mb=2048 -malloc_limit_mb=1024 ${FUZZ_SEED:+-seed="$FUZZ_SEED"} ${FUZZ_RUNS:+-runs="$FUZZ_RUNS"} \
    -print_final_stats=1 -artifact_prefix="$artifacts/" >"$log" 2>&1 || true
  execs=$(grep -o 'stat::number_of_executed_units: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*$' || echo "?")
  rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | tail -1 | grep -o '[0-9]*$' || echo "?")
  seeded=$(grep -o 'INITED cov: [0-9]*' "$log" | head -1 | grep -o '[0-9]*$' || echo "?")
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*$' || echo "?")
  corp=$(ls "$corpus" | wc -l)
  after=$(ls "$artifacts" | wc -l)
  found=$((after - before))
  if [ "$found" -gt 0 ] || grep -q '==ERROR\|panicked at\|deadly signal' "$log"; then
    status=1
    findings="$found new: $(ls -t "$artifacts" | head -n "$found" | tr '\n' ' ')(log: fuzz/corpus/$t.log)"
  else
    findings="none"
  fi
  printf '%-6s %12s %8s %11s %6s %7s  %s\n' "$t" "$execs" "$rate" "$seeded" "$cov" "$corp" "$findings"
done
exit $status
