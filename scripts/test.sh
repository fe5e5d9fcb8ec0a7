#!/usr/bin/env bash
# The whole test suite, exactly as CI runs it (.ci/run calls this). Works from any directory.
#
#   scripts/test.sh
#
# Runs every check even when an earlier one fails, prints a summary, and exits non-zero if any
# check failed: cargo fmt --check, cargo clippy (-D warnings), cargo test --release (all with
# the `video` feature, as setup.sh builds; CHUNKC_VIDEO=0: without), a check that chunkc still
# builds without the feature, the wheel (scripts/wheel.sh), the Python suite in tests/python
# against target/release/chunkc and the installed wheel, the book (book-links: every internal link,
# anchor and page of book/src, scripts/book_links.py; book: `mdbook build` with the pinned mdBook
# that setup.sh installs, skipped where it could not), and a 10 s run of each fuzz target when
# cargo-fuzz is installed (CHUNKC_FUZZ=1: install it if needed; CHUNKC_FUZZ=0: skip;
# CHUNKC_FUZZ_SECONDS: another length).
#
# CHUNKC_FULL_PUSHT=/path/to/pusht_cchi_v7_replay.zarr also runs the tests that build the full
# Push-T dataset (slow; off by default). A relative path is taken from where you run this.
set -euo pipefail
exec 2>&1 # one stream, so that piped output stays in order

if [ -n "${CHUNKC_FULL_PUSHT:-}" ] && [ -e "$CHUNKC_FULL_PUSHT" ]; then
    # Absolute, because the tests run from the repository root.
    CHUNKC_FULL_PUSHT=$(cd "$(dirname "$CHUNKC_FULL_PUSHT")" && pwd)/$(basename "$CHUNKC_FULL_PUSHT")
    export CHUNKC_FULL_PUSHT
fi
cd "$(dirname "${BASH_SOURCE[0]}")/.."
. scripts/setup.sh

if [ -t 1 ]; then bold=$'\033[1m' plain=$'\033[0m'; else bold='' plain=''; fi
start=$SECONDS
passed=()
failed=()

# Runs one named check; records the result instead of stopping at the first failure.
check() {
    local name=$1
    shift
    local shown="$name: $*"
    declare -F "$1" >/dev/null && shown=$name # a function below prints its own command
    printf '\n%s== %s%s\n' "$bold" "$shown" "$plain"
    local t0=$SECONDS rc=0
    "$@" || rc=$?
    if [ "$rc" -eq 0 ]; then
        passed+=("$name")
        printf -- '-- %s: ok (%ss)\n' "$name" $((SECONDS - t0))
    else
        failed+=("$name")
        printf -- '-- %s: FAILED with exit code %s (%ss)\n' "$name" "$rc" $((SECONDS - t0))
    fi
}

# rustfmt and clippy ship with rustup's default profile; add them if this toolchain lacks them.
for component in rustfmt clippy; do
    sub=${component/rustfmt/fmt}
    if ! cargo "$sub" --version >/dev/null 2>&1; then
        if command -v rustup >/dev/null; then
            echo "test: adding the $component component (rustup component add $component)"
            rustup component add "$component"
        fi
    fi
done

pytest_run() {
    # Exit code 5 means pytest collected no tests: that is a failure here, not a pass.
    local rc=0
    echo "CHUNKC_BIN=$PWD/target/release/chunkc .venv/bin/python -m pytest tests/python -q"
    CHUNKC_BIN="$PWD/target/release/chunkc" .venv/bin/python -m pytest tests/python -q || rc=$?
    [ "$rc" -eq 5 ] && echo "pytest collected no tests in tests/python"
    return "$rc"
}

# The features setup.sh built with (sourcing it exported them); unquoted on purpose: empty or
# `--features video`.
# shellcheck disable=SC2086
check fmt cargo fmt --check
check clippy cargo clippy --release --locked --all-targets $CHUNKC_FEATURES -- -D warnings
check cargo-test cargo test --release --locked $CHUNKC_FEATURES
# Default features (no FFmpeg): still builds, lints clean, and a video source says which
# feature it needs (clippy writes no binary, so target/release/chunkc keeps the feature).
if [ -n "$CHUNKC_FEATURES" ]; then
    check no-video-build cargo clippy --release --locked --all-targets -- -D warnings
fi
if [ -n "${CHUNKC_FULL_PUSHT:-}" ]; then
    echo "test: CHUNKC_FULL_PUSHT=$CHUNKC_FULL_PUSHT (full Push-T tests enabled)"
