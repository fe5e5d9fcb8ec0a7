"""The wheel, installed the way a user installs it (scripts/wheel.sh builds it; book: Install).

A fresh venv gets the wheel with `pip install --no-index`; the installed `chunkc` then runs from
a directory outside the checkout with a PATH that holds only that venv (no cargo, rustc, cmake or
system FFmpeg tools). Its outputs are compared with the developer build's (target/release/chunkc,
linked to the system FFmpeg) byte for byte; the videos it encodes itself (SVT-AV1, its only
encoder) are read back with PyAV.

The wheel is $CHUNKC_WHEEL (scripts/test.sh builds it and sets it: a missing file fails), else the
newest dist/chunkc-*.whl; with neither, these tests skip.
"""

import filecmp
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
from wheel_check import C_LIBRARY, GPL_MARKS  # noqa: E402

from conftest import PUSHT, REPO, VIDEO_BACKENDS, RawSource, chunkc_bin, lerobot_dataset, write_spec

DATA = REPO / "tests" / "data"


def wheel_path():
    given = os.environ.get("CHUNKC_WHEEL")
    if given:
        return Path(given)
    built = sorted((REPO / "dist").glob("chunkc-*.whl"), key=lambda p: p.stat().st_mtime)
    return built[-1] if built else None


WHEEL = wheel_path()
pytestmark = pytest.mark.skipif(WHEEL is None, reason="no wheel: run scripts/wheel.sh (scripts/test.sh does)")


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(venv, env): the wheel installed into a fresh venv, and the environment to run it in."""
    assert WHEEL.is_file(), f"CHUNKC_WHEEL={WHEEL} is not a file: scripts/wheel.sh failed?"
    d = tmp_path_factory.mktemp("wheel")
    venv = d / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    pip = subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "--no-index",
                          "--disable-pip-version-check", "--quiet", str(WHEEL)],
                         capture_output=True, text=True)
    assert pip.returncode == 0, pip.stderr
    env = {"PATH": str(venv / "bin"), "HOME": str(d), "LANG": "C.UTF-8"}
    for tool in ("cargo", "rustc", "cmake", "ffmpeg", "pkg-config"):
        assert shutil.which(tool, path=env["PATH"]) is None, f"{tool} is on the test's PATH"
    return venv, env


def wheel_run(installed, *args, cwd, python=False, check=True):
    venv, env = installed
    cmd = [str(venv / "bin" / "python"), "-m", "chunkc"] if python else ["chunkc"]
    exe = shutil.which(cmd[0], path=env["PATH"])
    assert exe is not None and exe.startswith(str(venv)), f"{cmd[0]} is not the venv's: {exe}"
    proc = subprocess.run([exe, *cmd[1:], *map(str, args)], cwd=cwd, env=env, capture_output=True, text=True)
    if check:
        assert proc.returncode == 0, f"wheel chunkc {args} failed:\n{proc.stderr}"
    return proc


def dev_run(*args, cwd, check=True):
    proc = subprocess.run([chunkc_bin(), *map(str, args)], cwd=cwd, capture_output=True, text=True,
                          env={**os.environ, "LANG": "C.UTF-8"})
    if check:
        assert proc.returncode == 0, f"developer chunkc {args} failed:\n{proc.stderr}"
    return proc


def tree(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())


def assert_same_tree(a: Path, b: Path):
    files = tree(a)
    assert files == tree(b), f"the wheel's and the developer build's outputs hold different files"
    different = [f for f in files if not filecmp.cmp(a / f, b / f, shallow=False)]
    assert not different, f"{len(different)} of {len(files)} files differ: {different[:10]}"
    return files


def both(installed, tmp_path, spec_text: str, *args):
    """Writes the spec into tmp/wheel and tmp/dev, builds it with each binary there, and returns
    the two directories (outputs go to each directory's `out/`)."""
    dirs = []
    for name in ("wheel", "dev"):
        d = tmp_path / name
        d.mkdir()
        (d / "spec.toml").write_text(spec_text)
        dirs.append(d)
    wheel_run(installed, "build", "-q", *args, "spec.toml", cwd=dirs[0])
    dev_run("build", "-q", *args, "spec.toml", cwd=dirs[1])
    return dirs


def test_version_both_ways(installed, tmp_path):
    dev = dev_run("--version", cwd=tmp_path).stdout
    assert wheel_run(installed, "--version", cwd=tmp_path).stdout == dev
    assert wheel_run(installed, "--version", cwd=tmp_path, python=True).stdout == dev
    assert dev.startswith("chunkc ")


def test_binary_needs_only_the_c_library(installed):
    venv, _ = installed
    out = subprocess.run(["ldd", str(venv / "bin" / "chunkc")], capture_output=True, text=True, check=True).stdout
    libs = [line.split()[0] for line in out.splitlines() if line.strip()]
    assert libs, out
    foreign = [lib for lib in libs if lib != "linux-vdso.so.1" and not C_LIBRARY.match(Path(lib).name)]
    assert not foreign, f"ldd lists libraries outside the C library family:\n{out}"


def test_installed_size_and_licences(installed):
    venv, _ = installed
    site = next((venv / "lib").glob("python3*/site-packages"))
    files = [venv / "bin" / "chunkc", *(site / "chunkc").rglob("*"), *next(site.glob("chunkc-*.dist-info")).rglob("*")]
    size = sum(f.stat().st_size for f in files if f.is_file())
    print(f"installed size: {size / 1e6:.1f} MB")
    assert size < 60e6, f"the installed wheel takes {size / 1e6:.1f} MB (goal: under 60)"
    licences = {p.name for p in next(site.glob("chunkc-*.dist-info")).rglob("*") if p.is_file()}
    for name in ("LICENSE-MIT", "LICENSE-APACHE", "FFmpeg-COPYING.LGPLv2.1", "SVT-AV1-LICENSE.md",
                 "dav1d-COPYING", "HDF5-LICENSE", "THIRD-PARTY.md", "rust-crates.txt"):
        assert name in licences, f"{name} is not installed with the wheel"


def test_wheel_check_passes():
    """scripts/wheel_check.py on the wheel: only the C library, an LGPL FFmpeg, no GPL marks."""
    proc = subprocess.run([sys.executable, str(REPO / "scripts" / "wheel_check.py"), str(WHEEL)],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_platform_tag_is_what_auditwheel_finds():
    """The wheel's name claims a manylinux tag; auditwheel, reading the binary's versioned glibc
    symbols, must find the same one (no symbol newer than the tag's glibc)."""
    claimed = WHEEL.name.rsplit("-", 1)[1].removesuffix(".whl")
    show = subprocess.run([sys.executable, "-m", "auditwheel", "show", str(WHEEL)], capture_output=True, text=True)
    assert show.returncode == 0, show.stderr
    found = re.search(r'platform tag:\s*"([^"]+)"', show.stdout)
    assert found, show.stdout
    assert found.group(1) == claimed, show.stdout
    assert re.fullmatch(r"manylinux_2_(\d+)_\w+", claimed), claimed


def test_gpl_marks_are_found_in_a_gpl_build():
    """The oracle of the check above: each GPL mark it looks for is found in the GPL libraries the
    developer build loads (Debian's FFmpeg, built with --enable-gpl, and libx264), and the
    libpostproc marks in Debian's libpostproc, where it is installed."""
    out = subprocess.run(["ldd", chunkc_bin()], capture_output=True, text=True).stdout
    libs = [Path(p) for p in re.findall(r"=> (\S+)", out)]
    if not any("libavcodec" in p.name for p in libs):
        pytest.skip("the developer build links no shared libavcodec")
    libs += list(Path("/usr/lib").glob("*-linux-gnu/libpostproc.so.*"))
    data = [p.read_bytes() for p in libs]
    for mark in GPL_MARKS:
        if b"postproc" in mark and not any("libpostproc" in p.name for p in libs):
            continue
        assert any(mark in d for d in data), f"{mark!r} is in none of {[p.name for p in libs]}"


def test_demo_spec_byte_identical(installed, tmp_path):
    """specs/pusht.toml (the README's demo) built by the wheel = the developer build, every file."""
    text = (REPO / "specs" / "pusht.toml").read_text()
    text = text.replace('"../tests/data/pusht_subset.zarr"', f'"{PUSHT}"').replace('"../out/pusht"', '"out"')
    assert str(PUSHT) in text
    w, d = both(installed, tmp_path, text)
    files = assert_same_tree(w / "out", d / "out")
    assert any(f.endswith("data.h5") for f in files), files


@pytest.mark.parametrize("source", ["pusht_subset.zarr", "lerobot_video_v21", "lerobot_video_v3_av1"])
def test_init_then_build_byte_identical(installed, tmp_path, source):
    """`chunkc init` and `chunkc build` on a vendored set: the same spec and the same bytes from both
    builds. The LeRobot sets' frames are H.264 (v2.1) and AV1 (v3.0) videos: the wheel decodes them
    with FFmpeg's own H.264 decoder and dav1d, statically linked, into the same pixels."""
    specs = []
    for name, run in (("wheel", lambda *a, cwd: wheel_run(installed, *a, cwd=cwd)), ("dev", dev_run)):
        d = tmp_path / name
        d.mkdir()
        run("init", DATA / source, "--out", "spec.toml", cwd=d)
        specs.append((d / "spec.toml").read_text())
        run("build", "-q", "spec.toml", cwd=d)
    assert specs[0] == specs[1]
    files = assert_same_tree(tmp_path / "wheel", tmp_path / "dev")
    meta = [f for f in files if f.endswith("meta.json")]
    assert meta, files
    if source.startswith("lerobot_video"):
        # The frames are in the outputs: an image channel with its shape.
        assert any("observation.images" in (tmp_path / "wheel" / m).read_text() for m in meta)


def decode_all(path: Path):
    import av

    with av.open(str(path)) as c:
        stream = c.streams.video[0]
        codec = stream.codec_context.name
        frames = [f.to_ndarray(format="rgb24") for f in c.decode(stream)]
    return codec, np.stack(frames)


def psnr(a, b):
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return 10 * np.log10(255.0**2 / mse)




def test_hdf5_video_storage_is_av1_and_read_by_pyav(installed, tmp_path):
    """hdf5 `image_compression = "video"` in the wheel: x264's default becomes SVT-AV1 (no GPL
    encoder inside), every episode's mp4 decodes with PyAV to the source's frames, near-lossless."""
    write_spec(tmp_path, '[profiles.dp]\npreset = "diffusion_policy"\nformat = "hdf5"\nimage_compression = "video"')
    wheel_run(installed, "build", "-q", "spec.toml", cwd=tmp_path)
    videos = sorted((tmp_path / "out" / "dp").rglob("episode_*.mp4"))
    src = RawSource()
    assert len(videos) == len(src.ends), videos
    for e, path in enumerate(videos):
        codec, frames = decode_all(path)
        assert codec in ("av1", "libdav1d", "libaom-av1"), f"{path.name}: {codec}"
        raw = src.episode("img", e)
        assert frames.shape == raw.shape, (path.name, frames.shape, raw.shape)
        assert psnr(frames, raw) > 30, f"{path.name}: PSNR {psnr(frames, raw):.1f} dB"
    # meta.json says what the files hold, as PyAV reads it (from the encoder's configuration).
    av = pytest.importorskip("av")
    meta = json.loads((tmp_path / "out" / "dp" / "meta.json").read_text())
    storage = meta["channels"]["observation.image"]["storage"]
    with av.open(str(videos[0])) as c:
        ctx = c.streams.video[0].codec_context
        read = (ctx.codec.canonical_name, ctx.profile, ctx.format.name)
    assert (storage["codec"], storage["profile"], storage["pix_fmt"]) == read
    assert storage["stored"] == "encoded" and storage["encoder"] == "libsvtav1"


@pytest.fixture(scope="module")
def lerobot_export(installed, tmp_path_factory):
    """The wheel's LeRobot export of Push-T with video (SVT-AV1, the wheel's only encoder)."""
    d = tmp_path_factory.mktemp("wheel_lerobot")
    write_spec(d, '[profiles.lr]\npreset = "lerobot_diffusion"\nformat = "parquet"\nimage_encoding = "video"')
    wheel_run(installed, "build", "-q", "spec.toml", cwd=d)
    return d / "out" / "lr"


def test_lerobot_video_export_read_by_pyav(lerobot_export):
    """The LeRobot export with video from the wheel: one AV1 mp4 per camera, every frame read back
    by PyAV, in order, close to the source."""
    videos = sorted((lerobot_export / "videos").rglob("*.mp4"))
    assert len(videos) == 1, videos
    codec, frames = decode_all(videos[0])
    assert codec in ("av1", "libdav1d", "libaom-av1"), codec
    raw = RawSource().array("img")
    assert frames.shape == raw.shape, (frames.shape, raw.shape)
    assert psnr(frames, raw) > 30, f"PSNR {psnr(frames, raw):.1f} dB"


@pytest.mark.parametrize("backend", VIDEO_BACKENDS)
def test_lerobot_opens_the_wheels_export(lerobot_export, backend):
    """LeRobot's own `LeRobotDataset`, with its default video backend (torchcodec) and with pyav,
    opens the wheel's export: the source's actions, and each row's frame as PyAV decodes it."""
    ds = lerobot_dataset("chunkc/wheel", lerobot_export, backend)
    src = RawSource()
    action = src.array("action")
    _, frames = decode_all(next((lerobot_export / "videos").rglob("*.mp4")))
    assert len(ds) == len(action) == len(frames)
    for i in sorted({0, 1, len(ds) - 1, *range(0, len(ds), 97)}):
        item = ds[i]
        np.testing.assert_array_equal(item["action"].numpy(), action[i].astype(np.float32))
        hwc = np.round(item["observation.image"].numpy().transpose(1, 2, 0) * 255).astype(np.uint8)
        np.testing.assert_array_equal(hwc, frames[i], err_msg=f"row {i}")


def test_malformed_spec_same_message(installed, tmp_path):
    """`chunkc check` on a malformed spec: the wheel says what the developer build says."""
    bad = sorted((REPO / "tests" / "specs_bad").glob("*.toml"))
    assert len(bad) > 5
    for spec in bad[:: max(1, len(bad) // 8)]:
        shutil.copy(spec, tmp_path / spec.name)
        w = wheel_run(installed, "check", spec.name, cwd=tmp_path, check=False)
        d = dev_run("check", spec.name, cwd=tmp_path, check=False)
        assert w.returncode != 0 and w.returncode == d.returncode, (spec.name, w.returncode, d.returncode)
        assert w.stderr == d.stderr and w.stdout == d.stdout, spec.name


def test_libx264_is_refused_at_its_key(installed, tmp_path):
    """A spec asking for x264 explicitly: the wheel (no GPL encoder) refuses it at `video_codec`,
    before writing anything; the developer build (system FFmpeg, with x264) accepts it."""
    write_spec(tmp_path, '[profiles.dp]\npreset = "diffusion_policy"\nformat = "hdf5"\n'
               'image_compression = "video"\nvideo_codec = "libx264"')
    w = wheel_run(installed, "build", "spec.toml", cwd=tmp_path, check=False)
    assert w.returncode != 0
    assert "profiles.dp.video_codec" in w.stderr and "libx264" in w.stderr, w.stderr
    assert not (tmp_path / "out").exists()
    dev_run("check", "spec.toml", cwd=tmp_path)
