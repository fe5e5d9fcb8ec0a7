"""The LeRobot v2.1 export (`format = "parquet"`, `lerobot_version = "v2.1"`, issue 52): the
reader openpi and GR00T train through opens it, and what it gives is the source's.

Oracles, independent of chunkc's writer:
- PyPI lerobot 0.3.3's `LeRobotDataset` (the last release that reads v2.1; openpi's pinned lerobot
  has the same reader), run in `.venv-lerobot21` (scripts/setup.sh) by `lerobot21_read.py`, with
  `delta_timestamps` for the action chunk as openpi's `create_torch_dataset` builds them, and its
  default video backend (torchcodec);
- pyarrow reading the sources' parquet files, PyAV demuxing and decoding the videos, torchcodec
  decoding the source's videos, numpy computing the statistics;
- chunkc's own windows (the generated loader of an hdf5 profile of the same build, raw values),
  which LeRobot's chunks must equal, edge padding at the episode end included.
"""

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from conftest import G1, REPO, build_with_video, load_dataset, run_chunkc, write_mixture_spec

av = pytest.importorskip("av")

DATA = REPO / "tests" / "data"
VIDEO_V21 = DATA / "lerobot_video_v21"  # 3 episodes, 10 Hz, 96x96 H.264 (B-frames) and MPEG-4
TOP = "observation.images.top"
LEROBOT21 = REPO / ".venv-lerobot21" / "bin" / "python"
READER = Path(__file__).with_name("lerobot21_read.py")


@pytest.fixture(scope="module")
def lerobot21():
    """The interpreter of `.venv-lerobot21`, or a skip that says how to get it."""
    if not LEROBOT21.exists():
        pytest.skip(f"{LEROBOT21} is missing: scripts/setup.sh creates it (lerobot 0.3.3, LeRobot "
                    "v2.1's reader) with the Python model tier")
    return LEROBOT21


def read_v21(python, tmp_path, jobs):
    """Runs lerobot 0.3.3 over `jobs` (see lerobot21_read.py), offline; returns each job's
    arrays, `meta` decoded."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    for k, job in enumerate(jobs):
        job.setdefault("out", str(tmp_path / f"read{k}.npz"))
    spec = tmp_path / "jobs.json"
    spec.write_text(json.dumps(jobs))
    env = dict(os.environ, HF_HUB_OFFLINE="1", HF_DATASETS_OFFLINE="1",
               HF_HOME=str(tmp_path / "hf-home"), TOKENIZERS_PARALLELISM="false")
    proc = subprocess.run([str(python), str(READER), str(spec)], capture_output=True, text=True,
                          env=env, timeout=900)
    assert proc.returncode == 0, f"lerobot 0.3.3 failed:\n{proc.stderr[-6000:]}"
    out = []
    for job in jobs:
        with np.load(job["out"]) as z:
            got = {k: z[k] for k in z.files}
        got["meta"] = json.loads(str(got["meta"]))
        out.append(got)
    return out


def spec_text(source, profiles, split="val_fraction = 0.0", cam=True, out="out"):
    channels = ['action = "action"', '"observation.state" = "observation.state"']
    if cam:
        channels.append(f'"{TOP}" = "{TOP}"')
    return "\n".join(["version = 1", "[source]", 'format = "lerobot"', f'path = "{source}"',
                      "[source.channels]", *channels, "[split]", split, "[output]",
                      f'dir = "{out}"', profiles]) + "\n"


def source_episodes(root):
    """Per episode id of a LeRobot v2.1 source: its columns, read with pyarrow."""
    out = {}
    for f in sorted((root / "data").glob("chunk-*/episode_*.parquet")):
        t = pq.read_table(f)
        e = int(t.column("episode_index")[0].as_py())
        out[e] = {k: np.asarray(t.column(k).to_pylist(), dtype=np.float32)
                  for k in ("action", "observation.state")}
    return out


def v21_places(meta):
    """meta.json's v2.1 placement: (dataset, episode_index) -> source id."""
    lr = meta["lerobot"]
    return {(d, i): e for d, i, e in zip(lr["dataset"], lr["episode_index"], meta["episodes"])}


def windows(root):
    """chunkc's own windows (its loader), by (source episode id, t)."""
    ds = load_dataset(root)
    out = {}
    for i in range(len(ds)):
        s = ds[i]
        out[(int(s["episode_index"]), int(s["frame_index"]))] = s
    return out


