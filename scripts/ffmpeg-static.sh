#!/usr/bin/env bash
# Builds the static, LGPL FFmpeg the wheel links (scripts/wheel.sh calls this), once per machine.
#
#   scripts/ffmpeg-static.sh        prints the install prefix (lib/, include/, lib/pkgconfig/,
#                                   licenses/) on stdout; progress goes to stderr
#
# Only what chunkc uses, and nothing under the GPL (book/src/install.md lists it):
#   - FFmpeg 5.1 (LGPL 2.1 or later): the file protocol, the mp4/mov demuxer and muxer, the
#     native h264, hevc, mpeg4 and vp9 decoders and their parsers, the native mpeg4 encoder (for
#     LeRobot cameras under SVT-AV1's 64x64 minimum), libswscale; no --enable-gpl,
#     no x264, no libpostproc, no libavfilter, no libavdevice, no network, no autodetected
#     system libraries;
#   - SVT-AV1 1.4 (BSD 3-Clause Clear + the AOMedia patent licence): the AV1 encoder, LeRobot's
#     default codec;
#   - dav1d 1.0 (BSD 2-Clause): the AV1 decoder.
# The sources are Debian 12's source packages (`apt-get source`, with the Debian patches); a
# `deb-src` entry is added for the download when the system has none (root), and removed after.
# They are compiled with `zig cc` against glibc $CHUNKC_GLIBC (default 2.28, the manylinux_2_28
# baseline; zig from the `ziglang` package in .venv) rather than the system's glibc, so that the
# binary linked with them runs on older systems than this one (scripts/wheel.sh links with zig too).
#
# The result is cached in ${CHUNKC_CACHE:-~/.cache/chunkc}/ffmpeg-static/<key>, where the key
# is this script's hash, the architecture and the glibc: a second run, or a fresh clone on the same machine, prints the prefix
# at once. Needs nasm, pkg-config, dpkg-source (dpkg-dev) and, from .venv, cmake, meson, ninja and
# ziglang; as root, the missing Debian packages are installed.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
say() { printf 'ffmpeg-static: %s\n' "$*" >&2; }
die() { printf 'ffmpeg-static: error: %s\n' "$*" >&2; exit 1; }

glibc=${CHUNKC_GLIBC:-2.28}
key=$(sha256sum "${BASH_SOURCE[0]}" | cut -c1-16)-$(uname -m)-glibc$glibc
cache=${CHUNKC_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/chunkc}/ffmpeg-static
prefix=$cache/$key
if [ -e "$prefix/.complete" ]; then
    echo "$prefix"
    exit 0
fi

# Tools. The Python ones come from the project venv (setup.sh creates it).
venv=$root/.venv
[ -x "$venv/bin/python" ] || die "no $venv: run scripts/setup.sh first"
export PATH="$venv/bin:$PATH"
quiet=(--quiet)
[ "${CHUNKC_VERBOSE:-0}" = 1 ] && quiet=()
for tool in meson ninja cmake ziglang; do
    if ! "$venv/bin/python" -c "import importlib.metadata as m, sys; m.version(sys.argv[1])" "$tool" 2>/dev/null; then
        pin=$(grep -E "^$tool==" "$root/tests/python/requirements.txt" || echo "$tool")
        say "installing $pin into .venv"
        "$venv/bin/python" -m pip install "${quiet[@]}" --disable-pip-version-check "$pin"
    fi
done
debian=()
command -v nasm >/dev/null || debian+=(nasm)
command -v pkg-config >/dev/null || debian+=(pkg-config)
command -v dpkg-source >/dev/null || debian+=(dpkg-dev)
command -v xz >/dev/null || debian+=(xz-utils)
if [ "${#debian[@]}" -gt 0 ]; then
    [ "$(id -u)" = 0 ] || die "missing ${debian[*]}: install them (apt-get install ${debian[*]})"
    say "apt-get install ${debian[*]}"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${debian[@]}" >&2 \
        || { apt-get update -qq >&2 && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${debian[@]}" >&2; }
fi

work=$(mktemp -d "${TMPDIR:-/tmp}/chunkc-ffmpeg.XXXXXX")
trap 'rm -rf "$work"' EXIT
stage=$work/prefix
jobs=$(nproc)

# The compilers: zig's clang, for this machine's architecture and an old glibc.
arch=$(uname -m)
mkdir -p "$work/bin"
for tool in cc c++; do
    # zig's clang makes __DATE__ an error (-Wdate-time); SVT-AV1 logs its build date.
    printf '#!/bin/sh\nexec "%s" -m ziglang %s -target %s-linux-gnu.%s -Wno-error=date-time "$@"\n' \
        "$venv/bin/python" "$tool" "$arch" "$glibc" >"$work/bin/zig-$tool"
    chmod +x "$work/bin/zig-$tool"
done
zcc=$work/bin/zig-cc
zcxx=$work/bin/zig-c++

# 1. The sources, with Debian's patches applied.
say "fetching the sources (apt-get source ffmpeg svt-av1 dav1d)"
src_entry=/etc/apt/sources.list.d/chunkc-debian-src.sources
added=0
if ! grep -rqsE '^(Types:.*deb-src|deb-src )' /etc/apt/sources.list /etc/apt/sources.list.d/; then
    [ "$(id -u)" = 0 ] || die "apt has no deb-src entry and this is not root: add one (book/src/install.md) or run as root"
    codename=$(. /etc/os-release && echo "${VERSION_CODENAME:-bookworm}")
    cat >"$src_entry" <<EOF
