"""Stream copy in `image_compression = "video"` (issue 31): where an episode's camera frames are a
source video's own (same rate, no resize), the episode's mp4 holds the source's packets, not a
new encode.

Oracles, all independent of chunkc's writer:
- PyAV's demuxer: the stored file's packets are byte for byte the source file's packets of the
  episode's span (`bytes(packet)`), keyframe flags included;
- the same build's `image_compression = "none"` profile (frames chunkc decoded from the source,
  which `test_lerobot_video` checks against LeRobotDataset): PyAV's decode of a copied file and
  the generated loader both give exactly those pixels (a copy loses nothing);
- where the packets cannot stand alone (an episode that starts between keyframes, another codec
  asked for, a resize, `video_copy = false`), the file is a fresh encode, and the loader still
  returns exactly PyAV's decode of it.
"""

import json
import shutil
from fractions import Fraction

import h5py
import numpy as np
import pytest

from conftest import REPO, build_with_video as build, import_loader, run_chunkc

av = pytest.importorskip("av")

DATA = REPO / "tests" / "data"
V21 = DATA / "lerobot_video_v21"  # H.264 with B-frames, one file per episode (episode 2: MPEG-4)
V3 = DATA / "lerobot_video_v3_av1"  # AV1 g=2, the three episodes in one file per camera
TOP = "observation.images.top"


def spec(tmp_path, source, profiles, cam=TOP):
    path = tmp_path / "spec.toml"
    path.write_text("\n".join([
        "version = 1", "[source]", 'format = "lerobot"', f'path = "{source}"', "[source.channels]",
        'action = "action"', '"observation.state" = "observation.state"', f'"{cam}" = "{cam}"',
        "[split]", "val_fraction = 0.0", "[output]", 'dir = "out"',
        "[profiles.raw]", 'preset = "diffusion_policy"', "fps = 10", profiles,
    ]) + "\n")
    return path


def video_profile(name="video", extra=""):
    return f'[profiles.{name}]\npreset = "diffusion_policy"\nfps = 10\nimage_compression = "video"\n{extra}\n'


def stored(root, cam=TOP):
    with h5py.File(root / "data.h5", "r") as f:
        paths = [p.decode() for p in f[f"videos/{cam}/path"][:]]
        copied = f[f"videos/{cam}/copied"][:].tolist()
    return paths, copied


def raw_frames(root, cam=TOP):
    with h5py.File(root / "data.h5", "r") as f:
        return f[f"data/{cam}"][:]


def decode(path):
    with av.open(str(path)) as c:
        return [f.to_ndarray(format="rgb24") for f in c.decode(video=0)]


def packets(path, lo=None, hi=None):
    """(payload, keyframe) of the file's video packets in decode order whose presentation time
    is in [lo, hi) seconds (all when not given)."""
    out = []
    with av.open(str(path)) as c:
        s = c.streams.video[0]
        for p in c.demux(s):
            if p.size == 0:
                continue
            t = float(p.pts * s.time_base)
            if lo is None or lo - 1e-4 <= t < hi - 1e-4:
                out.append((bytes(p), p.is_keyframe))
    return out


