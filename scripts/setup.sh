#!/usr/bin/env bash
# Prepares a checkout for building and testing chunkc. Safe to run any number of times.
#
#   scripts/setup.sh        run it: creates .venv, installs the Python packages, builds chunkc
#   . scripts/setup.sh      source it (the other scripts do): the same, and then .venv/bin is on
#                           PATH in the sourcing shell
#
# Steps:
#   0. install the Debian packages the tests need when they are missing (headless `chromium` and
#      its fonts, for the HTML report tests; `nasm`, for libjpeg-turbo's SIMD decoders; FFmpeg's
#      development libraries, clang and pkg-config, for the `video` feature; FFmpeg's runtime
#      libraries torchcodec, LeRobot's default video backend, loads), with apt-get as root;
#      elsewhere it says what to install;
#   1. create the project virtualenv `.venv` (python3 -m venv) if there is none;
#   2. install tests/python/requirements.txt into it, only when that file changed since the last
#      successful install (its hash and tier are kept in .venv/.chunkc-requirements.sha256): the
#      core always, the target-model tier (torch, LeRobot, gym-pusht) when the disk has room;
#      with the model tier, `.venv-lerobot21` too: lerobot 0.3.3 (LeRobot v2.1's reader) over
#      .venv's torch (tests/python/requirements-lerobot21.txt);
#   3. put .venv/bin first on PATH: the bundled HDF5 build needs cmake >= 3.26, which comes from
#      the venv;
#   4. build chunkc with `cargo build --release --locked --features video` (the first build
#      compiles HDF5);
#   5. install mdBook, pinned ($CHUNKC_MDBOOK_VERSION), into cargo's bin directory with
#      `cargo install mdbook --locked`, only when `mdbook --version` does not print that version,
#      for test.sh's `book` check; after the chunkc build, so it never delays it. Where it cannot
#      be installed (offline) it warns, and the check is skipped, naming why (kept in
#      .venv/.chunkc-mdbook).
#
# Environment: PYTHON (the interpreter that creates the venv; default python3),
# CHUNKC_VERBOSE=1 (show pip's and cargo's full output), CHUNKC_PY_TIER=core|models (the Python
# tier; default: models where the disk has room), CHUNKC_MDBOOK=0 (do not install mdBook: the
# book check then skips building the book), CHUNKC_VIDEO=0 (build without the
# `video` feature: no FFmpeg needed, LeRobot videos cannot be read; see book/src/video.md for
# why the feature is off by default: Debian's libavcodec is GPL).
#
# Every script builds with the same features ($CHUNKC_FEATURES, exported when sourced), so
# that `cargo test` never rebuilds target/release/chunkc without them.

# The mdBook the book is built with (test.sh's `book` check): the newest 0.4.x, which builds with
# Rust >= 1.82. Exported, so that test.sh checks for the same version.
export CHUNKC_MDBOOK_VERSION=0.4.52

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
# libjpeg-turbo (the turbojpeg crate builds it) needs nasm for its SIMD decoders; without, it
# builds the C ones, slower on RLDS and JPEG-compressed HDF5 frames (the same pixels).
command -v nasm >/dev/null || debian+=(nasm)
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
# torchcodec, LeRobot's default video backend, dlopens the system FFmpeg: all seven of its
# libraries, libavdevice, libavfilter and libswresample too (readelf -d of torchcodec 0.10's
# libtorchcodec_core5.so). Without them every `LeRobotDataset` over a video set fails to load.
# Their runtime packages carry the FFmpeg major in their names (Debian 12: libavdevice59), so
# each missing one is named by what its -dev package depends on, once apt's lists are fresh.
runtime=()
for lib in libavutil libavcodec libavformat libavdevice libavfilter libswscale libswresample; do
    /sbin/ldconfig -p 2>/dev/null | grep -q "[[:space:]]$lib\.so\.[0-9]" || runtime+=("$lib")
done
if [ "${#debian[@]}" -gt 0 ] || [ "${#runtime[@]}" -gt 0 ]; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -qq >&2 || die "apt-get update failed"
        for lib in "${runtime[@]}"; do
            pkg=$(apt-cache depends "$lib-dev" 2>/dev/null \
                | awk -v l="$lib" '$1 == "Depends:" && $2 ~ "^" l "[0-9]+$" {print $2; exit}')
            debian+=("${pkg:-$lib-dev}")
        done
        say "installing Debian packages: ${debian[*]} (apt-get)"
        apt-get install -y -qq --no-install-recommends "${debian[@]}" >&2 \
            || die "apt-get could not install ${debian[*]}"
    else
        [ "${#runtime[@]}" -gt 0 ] && debian+=("${runtime[@]/%/ (runtime)}")
        say "warning: missing Debian packages ${debian[*]}: install them (apt-get install ...); the report tests need chromium, the \`video\` feature FFmpeg's -dev packages (or set CHUNKC_VIDEO=0), LeRobot's default video backend (torchcodec) FFmpeg's runtime libraries"
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