def chunk_of(rows, t, horizon):
    """LeRobot's action chunk at step t: rows t..t+H-1, the last row repeated past the end."""
    idx = np.minimum(np.arange(t, t + horizon), len(rows) - 1)
    return rows[idx], np.arange(t, t + horizon) >= len(rows)


def sample_indices(lengths, horizon, every=7):
    """The first and the last `horizon` + 2 samples of every episode, and every `every`-th."""
    out, start = set(), 0
    for n in lengths:
        out.update(range(start, start + min(n, 3)))
        out.update(range(max(start, start + n - horizon - 2), start + n))
        out.update(range(start, start + n, every))
        start += n
    return sorted(out)


def frame_times(path):
    """Presentation time (seconds) of every frame of an mp4, in order, and its codec."""
    with av.open(str(path)) as c:
        s = c.streams.video[0]
        times = [float(f.pts * s.time_base) for f in c.decode(s)]
        return times, s.codec_context.name


def decode(path):
    with av.open(str(path)) as c:
        return np.stack([f.to_ndarray(format="rgb24") for f in c.decode(video=0)])


def psnr(a, b):
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return np.inf if mse == 0 else 10 * np.log10(255.0**2 / mse)


def assert_lerobot_layout(root, fps):
    """What LeRobot's v2.1 reader (and GR00T's) demand of the files, checked on the files."""
    info = json.loads((root / "meta" / "info.json").read_text())
    assert info["codebase_version"] == "v2.1" and info["chunks_size"] == 1000
    assert all("names" in f and "shape" in f for f in info["features"].values())
    episodes = [json.loads(line) for line in (root / "meta" / "episodes.jsonl").read_text().splitlines()]
    stats = [json.loads(line) for line in (root / "meta" / "episodes_stats.jsonl").read_text().splitlines()]
    assert [e["episode_index"] for e in episodes] == list(range(len(episodes))) == [s["episode_index"] for s in stats]
    assert info["total_episodes"] == len(episodes)
    assert info["total_frames"] == sum(e["length"] for e in episodes)
    total = 0
    for e in episodes:
        i = e["episode_index"]
        t = pq.read_table(root / info["data_path"].format(episode_chunk=i // 1000, episode_index=i))
        assert t.num_rows == e["length"]
        assert t.column("episode_index").to_pylist() == [i] * e["length"]
        assert t.column("frame_index").to_pylist() == list(range(e["length"]))
        assert t.column("index").to_pylist() == list(range(total, total + e["length"]))
        total += e["length"]
        stamps = np.asarray(t.column("timestamp").to_pylist())
        np.testing.assert_allclose(stamps, np.arange(e["length"]) / fps, atol=1e-4)
        for key, f in info["features"].items():
            if f["dtype"] != "video":
                continue
            video = root / info["video_path"].format(episode_chunk=i // 1000, video_key=key, episode_index=i)
            times, codec = frame_times(video)
            assert len(times) == e["length"], f"{video}: {len(times)} frames for {e['length']} rows"
            np.testing.assert_allclose(np.asarray(times), stamps, atol=1e-4)
            if i == 0:
                with av.open(str(video)) as c:
                    s = c.streams.video[0]
                    # What LeRobot's get_video_info reads back from the file.
                    assert f["info"]["video.codec"] == s.codec.canonical_name
                    assert f["info"]["video.pix_fmt"] == s.pix_fmt
                    assert (f["info"]["video.height"], f["info"]["video.width"]) == (s.height, s.width)
                    assert f["names"] == ["height", "width", "channels"]
    return info, episodes


def test_openpi_opens_the_lowdim_export_and_its_chunks_are_the_sources(tmp_path, lerobot21):
    """A pi0 profile over the real G1 humanoid subset (26-D, 30 Hz): openpi's call (repo id
    under HF_LEROBOT_HOME, action chunk of 50 by delta_timestamps) opens the training dataset,
    lerobot 0.3.3 the validation one beside it; every chunk is the source's, edge-padded as
    LeRobot pads, and chunkc's own window; the statistics describe the episodes each holds."""
    horizon = 50
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(G1, f"""
[profiles.pi0]
preset = "pi0"
format = "parquet"
lerobot_version = "v2.1"

[profiles.win]
preset = "pi0"
format = "hdf5"
[profiles.win.normalize]
action = "none"
"observation.state" = "none"
""", split="val_fraction = 0.25\nseed = 0", cam=False))
    run_chunkc("build", "-q", spec)
    out = tmp_path / "out"
    root = out / "pi0"
    meta = json.loads((root / "meta.json").read_text())
    assert meta["data_format"] == "lerobot_v2.1"
    places = v21_places(meta)
    train_ids = [places[("train", i)] for i in range(len(meta["split"]["train"]))]
    val_ids = [places[("val", i)] for i in range(len(meta["split"]["val"]))]
    assert train_ids == [e for e in meta["episodes"] if e in meta["split"]["train"]]
    assert sorted(val_ids) == sorted(meta["split"]["val"]) and val_ids
    for r in (root, root / "val"):
        assert_lerobot_layout(r, 30)
    src = source_episodes(G1)
    lengths = {d: [len(src[e]["action"]) for e in ids] for d, ids in (("train", train_ids), ("val", val_ids))}
    jobs = [{"home": str(out), "repo_id": "pi0", "horizon": horizon,
             "indices": sample_indices(lengths["train"], horizon)},
            {"root": str(root / "val"), "repo_id": "pi0-val", "horizon": horizon}]
    train, val = read_v21(lerobot21, tmp_path / "lr", jobs)
    ours = windows(out / "win")
    for got, ids, name in ((train, train_ids, "train"), (val, val_ids, "val")):
        assert got["meta"]["num_episodes"] == len(ids)
        assert [e["length"] for e in got["meta"]["episodes"]] == lengths[name]
        assert got["meta"]["len"] == sum(lengths[name])
        assert len(got["sample"]) > (200 if name == "train" else 100)
        for k in range(len(got["sample"])):
            e, t = ids[int(got["episode_index"][k])], int(got["frame_index"][k])
            want, pad = chunk_of(src[e]["action"], t, horizon)
            np.testing.assert_array_equal(got["action"][k], want)
            np.testing.assert_array_equal(got["action_is_pad"][k], pad)
            np.testing.assert_array_equal(got["observation.state"][k], src[e]["observation.state"][t])
            assert got["task"][k] == "Pick up the yellow bottle on the table."
            if name == "train":
                w = ours[(e, t)]
                np.testing.assert_array_equal(got["action"][k], w["action"])
                np.testing.assert_array_equal(got["action_is_pad"][k], w["action_is_pad"])
        # LeRobot's normalization statistics: aggregated from episodes_stats.jsonl, and chunkc's
        # meta/stats.json, both the numbers of the rows this dataset holds.
        rows = np.concatenate([src[e]["action"] for e in ids]).astype(np.float64)
        stats = got["meta"]["stats"]["action"]
        np.testing.assert_allclose(stats["mean"], rows.mean(0), rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(stats["std"], rows.std(0), rtol=1e-7, atol=1e-9)
        np.testing.assert_array_equal(stats["min"], rows.min(0))
        np.testing.assert_array_equal(stats["max"], rows.max(0))
        assert stats["count"] == [len(rows)]
        written = json.loads(((root if name == "train" else root / "val") / "meta" / "stats.json").read_text())
        np.testing.assert_allclose(written["action"]["mean"], rows.mean(0), rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(written["action"]["std"], rows.std(0), rtol=1e-7, atol=1e-9)
    # openpi's TrainConfig finds norm_stats.json at <assets_dir>/<asset_id>/norm_stats.json:
    # AssetsConfig(assets_dir=<output.dir>, asset_id=<profile>), the repo id by default.
    norm = json.loads((out / "pi0" / "norm_stats.json").read_text())["norm_stats"]
    assert set(norm) == {"actions", "state"}
    assert set(norm["actions"]) == {"mean", "std", "q01", "q99"} and len(norm["actions"]["mean"]) == 26


def build_cameras(tmp_path):
    """The Push-T video set (H.264 with B-frames, one episode MPEG-4) as v2.1 four ways, and
    chunkc's raw frames beside them; one of three episodes is a validation episode."""
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(VIDEO_V21, """
[profiles.copied]
preset = "pi0"
chunk = 5
format = "parquet"
lerobot_version = "v2.1"
image_encoding = "video"

[profiles.encoded]
extends = "copied"
video_copy = false

[profiles.small]
extends = "copied"
[profiles.small.cameras."observation.images.top"]
size = [32, 32]

[profiles.png]
preset = "pi0"
chunk = 5
format = "parquet"
lerobot_version = "v2.1"

[profiles.raw]
preset = "pi0"
chunk = 5
""", split="val_fraction = 0.34\nseed = 0"))
    build_with_video(spec)
    return tmp_path / "out"


def test_lerobot_opens_the_camera_export_and_its_frames_are_the_sources(tmp_path, lerobot21):
    """Every v2.1 camera export opens with lerobot 0.3.3 (torchcodec): one frame per row at
    frame_index / fps; copied episodes decode to exactly the source video's frames, PNG ones
    are chunkc's decoded frames exactly, encoded ones are within 30 dB; a 32x32 camera, which
    SVT-AV1 refuses, is H.264."""
    out = build_cameras(tmp_path)
    meta = json.loads((out / "copied" / "meta.json").read_text())
    places = v21_places(meta)
    import h5py

    with h5py.File(out / "raw" / "data.h5", "r") as f:
        raw = f[f"data/{TOP}"][:]
    ends = meta["episode_ends"]
    starts = [0] + ends[:-1]
    position = {e: k for k, e in enumerate(meta["episodes"])}
    source_files = {e: VIDEO_V21 / "videos" / "chunk-000" / TOP / f"episode_{e:06d}.mp4" for e in meta["episodes"]}
    jobs, expect = [], []
    for name in ("copied", "encoded", "small", "png"):
        for dataset, sub in (("train", ""), ("val", "val")):
            root = out / name / sub
            info, _ = assert_lerobot_layout(root, 10)
            codec = info["features"][TOP].get("info", {}).get("video.codec")
            assert codec == {"copied": "h264", "encoded": "av1", "small": "h264", "png": None}[name]
            ids = [places[(dataset, i)] for i in range(info["total_episodes"])]
            jobs.append({"root": str(root), "repo_id": f"{name}-{dataset}", "horizon": 5,
                         "decode": [str(source_files[e]) for e in ids]})
            expect.append((name, ids))
    results = read_v21(lerobot21, tmp_path / "lr", jobs)
    src = source_episodes(VIDEO_V21)
    source_frames = {e: decode(f) for e, f in source_files.items()}
    for (name, ids), got in zip(expect, results):
        assert got["meta"]["backend"] == "torchcodec"
        assert len(got["sample"]) == got["meta"]["len"] == sum(len(src[e]["action"]) for e in ids) > 0
        assert got["meta"]["video_keys"] == ([] if name == "png" else [TOP])
        for k in range(len(got["sample"])):
            i, t = int(got["episode_index"][k]), int(got["frame_index"][k])
            e = ids[i]
            want, pad = chunk_of(src[e]["action"], t, 5)
            np.testing.assert_array_equal(got["action"][k], want)
            np.testing.assert_array_equal(got["action_is_pad"][k], pad)
            frame = got[TOP][k]
            ours = raw[starts[position[e]] + t]
            if name == "copied":
                np.testing.assert_array_equal(frame, got[f"decoded_{i}"][t])
            elif name == "png":
                # Lossless: chunkc's decode of the source, which is PyAV's.
                np.testing.assert_array_equal(frame, ours)
                np.testing.assert_array_equal(frame, source_frames[e][t])
            elif name == "encoded":
                assert psnr(frame, ours) > 30
            else:
                assert frame.shape == (32, 32, 3)


def test_copied_episodes_hold_the_source_packets(tmp_path):
    """Where an episode's frames are the source video's own, its v2.1 file holds the source's
    packets, byte for byte (PyAV's demuxer)."""
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(VIDEO_V21, """
[profiles.copied]
preset = "pi0"
chunk = 5
format = "parquet"
lerobot_version = "v2.1"
image_encoding = "video"
"""))
    build_with_video(spec)
    for e in range(3):
        name = f"episode_{e:06d}.mp4"
        mine = tmp_path / "out" / "copied" / "videos" / "chunk-000" / TOP / name
        theirs = VIDEO_V21 / "videos" / "chunk-000" / TOP / name
        with av.open(str(mine)) as a, av.open(str(theirs)) as b:
            pa = [bytes(p) for p in a.demux(a.streams.video[0]) if p.size]
            pb = [bytes(p) for p in b.demux(b.streams.video[0]) if p.size]
        assert pa == pb


def test_a_mixture_opens_as_one_v21_dataset(tmp_path, lerobot21):
    """A training mixture (the G1 humanoid at 30 Hz decimated to 10, Push-T at 10 Hz, padded to
    32 dimensions) exports one v2.1 dataset with `source_index`; lerobot 0.3.3's chunks are its
    sources' rows, as the v3.0 export of the same build stores them."""
    spec = write_mixture_spec(tmp_path, profiles="""
[profiles.lr]
preset = "pi0"
fps = 10
chunk = 8
format = "parquet"
lerobot_version = "v2.1"

[profiles.lr3]
extends = "lr"
lerobot_version = "v3.0"
""")
    run_chunkc("build", "-q", spec)
    root = tmp_path / "out" / "lr"
    info, episodes = assert_lerobot_layout(root, 10)
    lengths = [e["length"] for e in episodes]
    (got,) = read_v21(lerobot21, tmp_path / "lr-read", [
        {"root": str(root), "repo_id": "mix", "horizon": 8, "indices": sample_indices(lengths, 8, every=11)}])
    meta = json.loads((root / "meta.json").read_text())
    places = v21_places(meta)
    v3 = pq.read_table(tmp_path / "out" / "lr3" / "data" / "chunk-000" / "file-000.parquet")
    v3_action = np.asarray(v3.column("action").to_pylist(), dtype=np.float32)
    v3_episode = np.asarray(v3.column("episode_index").to_pylist())
    g1 = source_episodes(G1)
    sources = meta["sources"]
    for k in range(len(got["sample"])):
        e = places[("train", int(got["episode_index"][k]))]
        rows = v3_action[v3_episode == e]
        t = int(got["frame_index"][k])
        want, pad = chunk_of(rows, t, 8)
        np.testing.assert_array_equal(got["action"][k], want)
        np.testing.assert_array_equal(got["action_is_pad"][k], pad)
        own = int(got["source_index"][k]) == sources["own"]["index"]
        if own:
            # The G1 episode's own rows, every third (30 Hz to 10 Hz), zero-padded to 32.
            g = g1[e - sources["own"]["id_offset"]]["action"][::3]
            np.testing.assert_array_equal(got["action"][k][:, :26], chunk_of(g, t, 8)[0])
            assert not got["action"][k][:, 26:].any()


def roundtrip_spec(source, out, copy_v3=True):
    return spec_text(source, f"""
[profiles.v21]
preset = "pi0"
chunk = 5
format = "parquet"
lerobot_version = "v2.1"
image_encoding = "video"

[profiles.v3]
preset = "pi0"
chunk = 5
format = "parquet"
image_encoding = "video"
{"video_copy = true" if copy_v3 else ""}

[profiles.raw]
preset = "pi0"
chunk = 5
[profiles.raw.normalize]
action = "none"
"observation.state" = "none"
""", out=out)


def test_v21_to_v30_to_v21_keeps_rows_and_frames(tmp_path):
    """chunkc as the v2.1 <-> v3.0 converter: the source (v2.1) -> a v2.1 export -> v3.0
    (`video_copy = true`) -> v2.1 again gives the same rows and the same frames (the videos'
    packets are copied all the way); builds from the source, the v2.1 export and the v3.0
    export give the same windows, statistics and frames."""
    steps = [("a", VIDEO_V21), ("b", tmp_path / "a" / "v3"), ("c", tmp_path / "b" / "v21"),
             ("d", tmp_path / "a" / "v21")]
    for name, source in steps:
        spec = tmp_path / f"{name}.toml"
        spec.write_text(roundtrip_spec(source, name))
        build_with_video(spec)

    def rows(root):
        files = sorted((root / "data").glob("chunk-*/episode_*.parquet"))
        return [pq.read_table(f).to_pydict() for f in files]

    def frames(root):
        return [decode(f) for f in sorted((root / "videos").glob(f"chunk-*/{TOP}/episode_*.mp4"))]

    first, last = tmp_path / "a" / "v21", tmp_path / "c" / "v21"
    assert len(rows(first)) == len(frames(first)) == 3
    assert rows(first) == rows(last)
    for x, y in zip(frames(first), frames(last), strict=True):
        np.testing.assert_array_equal(x, y)
    assert (first / "meta" / "episodes_stats.jsonl").read_text() == (last / "meta" / "episodes_stats.jsonl").read_text()
    # The v3.0 export's per-episode files decode to the same frames.
    v3 = sorted((tmp_path / "a" / "v3" / "videos" / TOP).glob("chunk-*/file-*.mp4"))
    for x, f in zip(frames(first), v3, strict=True):
        np.testing.assert_array_equal(x, decode(f))
    # Windows, statistics and frames of builds from the source (a), the v3.0 export (b), the
    # v2.1 exports (c, d).
    import h5py

    ref = windows(tmp_path / "a" / "raw")
    assert len(ref) == 45
    ref_stats = json.loads((tmp_path / "a" / "raw" / "stats.json").read_text())
    with h5py.File(tmp_path / "a" / "raw" / "data.h5", "r") as f:
        ref_frames = f[f"data/{TOP}"][:]
    for name in "bcd":
        got = windows(tmp_path / name / "raw")
        assert sorted(got) == sorted(ref)
        for key, w in ref.items():
            for k in ("action", "action_is_pad", "observation.state", TOP):
                np.testing.assert_array_equal(got[key][k], w[k])
        assert json.loads((tmp_path / name / "raw" / "stats.json").read_text()) == ref_stats
        with h5py.File(tmp_path / name / "raw" / "data.h5", "r") as f:
            np.testing.assert_array_equal(f[f"data/{TOP}"][:], ref_frames)


def test_lerobot_04_reads_the_per_episode_v30_export(tmp_path):
    """LeRobot 0.4.4 (the suite's, v3.0's reader) opens a v3.0 export whose videos are one file
    per episode (`video_copy = true`), and its frames are the copied ones."""
    from conftest import lerobot_dataset

    spec = tmp_path / "spec.toml"
    spec.write_text(roundtrip_spec(VIDEO_V21, "out"))
    build_with_video(spec)
    root = tmp_path / "out" / "v3"
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    ds = lerobot_dataset("chunkc/v3", root)
    files = sorted((root / "videos" / TOP).glob("chunk-*/file-*.mp4"))
    want = np.concatenate([decode(f) for f in files])
    assert len(ds) == len(want)
    for i in range(0, len(ds), 4):
        frame = np.round(ds[i][TOP].numpy().transpose(1, 2, 0) * 255).astype(np.uint8)
        np.testing.assert_array_equal(frame, want[i])


def test_lerobot_version_v20_is_a_spec_error(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(G1, '[profiles.p]\npreset = "pi0"\nformat = "parquet"\nlerobot_version = "v2.0"\n',
                              cam=False))
    proc = run_chunkc("build", "-q", spec, check=False)
    assert proc.returncode == 2, proc.stderr
    assert "unknown value `v2.0` for `profiles.p.lerobot_version`" in proc.stderr
    assert "spec.toml:" in proc.stderr
    assert not (tmp_path / "out").exists()


def test_a_camera_short_of_frames_is_refused_naming_its_file(tmp_path):
    """A source episode whose video holds two frames fewer than its rows: the build fails
    naming the episode, the camera and the file, and writes nothing."""
    source = tmp_path / "src"
    shutil.copytree(VIDEO_V21, source)
    path = source / "videos" / "chunk-000" / TOP / "episode_000001.mp4"
    frames = decode(path)
    with av.open(str(path), "w") as c:
        s = c.add_stream("mpeg4", rate=10)
        s.width, s.height, s.pix_fmt = 96, 96, "yuv420p"
        for i, f in enumerate(frames[:-2]):
            vf = av.VideoFrame.from_ndarray(f, format="rgb24")
            vf.pts = i
            for p in s.encode(vf):
                c.mux(p)
        for p in s.encode():
            c.mux(p)
    spec = tmp_path / "spec.toml"
    spec.write_text(roundtrip_spec(source, "out"))
    proc = run_chunkc("build", "-q", spec, check=False)
    assert proc.returncode != 0
    assert "episode 1, camera `observation.images.top`" in proc.stderr
    assert "episode_000001.mp4: 16 frames for 18 rows" in proc.stderr
    assert not (tmp_path / "out").exists()


def test_the_bytes_do_not_depend_on_threads_or_shards(tmp_path):
    """The v2.1 export (copied and encoded videos, PNG frames, the validation dataset, a `groot`
    profile's GR00T files) is the same bytes with one thread, two, and from two shards merged."""
    text = spec_text(VIDEO_V21, """
[profiles.copied]
preset = "pi0"
chunk = 5
format = "parquet"
lerobot_version = "v2.1"
image_encoding = "video"

[profiles.encoded]
extends = "copied"
video_copy = false

[profiles.png]
preset = "pi0"
chunk = 5
format = "parquet"
lerobot_version = "v2.1"

[profiles.groot]
preset = "groot"
chunk = 5
relative_actions = ["xy"]
[profiles.groot.modality]
action = { xy = [0, 2] }
"observation.state" = { xy = [0, 2] }
""", split="val_fraction = 0.34\nseed = 0")
    files = {}
    for how in ("j1", "j2", "shards"):
        d = tmp_path / how
        d.mkdir()
        spec = d / "spec.toml"
        spec.write_text(text)
        if how == "shards":
            for i in range(2):
                run_chunkc("build", "-q", "--shard", f"{i}/2", "--partials", d / "parts", spec)
            run_chunkc("merge", "-q", "--partials", d / "parts", spec)
        else:
            build_with_video(spec, "-j", how[1])
        root = d / "out"
        files[how] = {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
                      if p.is_file() and not p.name.startswith(".") and p.name != "chunkc.lock"}
    assert any("val/videos" in f for f in files["j1"])
    assert "groot/val/meta/relative_stats.json" in files["j1"]
    assert files["j1"] == files["j2"] == files["shards"]


def test_many_episodes_written_side_by_side_are_the_sources_in_order(tmp_path):
    """More episodes than the writer takes at once (64), with PNG frames: every data file holds
    its source episode's rows under LeRobot's running `index` (carried from group to group, per
    dataset), its `episodes_stats.jsonl` entry is numpy's over the file, and the bytes are the
    same with one thread and two."""
    zarr = pytest.importorskip("zarr")
    src = tmp_path / "syn"
    run_chunkc("synth", src, "--format", "diffusion-policy-zarr", "--episodes", 150, "--steps", 12,
               "--cameras", 1, "--resolution", "16x16")
    text = (src / "spec.toml").read_text().split("[profiles.act]")[0]
    text = text.replace('path = "replay.zarr"', f'path = "{src / "replay.zarr"}"')
    text += '[profiles.v21]\npreset = "pi0"\nchunk = 4\nformat = "parquet"\nlerobot_version = "v2.1"\n'
    files = {}
    for jobs in ("1", "2"):
        d = tmp_path / f"j{jobs}"
        d.mkdir()
        (d / "spec.toml").write_text(text)
        run_chunkc("build", "-q", "-j", jobs, d / "spec.toml")
        root = d / "out"
        files[jobs] = {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
                       if p.is_file() and p.name != "chunkc.lock"}
    assert files["1"] == files["2"]
    out = tmp_path / "j1" / "out" / "v21"
    meta = json.loads((out / "meta.json").read_text())
    places = v21_places(meta)
    buffer = zarr.open(str(src / "replay.zarr"), mode="r")
    ends = np.asarray(buffer["meta/episode_ends"])
    action = np.asarray(buffer["data/action"])
    for name, folder in meta["lerobot"]["datasets"].items():
        root = out / folder
        stats = [json.loads(line) for line in (root / "meta" / "episodes_stats.jsonl").read_text().splitlines()]
        paths = sorted((root / "data").glob("chunk-*/episode_*.parquet"))
        assert len(paths) == len(stats) == sum(d == name for d, _ in places) > 64 * (name == "train")
        index = []
        for i, path in enumerate(paths):
            t = pq.read_table(path)
            assert t.column("episode_index").to_pylist() == [i] * t.num_rows
            index += t.column("index").to_pylist()
            e = places[(name, i)]
            rows = action[(ends[e - 1] if e else 0):ends[e]]
            got = np.asarray(t.column("action").to_pylist(), dtype=np.float32)
            np.testing.assert_array_equal(got, rows)
            assert stats[i]["episode_index"] == i
            np.testing.assert_allclose(stats[i]["stats"]["action"]["mean"], got.mean(axis=0, dtype=np.float64),
                                       rtol=1e-6, atol=1e-9)
        assert index == list(range(len(index)))
