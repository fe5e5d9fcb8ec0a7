#!/usr/bin/env bash
# Builds the self-contained wheel: dist/chunkc-<version>-py3-none-<platform>.whl.
#
#   scripts/wheel.sh        then: pip install dist/chunkc-*.whl
#
# The wheel holds the chunkc binary alone (maturin, `bindings = "bin"`, as ruff and uv ship
# theirs) and a small `chunkc` package for `python -m chunkc`. The binary links everything it
# uses statically but the C library: HDF5, libjpeg-turbo, the compressors, libc++, and an LGPL
# FFmpeg with SVT-AV1 and dav1d (scripts/ffmpeg-static.sh builds it once per machine, under
# ~/.cache/chunkc). Everything is compiled and linked by zig against glibc 2.28's symbols
# (CHUNKC_GLIBC), so it runs on any Linux with glibc 2.28 or newer (manylinux_2_28: RHEL 8,
# Debian 10, Ubuntu 18.10 and later), with no FFmpeg, Rust or cmake there. The licences of everything linked are in the wheel's
# .dist-info/licenses (licenses/ here); book/src/install.md says what is inside.
#
# Needs a Rust toolchain, gcc, clang (bindgen), nasm and pkg-config; as root, the missing Debian
# packages are installed. The Python build tools (maturin, cmake, meson, ninja, ziglang, auditwheel) go
# into .venv, pinned as tests/python/requirements.txt pins them. The build is separate from the
# developer build (target/wheel), so that target/release/chunkc keeps the system FFmpeg.
# Environment: CHUNKC_VERBOSE=1 (full output), CHUNKC_CACHE (the cache; default ~/.cache/chunkc).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
say() { printf 'wheel: %s\n' "$*" >&2; }
die() { printf 'wheel: error: %s\n' "$*" >&2; exit 1; }
start=$SECONDS
quiet=(--quiet)
[ "${CHUNKC_VERBOSE:-0}" = 1 ] && quiet=()

command -v cargo >/dev/null || die "cargo not found: building the wheel needs a Rust toolchain (https://rustup.rs)"
command -v cc >/dev/null || die "no C compiler: apt-get install gcc"
debian=()
command -v clang >/dev/null || debian+=(clang)
command -v nasm >/dev/null || debian+=(nasm)
command -v pkg-config >/dev/null || debian+=(pkg-config)
if [ "${#debian[@]}" -gt 0 ]; then
    [ "$(id -u)" = 0 ] || die "missing ${debian[*]}: install them (apt-get install ${debian[*]})"
    say "apt-get install ${debian[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >&2
    apt-get install -y -qq --no-install-recommends "${debian[@]}" >&2
fi

# The Python build tools, at the versions the test requirements pin.
if [ ! -x .venv/bin/python ]; then
    say "creating .venv"
    "${PYTHON:-python3}" -m venv .venv
fi
export PATH="$root/.venv/bin:$PATH"
pins=()
for tool in maturin cmake meson ninja ziglang auditwheel; do
    .venv/bin/python -c "import importlib.metadata as m, sys; m.version(sys.argv[1])" "$tool" 2>/dev/null && continue
    pins+=("$(grep -E "^$tool==" tests/python/requirements.txt || echo "$tool")")
done
if [ "${#pins[@]}" -gt 0 ]; then
    say "pip install ${pins[*]} (into .venv)"
    .venv/bin/python -m pip install "${quiet[@]}" --disable-pip-version-check "${pins[@]}"
fi

# The static LGPL FFmpeg (cached), found by ffmpeg-sys-next through pkg-config.
prefix=$(scripts/ffmpeg-static.sh)
for f in "$prefix"/licenses/*; do
    name=$(basename "$f")
    [ "$name" = VERSIONS ] && continue
    cmp -s "$f" "licenses/$name" \
        || die "licenses/$name differs from the one of the FFmpeg build ($f): update licenses/ (book/src/install.md)"
done
export PKG_CONFIG_PATH="$prefix/lib/pkgconfig" PKG_CONFIG_ALL_STATIC=1
# zig compiles the C and C++ dependencies (HDF5, libjpeg-turbo, the compressors) and links the
# binary against glibc $glibc's symbols, as it compiled FFmpeg: a manylinux_2_28 wheel from this
# Debian 12 machine. Snappy (inside blosc) is C++: cc-rs names zig's own libc++, which zig links
# statically.
glibc=${CHUNKC_GLIBC:-2.28}
export CXXSTDLIB=c++
export CARGO_TARGET_DIR="$root/target/wheel"

# The licences of every crate compiled in, from Cargo.lock (licenses/THIRD-PARTY.md).
.venv/bin/python scripts/third_party.py >&2

say "maturin build (features static-ffmpeg; first build: HDF5 and ~220 crates, several minutes)"
rm -rf dist/chunkc-*.whl
maturin build --release --locked --out dist --zig --compatibility "manylinux_${glibc/./_}" \
    --auditwheel check "${quiet[@]}" >&2
wheel=$(ls dist/chunkc-*.whl)
say "checking $(basename "$wheel")"
.venv/bin/python scripts/wheel_check.py "$wheel" >&2
say "done in $(((SECONDS - start) / 60))m$(((SECONDS - start) % 60))s: $wheel"
echo "$wheel"
