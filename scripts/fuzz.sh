#!/usr/bin/env bash
# Runs the libFuzzer targets in fuzz/ (book/src/fuzzing.md). Works from any directory.
#
#   scripts/fuzz.sh [SECONDS] [TARGET...]
#
# Runs each target (default: all of `cargo fuzz list`) for SECONDS (default 60), starting from
# the checked-in corpus fuzz/corpus/<target>/. Exits non-zero if any target crashed (a panic, an
# overflow, a hang past 30 s, or more than 2 GB of memory); the crashing input is then in
# fuzz/artifacts/<target>/. New inputs the fuzzer finds go to fuzz/work/<target>/ (ignored by
# git), never into the checked-in corpus; `cargo fuzz cmin` merges them (see the book).
#
# Exits 3 when cargo-fuzz is missing and cannot be installed.
#
# Works on stable Rust: installs cargo-fuzz (`cargo install cargo-fuzz --locked`, into cargo's
# bin directory) if `cargo fuzz` is missing, and builds with `--sanitizer none`, which needs no
# nightly (only the sanitizers do). The build is release with debug assertions and overflow
# checks, in fuzz/target (the first build compiles the bundled HDF5 again: minutes).
#
# Environment: CHUNKC_FUZZ_SANITIZER (default none; `address` needs a nightly toolchain),
# CHUNKC_FUZZ_ARGS (more libFuzzer flags, e.g. `-jobs=4 -workers=4`).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
. scripts/setup.sh # .venv/bin on PATH: cmake for the bundled HDF5

seconds=${1:-60}
shift || true
sanitizer=${CHUNKC_FUZZ_SANITIZER:-none}

say() { printf 'fuzz: %s\n' "$*"; }

if ! cargo fuzz --version >/dev/null 2>&1; then
    say "installing cargo-fuzz (cargo install cargo-fuzz --locked)"
    if ! cargo install cargo-fuzz --locked; then
        say "cannot install cargo-fuzz (offline?); nothing was fuzzed"
        exit 3
    fi
fi

targets=("$@")
if [ "${#targets[@]}" -eq 0 ]; then
    mapfile -t targets < <(cd fuzz && cargo fuzz list)
fi

say "building ${targets[*]} (sanitizer: $sanitizer)"
cargo fuzz build --sanitizer "$sanitizer"

# The file-based targets write their scratch files under TMPDIR: one directory, removed after.
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT

crashed=()
for target in "${targets[@]}"; do
    mkdir -p "fuzz/work/$target" "fuzz/corpus/$target"
    say "$target: ${seconds}s"
    # -timeout: one input taking 30 s is a hang; -rss_limit_mb: more than 2 GB is a leak or an
    # allocation sized by the input.
    # shellcheck disable=SC2086 # CHUNKC_FUZZ_ARGS is a list of flags
    if ! TMPDIR=$scratch cargo fuzz run --sanitizer "$sanitizer" "$target" \
        "fuzz/work/$target" "fuzz/corpus/$target" -- \
        -max_total_time="$seconds" -timeout=30 -rss_limit_mb=2048 -print_final_stats=1 \
        ${CHUNKC_FUZZ_ARGS:-}; then
        crashed+=("$target")
    fi
done

if [ "${#crashed[@]}" -gt 0 ]; then
    say "CRASHED: ${crashed[*]} (inputs in fuzz/artifacts/<target>/)"
    exit 1
fi
say "no crash in ${targets[*]} (${seconds}s each)"