fi
# The wheel (scripts/wheel.sh: static LGPL FFmpeg, cached under ~/.cache/chunkc, and a build of its
# own in target/wheel), which tests/python/test_wheel.py installs into a fresh venv and checks
# against target/release/chunkc. CHUNKC_WHEEL_BUILD=0 skips building it (test_wheel.py then
# tests dist/'s newest wheel, if any).
wheel_run() {
    echo "scripts/wheel.sh"
    local built
    built=$(scripts/wheel.sh) || return
    CHUNKC_WHEEL=$PWD/$built
    export CHUNKC_WHEEL
}
if [ "${CHUNKC_WHEEL_BUILD:-1}" = 1 ]; then
    check wheel wheel_run
else
    echo
    echo "test: wheel build skipped (CHUNKC_WHEEL_BUILD=0)"
fi
check pytest pytest_run

# The book (book/src): its internal links, anchors and pages (scripts/book_links.py, standard
# library only, after its own self-test), then a build with the pinned mdBook into a temporary
# folder (book.toml's build-dir, book/build, is left alone). mdBook fails on a missing SUMMARY
# entry or a bad book.toml; it only warns on a broken link, which the link check fails on.
book_links_run() {
    echo "python3 scripts/book_links.py --self-test && python3 scripts/book_links.py book/src"
    python3 scripts/book_links.py --self-test && python3 scripts/book_links.py book/src
}
mdbook=''
for candidate in mdbook "${CARGO_HOME:-$HOME/.cargo}/bin/mdbook"; do
    if "$candidate" --version 2>/dev/null | grep -qx "mdbook v$CHUNKC_MDBOOK_VERSION"; then
        mdbook=$candidate
        break
    fi
done
book_run() {
    local out rc=0
    out=$(mktemp -d)
    echo "$mdbook build book -d $out"
    "$mdbook" build book -d "$out" || rc=$?
    [ "$rc" -eq 0 ] && [ ! -f "$out/index.html" ] && echo "mdbook wrote no index.html" && rc=1
    rm -rf "$out"
    return "$rc"
}
check book-links book_links_run
if [ -n "$mdbook" ]; then
    check book book_run
else
    echo
    echo "test: book build skipped: mdBook $CHUNKC_MDBOOK_VERSION is not installed ($(cat .venv/.chunkc-mdbook 2>/dev/null || echo 'scripts/setup.sh did not install it'))"
fi

# A short bounded fuzz run (book/src/fuzzing.md). CHUNKC_FUZZ=1 runs it, installing cargo-fuzz
# if needed; CHUNKC_FUZZ=0 skips it; unset, it runs only where `cargo fuzz` is already installed.
# Not being able to install cargo-fuzz skips it; a crash fails it. The corpus itself is replayed
# by `cargo test` (tests/fuzz_corpus.rs) in any case.
fuzz_run() {
    local rc=0
    echo "scripts/fuzz.sh ${CHUNKC_FUZZ_SECONDS:-10}"
    scripts/fuzz.sh "${CHUNKC_FUZZ_SECONDS:-10}" || rc=$?
    if [ "$rc" -eq 3 ]; then
        echo "fuzz: skipped (cargo-fuzz could not be installed)"
        rc=0
    fi
    return "$rc"
}
fuzz=${CHUNKC_FUZZ:-auto}
if [ "$fuzz" = auto ]; then
    cargo fuzz --version >/dev/null 2>&1 && fuzz=1 || fuzz=0
fi
if [ "$fuzz" = 1 ]; then
    check fuzz fuzz_run
else
    echo
    echo "test: fuzz run skipped (cargo-fuzz not installed; CHUNKC_FUZZ=1 installs it and runs it)"
fi

elapsed=$((SECONDS - start))
echo
if [ "$(head -n1 .venv/.chunkc-tier 2>/dev/null)" = core ]; then
    echo "test.sh: note: Python tier 'core' ($(sed -n 2p .venv/.chunkc-tier)): the tests that need torch, LeRobot or gym-pusht were skipped (pytest's summary counts them)"
fi
if [ "${#failed[@]}" -eq 0 ]; then
    echo "test.sh: all ${#passed[@]} checks passed (${passed[*]}) in $((elapsed / 60))m$((elapsed % 60))s"
else
    echo "test.sh: FAILED: ${failed[*]} (passed: ${passed[*]:-none}) in $((elapsed / 60))m$((elapsed % 60))s"
    exit 1
fi