Types: deb-src
URIs: http://deb.debian.org/debian
Suites: $codename $codename-updates
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
EOF
    added=1
    apt-get update -qq >&2
fi
(cd "$work" && apt-get source -qq ffmpeg svt-av1 dav1d >&2) || {
    [ "$added" = 1 ] && rm -f "$src_entry"
    die "apt-get source failed"
}
if [ "$added" = 1 ]; then rm -f "$src_entry"; fi
dir() { find "$work" -maxdepth 1 -type d -name "$1-*" | head -n1; }
ffmpeg_src=$(dir ffmpeg)
svt_src=$(dir svt-av1)
dav1d_src=$(dir dav1d)
[ -n "$ffmpeg_src" ] && [ -n "$svt_src" ] && [ -n "$dav1d_src" ] || die "a source package is missing in $work"
log=$work/build.log
run() { "$@" >>"$log" 2>&1 || { tail -n 40 "$log" >&2; die "failed: $*"; }; }

# 2. SVT-AV1 (the encoder library only).
say "building $(basename "$svt_src") (static)"
run cmake -S "$svt_src" -B "$work/svt-build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_C_COMPILER="$zcc" -DCMAKE_CXX_COMPILER="$zcxx" \
    -DCMAKE_INSTALL_PREFIX="$stage" -DCMAKE_INSTALL_LIBDIR=lib -DBUILD_SHARED_LIBS=OFF \
    -DBUILD_APPS=OFF -DBUILD_DEC=OFF -DBUILD_TESTING=OFF -DCMAKE_POSITION_INDEPENDENT_CODE=ON \
    -DREPRODUCIBLE_BUILDS=ON
run cmake --build "$work/svt-build" -j "$jobs"
run cmake --install "$work/svt-build"

# 3. dav1d.
say "building $(basename "$dav1d_src") (static)"
CC=$zcc run meson setup "$work/dav1d-build" "$dav1d_src" --prefix="$stage" --libdir=lib \
    --buildtype=release --default-library=static -Denable_tools=false -Denable_tests=false \
    -Db_pie=true
run ninja -C "$work/dav1d-build" -j "$jobs"
run ninja -C "$work/dav1d-build" install

# 4. FFmpeg, LGPL: only the pieces chunkc calls.
say "building $(basename "$ffmpeg_src") (static, LGPL)"
(
    cd "$ffmpeg_src"
    export PKG_CONFIG_PATH=$stage/lib/pkgconfig
    run ./configure --prefix="$stage" --cc="$zcc" --cxx="$zcxx" --enable-static --disable-shared --enable-pic \
        --pkg-config-flags=--static --extra-libs="-lpthread -lm" \
        --disable-programs --disable-doc --disable-debug --disable-network --disable-autodetect \
        --disable-everything --disable-avdevice --disable-avfilter --disable-postproc \
        --enable-protocol=file --enable-demuxer=mov --enable-muxer=mp4,mov \
        --enable-decoder=h264,hevc,mpeg4,vp9,libdav1d \
        --enable-parser=h264,hevc,mpeg4video,vp9,av1 \
        --enable-bsf=h264_mp4toannexb,hevc_mp4toannexb,extract_extradata,av1_frame_split,vp9_superframe_split \
        --enable-libdav1d --enable-libsvtav1 --enable-encoder=libsvtav1,mpeg4 \
        --enable-swscale --enable-swresample
    # zig's glibc headers are the newest glibc's, which dropped sys/sysctl.h (2.32), while its
    # 2.28 link stubs still have sysctl(): configure finds the function, cpu.c the header missing.
    sed -i 's/^#define HAVE_SYSCTL 1$/#define HAVE_SYSCTL 0/' config.h
    grep -q "License: LGPL" ffbuild/config.log 2>/dev/null || grep -q 'FFMPEG_LICENSE "LGPL' config.h \
        || die "FFmpeg's configure did not settle on an LGPL licence"
    run make -j "$jobs"
    run make install
)

# 5. The licences, for the wheel.
mkdir -p "$stage/licenses"
cp "$ffmpeg_src/COPYING.LGPLv2.1" "$stage/licenses/FFmpeg-COPYING.LGPLv2.1"
cp "$ffmpeg_src/LICENSE.md" "$stage/licenses/FFmpeg-LICENSE.md"
cp "$svt_src/LICENSE.md" "$stage/licenses/SVT-AV1-LICENSE.md"
cp "$svt_src/PATENTS.md" "$stage/licenses/SVT-AV1-PATENTS.md"
cp "$dav1d_src/COPYING" "$stage/licenses/dav1d-COPYING"
{
    echo "FFmpeg $(basename "$ffmpeg_src" | sed 's/^ffmpeg-//'), Debian's source package, LGPL 2.1 or later"
    echo "SVT-AV1 $(basename "$svt_src" | sed 's/^svt-av1-//'), Debian's source package, BSD 3-Clause Clear"
    echo "dav1d $(basename "$dav1d_src" | sed 's/^dav1d-//'), Debian's source package, BSD 2-Clause"
    echo "compiled with zig $("$venv/bin/python" -m ziglang version) for $arch-linux-gnu.$glibc"
} >"$stage/licenses/VERSIONS"
grep -rq "x264\|postproc" "$stage/lib/pkgconfig" && die "a GPL library slipped into the pkg-config files"

mkdir -p "$cache"
rm -rf "$prefix"
mv "$stage" "$prefix"
# pkg-config files name the staging prefix; point them at the cache.
sed -i "s|$stage|$prefix|g" "$prefix"/lib/pkgconfig/*.pc
touch "$prefix/.complete"
say "done: $prefix"
echo "$prefix"
