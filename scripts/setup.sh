#!/usr/bin/env bash
# Prepares a checkout for building and testing chunkc. Safe to run any number of times.
#
#   scripts/setup.sh        run it: creates .venv, installs the Python packages, builds chunkc
#   . scripts/setup.sh      source it (the other scripts do): the same, and then .venv/bin is on
#                           PATH in the sourcing shell
#
# Steps:
#   0. install the Debian packages the tests need when they are missing (headless `chromium` and
#      its fonts, for the HTML report tests; FFmpeg's development libraries, clang and pkg-config,
#      for the `video` feature), with apt-get as root; elsewhere it says what to install;
#   1. create the project virtualenv `.venv` (python3 -m venv) if there is none;
#   2. install tests/python/requirements.txt into it, only when that file changed since the last
#      successful install (its hash is kept in .venv/.chunkc-requirements.sha256);
#   3. put .venv/bin first on PATH: the bundled HDF5 build needs cmake >= 3.26, which comes from
#      the venv;
#   4. build chunkc with `cargo build --release --locked --features video` (the first build
#      compiles HDF5).
#
# Environment: PYTHON (the interpreter that creates the venv; default python3),
# CHUNKC_VERBOSE=1 (show pip's and cargo's full output), CHUNKC_VIDEO=0 (build without the
# `video` feature: no FFmpeg needed, LeRobot videos cannot be read; see book/src/video.md for
# why the feature is off by default: Debian's libavcodec is GPL).
#
# Every script builds with the same features ($CHUNKC_FEATURES, exported when sourced), so
# that `cargo test` never rebuilds target/release/chunkc without them.

if [[ "${BASH_SOURCE[0]}" != "$0" ]]; then
    # Sourced. Do the work in a child bash, so that strict mode and helper variables never leak
    # into (or kill) the sourcing shell; then put .venv/bin on its PATH, once.
    CHUNKC_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)" || return
    export CHUNKC_ROOT
    "${BASH:-bash}" "$CHUNKC_ROOT/scripts/setup.sh" || return
    if [ "${CHUNKC_VIDEO:-1}" = 0 ]; then CHUNKC_FEATURES=""; else CHUNKC_FEATURES="--features video"; fi
    export CHUNKC_FEATURES
    case ":$PATH:" in
        *":$CHUNKC_ROOT/.venv/bin:"*) ;;
        *) export PATH="$CHUNKC_ROOT/.venv/bin:$PATH" ;;
    esac
    return 0
fi

set -euo pipefail
CHUNKC_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$CHUNKC_ROOT"

say() { printf 'setup: %s\n' "$*" >&2; }
die() { printf 'setup: error: %s\n' "$*" >&2; exit 1; }

python=${PYTHON:-python3}
venv=.venv
requirements=tests/python/requirements.txt
stamp=$venv/.chunkc-requirements.sha256
quiet=(--quiet)
[ "${CHUNKC_VERBOSE:-0}" = 1 ] && quiet=()

command -v cargo >/dev/null \
    || die "cargo not found: install a Rust toolchain (https://rustup.rs)"
command -v cc >/dev/null || command -v gcc >/dev/null \
    || die "no C compiler found; HDF5 is compiled from source (Debian: apt-get install gcc)"

# 0. Debian packages, each named with the command or file that shows it is installed. apt-get's
#    lists are refreshed once, only when something is missing.
debian=()
command -v chromium >/dev/null || command -v chromium-browser >/dev/null || debian+=(chromium)
[ -e /usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf ] || debian+=(fonts-liberation)
# The `video` feature: ffmpeg-sys-next finds FFmpeg with pkg-config and binds it with bindgen
# (libclang). Debian 12's FFmpeg is 5.1, which ffmpeg-next 7.1 supports.
features=(--features video)
if [ "${CHUNKC_VIDEO:-1}" = 0 ]; then
    features=()
else
    command -v pkg-config >/dev/null || debian+=(pkg-config)
    command -v clang >/dev/null || debian+=(clang)
    for lib in libavcodec libavformat libswscale libavutil; do
        pkg-config --exists "$lib" 2>/dev/null || debian+=("$lib-dev")
    done
fi
if [ "${#debian[@]}" -gt 0 ]; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        say "installing Debian packages: ${debian[*]} (apt-get)"
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -qq >&2 \
            && apt-get install -y -qq --no-install-recommends "${debian[@]}" >&2 \
            || die "apt-get could not install ${debian[*]}"
    else
        say "warning: missing Debian packages ${debian[*]}: install them (apt-get install ${debian[*]}); the report tests need chromium, the \`video\` feature the others (or set CHUNKC_VIDEO=0)"
    fi
fi

# 1. The virtualenv. A half-created one (no python in it) is replaced.
if [ ! -x "$venv/bin/python" ]; then
    command -v "$python" >/dev/null \
        || die "$python not found: install Python 3.11 with pip, or set PYTHON"
    say "creating $venv with $("$python" --version 2>&1)"
    rm -rf "$venv"
    if ! "$python" -m venv "$venv"; then
        rm -rf "$venv"
        die "'$python -m venv' failed (Debian: apt-get install python3-venv)"
    fi
fi

# 2. The Python packages, when the requirements changed.
want=$("$venv/bin/python" -c 'import hashlib, sys
print(hashlib.sha256(open(sys.argv[1], "rb").read()).hexdigest())' "$requirements")
have=$(cat "$stamp" 2>/dev/null || true)
if [ "$want" != "$have" ]; then
    if [ -z "$have" ]; then
        say "installing $requirements into $venv (first time: ~3 GB of downloads, torch included)"
    else
        say "$requirements changed: updating $venv"
    fi
    # torch and its CUDA libraries need ~6 GB installed; pip's cache would hold a second copy of
    # the downloads, so it is not used, and pip unpacks into the project's own disk, not /tmp
    # (which can be a small tmpfs).
    free_mb=$(df -Pm . | awk 'NR==2 {print $4}')
    if [ -n "$free_mb" ] && [ "$free_mb" -lt 9000 ]; then
        say "warning: only ${free_mb} MB free on $(df -P . | awk 'NR==2 {print $6}'); the install needs ~9 GB at its peak"
    fi
    mkdir -p "$venv/.pip-tmp"
    if ! TMPDIR="$CHUNKC_ROOT/$venv/.pip-tmp" "$venv/bin/python" -m pip install "${quiet[@]}" \
        --disable-pip-version-check --no-cache-dir -r "$requirements"; then
        rm -rf "$venv/.pip-tmp"
        df -h . >&2 || true
        die "pip could not install $requirements (see above; free disk space is shown)"
    fi
    rm -rf "$venv/.pip-tmp"
    # Written only after a successful install, so an interrupted install is retried next time.
    printf '%s\n' "$want" >"$stamp"
fi

# 3. cmake (and python) from the venv.
export PATH="$CHUNKC_ROOT/$venv/bin:$PATH"

# 4. The release build (tests build with --release too, so HDF5 is compiled only once).
say "building chunkc (cargo build --release --locked ${features[*]}; $(cmake --version | head -n1))"
if [ ! -d target/release/build ]; then
    say "first build: compiling HDF5 and ~220 crates takes a while"
fi
cargo build --release --locked "${features[@]}" "${quiet[@]}"
say "ready: $(target/release/chunkc --version) at target/release/chunkc"
