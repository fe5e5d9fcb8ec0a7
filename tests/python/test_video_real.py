"""Video on real camera footage (issue 48): tests/data/lerobot_video_real_g1 holds two episodes of
a public Unitree G1 LeRobot set (640x480 at 30 fps; episode 0 the source's own AV1 packets,
episode 1 re-encoded as MPEG-4 part 2 while info.json says `av1`; see
tests/fixtures/make_real_video.py). The other video fixtures are Push-T's 96x96 renders.

Oracles: LeRobot 0.4.4's `decode_video_frames` with either backend (what `LeRobotDataset`
calls), PyAV's decode and demux of the stored files, and PyAV's read of each file's codec.
"""
import json

import h5py
import numpy as np
import pytest

from conftest import REPO, VIDEO_BACKENDS, build_with_video as build, model_tier
from test_frame_storage import assert_loader_returns, pyav_frames
from test_video_read import compare, to_u8

av = pytest.importorskip("av")

REAL = REPO / "tests" / "data" / "lerobot_video_real_g1"
CAM = "observation.images.cam_high"
FPS = 30


def spec(tmp_path, storage):
    path = tmp_path / "spec.toml"
    path.write_text("\n".join([
        "version = 1", "[source]", 'format = "lerobot"', f'path = "{REAL}"', "[source.channels]",
        'action = "action"', '"observation.state" = "observation.state"', f'"{CAM}" = "{CAM}"',
        "[split]", "val_fraction = 0.0", "[output]", 'dir = "out"',
        # Diffusion Policy's window: two observations, which share a GOP or straddle two.
        "[profiles.dp]", 'preset = "diffusion_policy"', f"fps = {FPS}", f'image_compression = "{storage}"',
    ]) + "\n")
    return path


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("real")
    proc = build(spec(d, "video"), "-j", "2")
    # info.json says av1; episode 1 holds MPEG-4: decoded as what it holds, with a warning.
    assert "mpeg4" in proc.stderr, proc.stderr
    return d / "out" / "dp"


def episode_files(root):
    with h5py.File(root / "data.h5", "r") as f:
        paths = [p.decode() for p in f[f"videos/{CAM}/path"][:]]
        copied = f[f"videos/{CAM}/copied"][:].tolist()
    return paths, copied


def source_file(e):
    return REAL / f"videos/chunk-000/{CAM}/episode_{e:06d}.mp4"


def test_real_footage_is_copied_and_meta_json_names_what_the_files_hold(built):
    paths, copied = episode_files(built)
    assert copied == [1, 1]
    held = []
    for e, p in enumerate(paths):
        with av.open(str(built / p)) as c, av.open(str(source_file(e))) as s:
            held.append(c.streams.video[0].codec_context.codec.canonical_name)
            # A copy: the source's packets, byte for byte, keyframe flags included.
            ours = [(bytes(k), k.is_keyframe) for k in c.demux(video=0) if k.size]
            theirs = [(bytes(k), k.is_keyframe) for k in s.demux(video=0) if k.size]
            assert ours == theirs, p
    assert held == ["av1", "mpeg4"]
    meta = json.loads((built / "meta.json").read_text())
    streams = meta["channels"][CAM]["storage"]["streams"]
    assert sorted(s["codec"] for s in streams) == ["av1", "mpeg4"]


def test_the_loader_returns_pyav_decodes_with_the_same_batches_for_any_workers(built):
    assert_loader_returns(built, CAM, pyav_frames(built, CAM))


@pytest.mark.parametrize("backend", VIDEO_BACKENDS)
def test_real_frames_equal_lerobots_decode(tmp_path, backend):
    """chunkc's decode of the source (read back from an uncompressed profile) against LeRobot's
    own decode of each episode's file at the rows' timestamps."""
    decode_video_frames = model_tier("lerobot.datasets.video_utils").decode_video_frames
    build(spec(tmp_path, "none"))
    with h5py.File(tmp_path / "out" / "dp" / "data.h5", "r") as f:
        frames = f[f"data/{CAM}"][:]
        ends = f["meta/episode_ends"][:]
    starts = np.concatenate([[0], ends[:-1]])
    for e, (lo, hi) in enumerate(zip(starts, ends)):
        ts = [k / FPS for k in range(hi - lo)]
        ref = to_u8(decode_video_frames(source_file(e), ts, 1e-4, backend).numpy())
        n = compare(frames[lo:hi], ref, f"episode {e} ({backend})")
        print(f"real episode {e}, {backend}: {n} values differ")