# 2. The Python packages, in two tiers (see the head of tests/python/requirements.txt): the
#    core always, the target-model tier (torch, LeRobot, gym-pusht: ~8 GB installed, ~11 GB at
#    the install's peak) when the disk has room for it, the Rust build and the tests' scratch.
#    A tier is installed again only when the file changed or a larger tier became possible; what
#    was installed and why is kept in $stamp ("<sha256 of the file> <tier>") and $tier_file.
#    torch and its CUDA libraries are most of it; pip's cache would hold a second copy of the
#    downloads, so it is not used, and pip unpacks into the project's own disk, not /tmp (which
#    can be a small tmpfs).
free_mb() { df -Pm . | awk 'NR==2 {print $4}'; }
pip_install() {
    mkdir -p "$venv/.pip-tmp"
    local rc=0
    TMPDIR="$CHUNKC_ROOT/$venv/.pip-tmp" "$venv/bin/python" -m pip install "${quiet[@]}" \
        --disable-pip-version-check --no-cache-dir -r "$1" || rc=$?
    rm -rf "$venv/.pip-tmp"
    return "$rc"
}
core_requirements=$venv/.chunkc-requirements-core.txt
tier_file=$venv/.chunkc-tier
# Measured on Debian 12 (MB): the model tier's install peak; target/ after the release build and
# the release test binaries; the Python suite's scratch directories.
models_peak_mb=11500
target_mb=6000
scratch_mb=2500
want=$("$venv/bin/python" -c 'import hashlib, sys
print(hashlib.sha256(open(sys.argv[1], "rb").read()).hexdigest())' "$requirements")
have_sha='' have_tier=''
[ -f "$stamp" ] && read -r have_sha have_tier <"$stamp"
free=$(free_mb)
need=$((models_peak_mb + scratch_mb))
[ -d target/release/deps ] || need=$((need + target_mb))
tier=${CHUNKC_PY_TIER:-auto}
case "$tier" in
    core | models) reason="CHUNKC_PY_TIER=$tier" ;;
    auto)
        if [ "$have_tier" = models ] || [ "$free" -ge "$need" ]; then
            tier=models reason="$free MB free"
        else
            tier=core reason="only $free MB free on $(df -P . | awk 'NR==2 {print $6}'); the model tier needs ~$need MB"
        fi
        ;;
    *) die "CHUNKC_PY_TIER must be core or models, not '$tier'" ;;
esac
if [ "$want" != "$have_sha" ] || [ "$tier" != "$have_tier" ]; then
    if [ -z "$have_sha" ]; then
        say "installing the $tier tier of $requirements into $venv ($reason)"
    else
        say "$requirements or its tier changed: updating $venv to the $tier tier ($reason)"
    fi
    sed '/^# tier: models/,$d' "$requirements" >"$core_requirements"
    if ! pip_install "$core_requirements"; then
        df -h . >&2 || true
        die "pip could not install the core of $requirements (see above; free disk space is shown)"
    fi
    if [ "$tier" = models ] && ! pip_install "$requirements"; then
        df -h . >&2 || true
        [ "${CHUNKC_PY_TIER:-auto}" = models ] \
            && die "pip could not install the model tier of $requirements (see above)"
        # A half-installed torch is worse than none: start again with the core only.
        say "warning: the model tier did not install (see above); $venv gets the core only, and the tests that need torch or LeRobot will skip"
        rm -rf "$venv"
        "$python" -m venv "$venv" || die "'$python -m venv' failed"
        pip_install "$core_requirements" \
            || die "pip could not install the core of $requirements (see above)"
        tier=core reason="the model tier's install failed with $free MB free"
    fi
    # Written only after a successful install, so an interrupted install is retried next time.
    printf '%s %s\n' "$want" "$tier" >"$stamp"
    printf '%s\n%s\n' "$tier" "$reason" >"$tier_file"
fi
if [ "$tier" = core ]; then
    say "warning: Python tier 'core' ($(sed -n 2p "$tier_file")): the target-model tests (torch, LeRobot, gym-pusht) will skip; free disk and run setup again, or set CHUNKC_PY_TIER=models"
fi

