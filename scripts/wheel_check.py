"""Checks a chunkc wheel before it ships (scripts/wheel.sh runs it; so does tests/python/test_wheel.py).

    python scripts/wheel_check.py dist/chunkc-*.whl

Fails (exit 1, naming what is wrong) unless:
  - the wheel holds the binary (`chunkc-<v>.data/scripts/chunkc`) and the `chunkc` package;
  - the binary needs no shared library but the C library family (libc, libm, libgcc_s, the
    dynamic loader, libpthread, libdl, librt): `readelf -d` lists its DT_NEEDED entries;
  - its FFmpeg is the LGPL build: libavcodec's licence string says LGPL, and neither x264,
    libpostproc nor FFmpeg's GPL configuration is inside;
  - the licences of chunkc and of everything linked are in `.dist-info/licenses`.
Prints the wheel's size, the installed size and `auditwheel show`'s platform tag.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

C_LIBRARY = re.compile(r"^(libc|libm|libgcc_s|libpthread|libdl|librt)\.so\.\d+$|^ld-linux[-\w.]*\.so\.\d+$")
LICENCES = [
    "LICENSE-MIT",
    "LICENSE-APACHE",
    "FFmpeg-COPYING.LGPLv2.1",
    "SVT-AV1-LICENSE.md",
    "SVT-AV1-PATENTS.md",
    "dav1d-COPYING",
    "HDF5-LICENSE",
    "libc++-LICENSE.TXT",
    "THIRD-PARTY.md",
    "rust-crates.txt",
]
# Strings that only a GPL FFmpeg or a GPL library would put into the binary.
# (Not "x264 - core": FFmpeg's own H.264 decoder holds it, to recognise x264's SEI banner.)
GPL_MARKS = [
    b"videolan.org/x264",  # x264's SEI banner, which its encoder writes into every stream
    b"libx264 H.264 / AVC",  # FFmpeg's libx264 wrapper (its long name)
    b"--enable-gpl",
    b"--enable-libx264",
    b"GPL version 2 or later",
    b"pp_postprocess",
    b"postproc_configuration",
]


def needed(binary: Path) -> list[str]:
    out = subprocess.run(["readelf", "-d", str(binary)], capture_output=True, text=True, check=True).stdout
    return re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]", out)


def check(wheel: Path) -> list[str]:
    problems = []
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
        binaries = [n for n in names if re.fullmatch(r"chunkc-[^/]+\.data/scripts/chunkc", n)]
        if len(binaries) != 1:
            return [f"{wheel.name}: no single chunkc binary in .data/scripts (found {binaries})"]
        for module in ("chunkc/__init__.py", "chunkc/__main__.py"):
            if module not in names:
                problems.append(f"{wheel.name}: no {module}")
        licences = {Path(n).name for n in names if re.match(r"chunkc-[^/]+\.dist-info/licenses/", n)}
        for name in LICENCES:
            if name not in licences:
                problems.append(f"{wheel.name}: no licence file {name} in .dist-info/licenses")
        installed = sum(i.file_size for i in z.infolist())
        with tempfile.TemporaryDirectory() as tmp:
            binary = Path(z.extract(binaries[0], tmp))
            libs = needed(binary)
            data = binary.read_bytes()
    foreign = [lib for lib in libs if not C_LIBRARY.match(lib)]
    if foreign:
        problems.append(f"the binary needs shared libraries outside the C library family: {foreign}")
    if b"LGPL version 2.1 or later" not in data:
        problems.append("the binary holds no LGPL FFmpeg (libavcodec's licence string is missing)")
    for mark in GPL_MARKS:
        if mark in data:
            problems.append(f"the binary holds {mark.decode()!r}: a GPL component is linked")
    print(f"{wheel.name}: {wheel.stat().st_size / 1e6:.1f} MB, {installed / 1e6:.1f} MB installed")
    print(f"binary needs: {', '.join(libs)}")
    try:
        show = subprocess.run(
            [sys.executable, "-m", "auditwheel", "show", str(wheel)], capture_output=True, text=True
        )
        tag = re.search(r'consistent with the following platform tag:\s*"([^"]+)"', show.stdout)
        print(f"auditwheel: {tag.group(1) if tag else show.stdout.strip() or show.stderr.strip()}")
    except OSError as e:
        print(f"auditwheel: not run ({e})")
    return problems


def main() -> int:
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    problems = check(Path(sys.argv[1]))
    for p in problems:
        print(f"wheel_check: {p}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