def source_spans(source, cam=TOP):
    """Per episode: its file and [from, to) in seconds, from the dataset's own metadata."""
    info = json.loads((source / "meta" / "info.json").read_text())
    if info["codebase_version"].startswith("v2"):
        files = sorted((source / "videos" / "chunk-000" / cam).glob("*.mp4"))
        return [(f, None, None) for f in files]
    import pandas as pd

    eps = pd.read_parquet(source / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    f = source / "videos" / cam / "chunk-000" / "file-000.mp4"
    return [(f, r[f"videos/{cam}/from_timestamp"], r[f"videos/{cam}/to_timestamp"]) for _, r in eps.iterrows()]


def assert_loader_gives(root, want, cam=TOP):
    ds = import_loader(root).ChunkedDataset(str(root))
    rows = np.random.default_rng(0).permutation(len(want))
    np.testing.assert_array_equal(ds._read(cam, rows), want[rows])


@pytest.mark.parametrize("source", [V21, V3], ids=["v21-h264-bframes", "v30-av1-shared-file"])
def test_source_packets_are_copied_and_decode_to_the_source_frames(tmp_path, source):
    build(spec(tmp_path, source, video_profile()))
    root = tmp_path / "out" / "video"
    paths, copied = stored(root)
    assert copied == [1] * len(paths)
    # Packet for packet the source's, episode by episode.
    for p, (f, lo, hi) in zip(paths, source_spans(source)):
        assert packets(root / p) == packets(f, lo, hi), p
    # Lossless: exactly the frames the raw profile holds (decoded from the source).
    want = raw_frames(tmp_path / "out" / "raw")
    got = np.concatenate([np.stack(decode(root / p)) for p in paths])
    np.testing.assert_array_equal(got, want)
    assert_loader_gives(root, want)
    lock = json.loads((tmp_path / "chunkc.lock").read_text())["specs"]["spec.toml"]["profiles"]
    assert lock["video"]["encoder"]["settings"]["stream_copy"] == "any codec"
    size = sum((root / p).stat().st_size for p in paths)
    src = sum(f.stat().st_size for f in {f for f, _, _ in source_spans(source)})
    assert size <= 1.2 * src, (size, src)


@pytest.mark.parametrize("extra, copied", [
    ("video_copy = false", [0, 0, 0]),
    # Only H.264 streams are kept when the spec asks for libx264: episode 2 of the fixture is
    # MPEG-4.
    ('video_codec = "libx264"', [1, 1, 0]),
    ('[profiles.video.cameras."observation.images.top"]\nsize = [64, 64]', [0, 0, 0]),
])
def test_what_is_not_the_source_stream_is_encoded(tmp_path, extra, copied):
    build(spec(tmp_path, V21, video_profile(extra=extra)))
    root = tmp_path / "out" / "video"
    paths, got = stored(root)
    assert got == copied
    for p in paths:  # fresh encodes are x264's; the copies here are of H.264 episodes
        with av.open(str(root / p)) as c:
            assert c.streams.video[0].codec_context.name == "h264", p
    want = np.concatenate([np.stack(decode(root / p)) for p in paths])
    assert_loader_gives(root, want)
    if "size" not in extra:
        raw = raw_frames(tmp_path / "out" / "raw")
        for i, (p, was_copied) in enumerate(zip(paths, got)):
            frames = np.stack(decode(root / p))
            lo = sum(len(decode(root / q)) for q in paths[:i])
            if was_copied:
                np.testing.assert_array_equal(frames, raw[lo:lo + len(frames)])
            else:  # a second generation of loss, small
                assert np.abs(frames.astype(int) - raw[lo:lo + len(frames)]).mean() < 8


def reencode_with_gop(source, out, gop):
    """The v3.0 fixture with its shared top-camera file encoded again as H.264 with a keyframe
    every `gop` frames exactly, no B-frames: with 20-frame episodes and gop 8, episode 1 starts
    at frame 20, between keyframes 16 and 24."""
    shutil.copytree(source, out)
    f = out / "videos" / TOP / "chunk-000" / "file-000.mp4"
    frames = decode(f)
    f.unlink()
    with av.open(str(f), "w") as c:
        s = c.add_stream("libx264", rate=10)
        s.width, s.height, s.pix_fmt = frames[0].shape[1], frames[0].shape[0], "yuv420p"
        s.options = {"x264-params": f"keyint={gop}:min-keyint={gop}:scenecut=0:bframes=0", "crf": "18"}
        s.codec_context.time_base = Fraction(1, 10)
        for i, a in enumerate(frames):
            vf = av.VideoFrame.from_ndarray(a, format="rgb24")
            vf.pts = i
            for p in s.encode(vf):
                c.mux(p)
        for p in s.encode():
            c.mux(p)
    info = json.loads((out / "meta" / "info.json").read_text())
    info["features"][TOP]["info"]["video.codec"] = "h264"
    (out / "meta" / "info.json").write_text(json.dumps(info, indent=4))
    return out


def test_an_episode_between_keyframes_is_encoded(tmp_path):
    source = reencode_with_gop(V3, tmp_path / "src", gop=8)
    build(spec(tmp_path, source, video_profile()))
    root = tmp_path / "out" / "video"
    paths, copied = stored(root)
    # Episodes 0 and 2 start on keyframes 0 and 40; episode 1 at 20 does not.
    assert copied == [1, 0, 1]
    raw = raw_frames(tmp_path / "out" / "raw")
    decoded = [np.stack(decode(root / p)) for p in paths]
    np.testing.assert_array_equal(decoded[0], raw[:20])
    np.testing.assert_array_equal(decoded[2], raw[40:])
    assert np.abs(decoded[1].astype(int) - raw[20:40]).mean() < 8
    assert_loader_gives(root, np.concatenate(decoded))
    # A profile whose random-access bound is shorter than the source's GOP encodes everything.
    shutil.rmtree(tmp_path / "out")
    (tmp_path / "chunkc.lock").unlink()
    build(spec(tmp_path, source, video_profile(extra="video_gop = 4")))
    assert stored(tmp_path / "out" / "video")[1] == [0, 0, 0]


def test_copied_bytes_do_not_depend_on_threads_or_shards(tmp_path):
    files = {}
    for how in ("j1", "j2", "shards"):
        d = tmp_path / how
        d.mkdir()
        path = spec(d, V3, video_profile())
        if how == "shards":
            for i in range(2):
                run_chunkc("build", "-q", "--shard", f"{i}/2", "--partials", d / "parts", path)
            run_chunkc("merge", "-q", "--partials", d / "parts", path)
        else:
            build(path, "-j", how[1])
        root = d / "out" / "video"
        files[how] = {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}
    assert stored(tmp_path / "j1" / "out" / "video")[1] == [1, 1, 1]
    assert files["j1"] == files["j2"] == files["shards"]


def video_only_spec(tmp_path, extra=""):
    """The video profile alone: no other sink wants the frames' pixels."""
    path = spec(tmp_path, V3, video_profile(extra=extra))
    text = path.read_text()
    text = text.replace('[profiles.raw]\npreset = "diffusion_policy"\nfps = 10\n', "")
    path.write_text(text)
    return path


@pytest.mark.parametrize("copy", [True, False])
def test_partials_hold_the_packets_place_not_the_frames_of_a_copy(tmp_path, copy):
    """A shard whose frames every sink copies from the source's packets writes where the packets
    are, not the decoded frames (at DROID's scale the frames are terabytes: the scale chapter);
    the merge copies them, giving the single build's bytes. Frames that are encoded keep their
    pixels in the partial. The oracle for size: the frames' decoded bytes (PyAV)."""
    files = {}
    for how in ("one", "shards"):
        d = tmp_path / how
        d.mkdir()
        path = video_only_spec(d, "" if copy else "video_copy = false")
        if how == "shards":
            for i in range(2):
                run_chunkc("build", "-q", "--shard", f"{i}/2", "--partials", d / "parts", path)
            run_chunkc("merge", "-q", "--partials", d / "parts", path)
        else:
            build(path)
        root = d / "out" / "video"
        files[how] = {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}
    assert files["one"] == files["shards"]
    assert stored(tmp_path / "one" / "out" / "video")[1] == ([1, 1, 1] if copy else [0, 0, 0])
    decoded = sum(f.nbytes for v in sorted((V3 / "videos" / TOP).rglob("*.mp4")) for f in decode(v))
    partials = sum(p.stat().st_size for p in (tmp_path / "shards" / "parts").glob("*.partial"))
    if copy:
        assert partials < decoded / 10, (partials, decoded)
    else:
        assert partials > decoded, (partials, decoded)


def test_a_source_changed_between_shards_and_merge_fails_naming_it(tmp_path):
    """The merge copies what the shards left to a copy; a source whose video changed since (a
    copy now refused) fails naming the file, and writes nothing."""
    source = tmp_path / "src"
    shutil.copytree(V3, source)
    path = spec(tmp_path, source, video_profile())
    path.write_text(path.read_text().replace('[profiles.raw]\npreset = "diffusion_policy"\nfps = 10\n', ""))
    for i in range(2):
        run_chunkc("build", "-q", "--shard", f"{i}/2", "--partials", tmp_path / "parts", path)
    video = sorted((source / "videos" / TOP).rglob("*.mp4"))[0]
    video.write_bytes(video.read_bytes()[: video.stat().st_size // 2])
    p = run_chunkc("merge", "-q", "--partials", tmp_path / "parts", path, check=False)
    assert p.returncode != 0
    assert str(video) in p.stderr or video.name in p.stderr, p.stderr
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").rglob("meta.json"))


@pytest.mark.parametrize("keys, message", [
    ("video_copy = false", "`video_copy` sets the video encoder, but profile `bad` stores no video"),
    ('format = "parquet"\nvideo_copy = true',
     "`video_copy` sets the video encoder, but profile `bad` stores frames as PNG"),
])
def test_video_copy_without_video_is_a_spec_error(tmp_path, keys, message):
    path = spec(tmp_path, V21, f'[profiles.bad]\npreset = "diffusion_policy"\nfps = 10\n{keys}\n')
    proc = run_chunkc("build", "-q", path, check=False)
    assert proc.returncode == 2, proc.stderr
    assert message in proc.stderr
    assert "spec.toml:" in proc.stderr
    assert not (tmp_path / "out").exists()


def test_a_synthesized_lerobot_set_seeks_like_lerobots_and_is_copied(tmp_path):
    """`chunkc synth --format lerobot` encodes as LeRobot does, keyframe every 2 frames included
    (what LeRobot's decoders seek to), so every episode of its shared files is copied."""
    run_chunkc("synth", "--format", "lerobot", "--episodes", "3", "--steps", "21", "--cameras", "1",
               "--resolution", "64x64", "--fps", "10", tmp_path / "syn")
    source = tmp_path / "syn" / "lerobot"
    cam = "observation.images.cam0"
    f = source / "videos" / cam / "chunk-000" / "file-000.mp4"
    with av.open(str(f)) as c:
        keys = [p.is_keyframe for p in c.demux(c.streams.video[0]) if p.size]
    assert len(keys) == 63 and [i for i, k in enumerate(keys) if k] == list(range(0, 63, 2))
    path = tmp_path / "spec.toml"
    path.write_text("\n".join([
        "version = 1", "[source]", 'format = "lerobot"', f'path = "{source}"', "[source.channels]",
        'action = "action"', f'"{cam}" = "{cam}"', "[split]", "val_fraction = 0.0", "[output]", 'dir = "out"',
        video_profile(),
    ]) + "\n")
    build(path)
    # 21-frame episodes start on frames 0, 21 and 42: only 0 and 42 are keyframes.
    assert stored(tmp_path / "out" / "video", cam)[1] == [1, 0, 1]


def test_the_default_copies_a_source_with_longer_gops(tmp_path):
    """A real LeRobot set's MPEG-4 files put keyframes 12 apart where chunkc's encoder writes
    8: the default `video_gop` (unset) follows the source's when it copies, so every episode is
    copied (issue 37: none was, and the build re-encoded 43 episodes in 254 s). The attributes
    then describe the stored streams, not the encoder; a `video_gop` the spec sets below the
    source's refuses the copy and records why."""
    source = reencode_with_gop(V3, tmp_path / "src", gop=20)  # keyframes on every episode start
    said = build(spec(tmp_path, source, video_profile())).stderr
    assert f"video: videos `{TOP}`: 3 of 3 episodes copied from the source's stream" in said, said
    root = tmp_path / "out" / "video"
    paths, copied = stored(root)
    assert copied == [1, 1, 1]
    with h5py.File(root / "data.h5", "r") as f:
        attrs = dict(f[f"videos/{TOP}"].attrs)
    assert attrs["stored"] == "copied"
    assert attrs["codec"] == "h264" and attrs["crf"] == -1 and attrs["gop"] == -1
    assert "copy_refused" not in attrs
    # The stored stream is what the attribute says (PyAV, the real reader).
    with av.open(str(root / paths[0])) as c:
        assert c.streams.video[0].codec_context.name == "h264"
    shutil.rmtree(tmp_path / "out")
    (tmp_path / "chunkc.lock").unlink()
    said = build(spec(tmp_path, source, video_profile(extra="video_gop = 8"))).stderr
    _, copied = stored(tmp_path / "out" / "video")
    assert copied == [0, 0, 0]
    # The build says why, and which key changes it.
    assert f"video: videos `{TOP}`: 0 of 3 episodes copied" in said, said
    assert "set `video_gop = 20`" in said, said
    with h5py.File(tmp_path / "out" / "video" / "data.h5", "r") as f:
        attrs = dict(f[f"videos/{TOP}"].attrs)
    assert attrs["stored"] == "encoded" and attrs["codec"] == "h264" and attrs["crf"] == 23
    assert attrs["encoder"] == "libx264"
    refused = attrs["copy_refused"]
    assert "keyframes 20 frames apart, more than `video_gop` = 8" in refused, refused
    assert "set `video_gop = 20`" in refused and "episodes 0, 1, 2" in refused, refused


def formats_read(root, paths):
    """{(codec, profile, pixel format): files} of the stored files, as PyAV reads them."""
    found = {}
    for p in paths:
        with av.open(str(root / p)) as c:
            ctx = c.streams.video[0].codec_context
            key = (ctx.codec.canonical_name, ctx.profile, ctx.format.name)
        found[key] = found.get(key, 0) + 1
    return found


@pytest.mark.parametrize("source, extra, codecs, stored_as", [
    (V21, "", {"h264", "mpeg4"}, "copied"),  # episodes 0-1 H.264, episode 2 MPEG-4
    (V21, "video_copy = false", {"h264"}, "encoded"),
    (V21, 'video_codec = "libx264"', {"h264"}, "mixed"),  # H.264 kept, MPEG-4 re-encoded
    (V3, "", {"av1"}, "copied"),
    (V3, "video_copy = false", {"h264"}, "encoded"),
], ids=["h264+mpeg4-copied", "h264+mpeg4-encoded", "h264-copied-mpeg4-encoded", "av1-copied", "av1-encoded"])
def test_meta_json_says_what_the_stored_streams_hold(tmp_path, source, extra, codecs, stored_as):
    """meta.json's codec, profile and pixel format of a video camera are what PyAV reads from
    the stored files, whether they were copied from an AV1, H.264 or MPEG-4 source or encoded;
    the HDF5 group's attributes say the same; and the loader refuses a file that holds another
    codec than meta.json says."""
    build(spec(tmp_path, source, video_profile(extra=extra)))
    root = tmp_path / "out" / "video"
    paths, copied = stored(root)
    storage = json.loads((root / "meta.json").read_text())["channels"][TOP]["storage"]
    found = formats_read(root, paths)
    assert {c for c, _, _ in found} == codecs
    assert {(s["codec"], s["profile"], s["pix_fmt"]): s["episodes"] for s in storage["streams"]} == found
    assert storage["stored"] == stored_as
    for i, field in enumerate(("codec", "profile", "pix_fmt")):
        values = {k[i] for k in found}
        assert storage[field] == (values.pop() if len(values) == 1 else None), field
    if stored_as == "copied":
        assert storage["encoder"] is None and storage["crf"] is None and storage["gop"] is None
    else:
        assert storage["encoder"] == "libx264" and storage["crf"] == 23
    with h5py.File(root / "data.h5", "r") as f:
        attrs = dict(f[f"videos/{TOP}"].attrs)
    assert attrs["stored"] == stored_as
    assert attrs["codec"] == (storage["codec"] or "mixed")
    assert attrs["pix_fmt"] == (storage["pix_fmt"] or "mixed")
    assert attrs.get("profile") == (storage["profile"] or ("mixed" if len({k[1] for k in found}) > 1 else None))
    # The loader reads the field: a file swapped for another codec's is refused by name.
    candidates = sorted((V21 / "videos").rglob("*.mp4")) + sorted((V3 / "videos").rglob("*.mp4"))
    other = next(f for f in candidates if not {c for c, _, _ in formats_read(f.parent, [f.name])} & codecs)
    shutil.copy(other, root / paths[0])
    ds = import_loader(root).ChunkedDataset(str(root))
    with pytest.raises(ValueError, match="where meta.json says this camera's files hold"):
        ds._read(TOP, np.array([0]))