# 2b. LeRobot 0.3.3, the v2.1 reader of the LeRobot v2.1 export's tests, in a venv of its own
#     (tests/python/requirements-lerobot21.txt says why): only with the model tier, whose torch it
#     borrows. The venv is rebuilt whenever that file changes (a few small packages, seconds);
#     its packages are installed before the .pth that shows it .venv's, so that pip never sees
#     (or touches) .venv's own datasets and fsspec.
lr_venv=.venv-lerobot21
lr_requirements=tests/python/requirements-lerobot21.txt
lr_stamp=$lr_venv/.chunkc-requirements.sha256
if [ "$tier" = models ]; then
    lr_want=$("$venv/bin/python" -c 'import hashlib, sys
print(hashlib.sha256(open(sys.argv[1], "rb").read() + sys.argv[2].encode()).hexdigest())' \
        "$lr_requirements" "$CHUNKC_ROOT")
    lr_have=''
    [ -f "$lr_stamp" ] && read -r lr_have <"$lr_stamp"
    if [ "$lr_want" != "$lr_have" ]; then
        say "creating $lr_venv (lerobot 0.3.3, LeRobot v2.1's reader) beside $venv"
        rm -rf "$lr_venv"
        "$venv/bin/python" -m venv "$lr_venv" || die "'python -m venv $lr_venv' failed"
        mkdir -p "$lr_venv/.pip-tmp"
        TMPDIR="$CHUNKC_ROOT/$lr_venv/.pip-tmp" "$lr_venv/bin/python" -m pip install "${quiet[@]}" \
            --disable-pip-version-check --no-cache-dir --no-deps -r "$lr_requirements" \
            || { rm -rf "$lr_venv"; die "pip could not install $lr_requirements into $lr_venv (see above)"; }
        rm -rf "$lr_venv/.pip-tmp"
        own=$("$lr_venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
        main=$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
        printf '%s\n' "$main" >"$own/_chunkc_main_venv.pth"
        "$lr_venv/bin/python" -c 'from lerobot.datasets.lerobot_dataset import LeRobotDataset' \
            || { rm -rf "$lr_venv"; die "lerobot 0.3.3 does not import in $lr_venv (see above)"; }
        printf '%s\n' "$lr_want" >"$lr_stamp"
    fi
fi

# 3. cmake (and python) from the venv.
export PATH="$CHUNKC_ROOT/$venv/bin:$PATH"

# 4. The release build (tests build with --release too, so HDF5 is compiled only once).
say "building chunkc (cargo build --release --locked ${features[*]}; $(cmake --version | head -n1))"
if [ ! -d target/release/build ]; then
    say "first build: compiling HDF5 and ~220 crates takes a while"
    free=$(free_mb)
    if [ "$free" -lt "$target_mb" ]; then
        say "warning: only $free MB free; the build and the test binaries need ~$target_mb MB in target/"
    fi
fi
cargo build --release --locked "${features[@]}" "${quiet[@]}"
say "ready: $(target/release/chunkc --version) at target/release/chunkc"

# 5. mdBook, pinned, for the book check. Only the `search` feature: `serve` and `watch` (tokio,
#    axum, notify) are for writers, not for CI, and would add to the install (2m35s on 2 shared
#    cores with only `search`, measured with mdBook 0.4.52 and Rust 1.95).
mdbook_note=$venv/.chunkc-mdbook
mdbook_bin=${CARGO_HOME:-$HOME/.cargo}/bin/mdbook
mdbook_ok() { "$1" --version 2>/dev/null | grep -qx "mdbook v$CHUNKC_MDBOOK_VERSION"; }
if mdbook_ok mdbook || mdbook_ok "$mdbook_bin"; then
    rm -f "$mdbook_note"
elif [ "${CHUNKC_MDBOOK:-1}" = 0 ]; then
    echo "CHUNKC_MDBOOK=0: mdBook $CHUNKC_MDBOOK_VERSION not installed" >"$mdbook_note"
else
    say "installing mdBook $CHUNKC_MDBOOK_VERSION for the book check (cargo install mdbook --locked; a few minutes, once)"
    mdbook_log=$venv/.chunkc-mdbook.log
    if cargo install mdbook --version "$CHUNKC_MDBOOK_VERSION" --locked --no-default-features \
        --features search "${quiet[@]}" >"$mdbook_log" 2>&1; then
        rm -f "$mdbook_note" "$mdbook_log"
    else
        cat "$mdbook_log" >&2
        why=$(grep -m1 -i 'error' "$mdbook_log" || true)
        echo "cargo install mdbook --version $CHUNKC_MDBOOK_VERSION failed (offline?): ${why:-see the output above}" >"$mdbook_note"
        say "warning: $(cat "$mdbook_note"); the book check will skip building the book"
    fi
fi
