"""The `groot` preset (issue 52): a LeRobot v2.1 dataset with NVIDIA GR00T N1.7's
`meta/modality.json`, `meta/stats.json` and `meta/relative_stats.json`.

Oracles, independent of chunkc's writer:
- `groot_oracle.GrootDataset`: what GR00T's loader and statistics script read and compute,
  written from their published semantics (GR00T is not on the package index): modality
  slicing, one video frame per row, the six statistics with numpy's linear quantiles, the
  relative action chunks;
- pyarrow and zarr-python reading the sources, PyAV decoding the videos;
- lerobot 0.3.3 (`.venv-lerobot21`, see test_lerobot_v21.py): a GR00T dataset is a LeRobot v2.1
  dataset, and LeRobot's reader opens it.
"""

import json

import numpy as np
import pytest
import zarr

from conftest import G1, PUSHT, build_with_video, run_chunkc, write_mixture_spec
from groot_oracle import STATS, GrootDataset, check_config
from test_lerobot_v21 import (TOP, VIDEO_V21, assert_lerobot_layout, chunk_of, decode, lerobot21,
                              read_v21, sample_indices, source_episodes, spec_text, v21_places)

TASK = "Pick up the yellow bottle on the table."
G1_PARTS = '{ arms = [0, 14], hands = [14, 26] }'


def part(start, end, key):
    return {"start": start, "end": end, "original_key": key}


def assert_stats_are_groots(g, relative=(), horizon=16):
    """The shipped statistics are the ones GR00T keeps (every float feature, six keys), exactly
    its definitions over the dataset's float32 values (means and stds exact, where GR00T's
    float32 arithmetic lands within 1e-4, or 1e-5 relative), and its relative action statistics."""
    assert g.keeps_shipped_stats()
    assert set(g.stats) == set(g.float_features())
    exact, theirs = g.computed_stats(np.float64), g.computed_stats(np.float32)
    for key in g.stats:
        assert set(g.stats[key]) == set(STATS)
        for s in STATS:
            got = np.asarray(g.stats[key][s])
            np.testing.assert_allclose(got, exact[key][s], rtol=1e-9, atol=1e-12, err_msg=f"{key}.{s}")
            np.testing.assert_allclose(got, theirs[key][s], rtol=1e-5, atol=1e-4, err_msg=f"{key}.{s}")
        np.testing.assert_array_equal(g.stats[key]["min"], theirs[key]["min"])
        np.testing.assert_array_equal(g.stats[key]["max"], theirs[key]["max"])
    if not relative:
        assert g.relative_stats is None
        return
    assert list(g.relative_stats) == sorted(relative)
    want = g.computed_relative_stats(relative, horizon, np.float64)
    for key in relative:
        width = g.modality["action"][key]["end"] - g.modality["action"][key]["start"]
        for s in STATS:
            got = np.asarray(g.relative_stats[key][s])
            assert got.shape == (horizon, width), (key, s, got.shape)
            np.testing.assert_allclose(got, want[key][s], rtol=1e-9, atol=1e-12, err_msg=f"{key}.{s}")


def test_groot_reads_the_export_and_its_statistics_are_its_own(tmp_path, lerobot21):
    """The real G1 humanoid subset (26-D, 30 Hz) as a `groot` profile with named parts and a
    relative action: both datasets (training in the profile folder, validation in `val/`) hold
    what GR00T's loader demands, its slices are the source's columns, N1.7's samples are
    chunkc's, the statistics are GR00T's definitions; lerobot 0.3.3 opens it with the source's
    chunks."""
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(G1, f"""
[profiles.groot]
preset = "groot"
relative_actions = ["arms"]

[profiles.groot.modality]
"observation.state" = {G1_PARTS}
action = {G1_PARTS}
""", split="val_fraction = 0.25\nseed = 0", cam=False))
    run_chunkc("build", "-q", spec)
    root = tmp_path / "out" / "groot"
    meta = json.loads((root / "meta.json").read_text())
    assert meta["chunk_size"] == 16 and meta["padding"] == "truncate"
    assert {m["mode"] for m in meta["normalization"].values()} == {"groot_quantile"}
    places = v21_places(meta)
    src = source_episodes(G1)
    for name, r in (("train", root), ("val", root / "val")):
        assert_lerobot_layout(r, 30)
        g = GrootDataset(r)
        assert g.modality == {
            "state": {"arms": part(0, 14, "observation.state"), "hands": part(14, 26, "observation.state")},
            "action": {"arms": part(0, 14, "action"), "hands": part(14, 26, "action")},
            "video": {},
            "annotation": {"human.task_description": {"original_key": "task_index"}},
        }
        ids = [places[(name, i)] for i in range(len(g.episodes))]
        assert sorted(ids) == sorted(meta["split"][name]) and ids
        for i, e in enumerate(ids):
            df = g.table(i)
            assert len(df) == g.episodes[i]["length"] == len(src[e]["action"])
            for group, column in (("state", "observation.state"), ("action", "action")):
                np.testing.assert_array_equal(g.part(df, group, "arms"), src[e][column][:, :14])
                np.testing.assert_array_equal(g.part(df, group, "hands"), src[e][column][:, 14:])
            assert set(g.language(df)) == {TASK}
        # GR00T N1.7 samples every start step whose 16-step chunk fits: chunkc's windows.
        assert meta["num_samples"][name] == len(g.samples(16)) > 0
        assert_stats_are_groots(g, relative=["arms"])
    g = GrootDataset(root)
    # The modality config GR00T's fine-tuning script takes (`--modality-config-path`).
    check_config(root / "groot_config.py", g, 16, relative=["arms"])
    assert not (root / "val" / "groot_config.py").exists()
    lengths = [e["length"] for e in g.episodes]
    (got,) = read_v21(lerobot21, tmp_path / "lr", [
        {"root": str(root), "repo_id": "groot", "horizon": 16, "indices": sample_indices(lengths, 16, every=13)}])
    assert got["meta"]["num_episodes"] == len(g.episodes)
    for k in range(len(got["sample"])):
        e, t = places[("train", int(got["episode_index"][k]))], int(got["frame_index"][k])
        want, pad = chunk_of(src[e]["action"], t, 16)
        np.testing.assert_array_equal(got["action"][k], want)
        np.testing.assert_array_equal(got["action_is_pad"][k], pad)


def test_groot_cameras_are_video_keys_with_a_frame_per_row(tmp_path):
    """A camera is GR00T's video key (named after its last component), one frame per row in
    every episode's mp4, each the source video's frame (copied); parts named alike in the state
    and the action make a relative action."""
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(VIDEO_V21, """
[profiles.g]
preset = "groot"
chunk = 5
image_encoding = "video"
relative_actions = ["xy"]

[profiles.g.modality]
action = { xy = [0, 2] }
"observation.state" = { xy = [0, 2] }
""", split="val_fraction = 0.34\nseed = 0"))
    build_with_video(spec)
    root = tmp_path / "out" / "g"
    places = v21_places(json.loads((root / "meta.json").read_text()))
    for name, r in (("train", root), ("val", root / "val")):
        assert_lerobot_layout(r, 10)
        g = GrootDataset(r)
        assert g.modality["video"] == {"top": {"original_key": TOP}}
        for i, ep in enumerate(g.episodes):
            frames = decode(g.video_path(i, "top"))
            assert len(frames) == len(g.table(i)) == ep["length"]
            e = places[(name, i)]
            source = decode(VIDEO_V21 / "videos" / "chunk-000" / TOP / f"episode_{e:06d}.mp4")
            np.testing.assert_array_equal(frames, source)
        assert_stats_are_groots(g, relative=["xy"], horizon=5)
    check_config(root / "groot_config.py", GrootDataset(root), 5, relative=["xy"])


def test_a_groot_mixture_is_a_dataset_per_source(tmp_path, lerobot21):
    """GR00T mixes datasets itself: over a mixture (the G1 at 30 Hz taken to 10, Push-T at 10),
    each source is a v2.1 dataset pair of its own in `sources/<name>/`, at its own widths (no
    padding, no `source_index`), with its own modality and GR00T's statistics of its rows,
    beside chunkc's per-source statistics files; the profile folder holds no dataset."""
    spec = write_mixture_spec(tmp_path, profiles="""
[profiles.g]
preset = "groot"
fps = 10
chunk = 8
""")
    run_chunkc("build", "-q", spec)
    root = tmp_path / "out" / "g"
    assert not (root / "meta").exists() and not (root / "data").exists()
    meta = json.loads((root / "meta.json").read_text())
    places = v21_places(meta)
    sources = meta["sources"]
    g1 = source_episodes(G1)
    z = zarr.open(str(PUSHT), mode="r")
    ends = z["meta/episode_ends"][:]
    starts = np.concatenate([[0], ends[:-1]])
    widths = {"own": (26, 26), "sim": (2, 5)}
    for src, (aw, sw) in widths.items():
        for name in (f"sources/{src}", f"sources/{src}/val"):
            r = root / name
            assert_lerobot_layout(r, 10)
            g = GrootDataset(r)
            assert g.modality["action"] == {"action": part(0, aw, "action")}
            assert g.modality["state"] == {"state": part(0, sw, "observation.state")}
            assert "source_index" not in g.info["features"]
            assert g.info["features"]["action"]["shape"] == [aw]
            for i in range(len(g.episodes)):
                df = g.table(i)
                own_id = places[(name, i)] - sources[src]["id_offset"]
                if src == "own":
                    want = g1[own_id]["action"][::3]
                else:
                    want = z["data/action"][starts[own_id]:ends[own_id]]
                np.testing.assert_array_equal(g.part(df, "action", "action"), want)
                assert len(df) == g.episodes[i]["length"]
            assert_stats_are_groots(g)
        # chunkc's per-source statistics stay beside GR00T's dataset, and its config.
        for f in ("stats.json", "lerobot_stats.json"):
            assert (root / "sources" / src / f).exists()
        check_config(root / "sources" / src / "groot_config.py", GrootDataset(root / "sources" / src), 8)
    sim = GrootDataset(root / "sources" / "sim")
    (got,) = read_v21(lerobot21, tmp_path / "lr", [
        {"root": str(root / "sources" / "sim"), "repo_id": "sim", "horizon": 8}])
    assert got["meta"]["len"] == sum(e["length"] for e in sim.episodes)
    assert "source_index" not in got


def test_groot_parts_past_the_channel_and_png_cameras_are_refused_and_nothing_is_written(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(G1, """
[profiles.g]
preset = "groot"
[profiles.g.modality]
action = { arms = [0, 14], hands = [14, 27] }
""", cam=False))
    proc = run_chunkc("build", "-q", spec, check=False)
    assert proc.returncode == 2, proc.stderr
    assert "part `hands` of `action` ends at 27, and `action` has 26 dimensions" in proc.stderr
    assert "spec.toml:" in proc.stderr
    assert not (tmp_path / "out").exists()
    # GR00T decodes cameras from mp4s: PNG frames are refused.
    spec.write_text(spec_text(VIDEO_V21, '[profiles.g]\npreset = "groot"\nchunk = 5\nimage_encoding = "png"\n'))
    proc = run_chunkc("build", "-q", spec, check=False)
    assert proc.returncode == 2, proc.stderr
    assert "GR00T decodes cameras from one mp4 per episode" in proc.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("preset", ["pi0", "pi05", "pi0_fast"])
def test_openpi_presets_write_v21_with_norm_stats_at_the_asset_id(tmp_path, preset):
    """openpi's presets take `lerobot_version = "v2.1"`; `norm_stats.json` is in the profile
    folder, `<assets_dir>/<asset_id>/norm_stats.json` with assets_dir = output.dir and asset_id
    = the profile (the repo id under HF_LEROBOT_HOME = output.dir)."""
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text(G1, f"""
[profiles.{preset}]
preset = "{preset}"
format = "parquet"
lerobot_version = "v2.1"
""", cam=False))
    run_chunkc("build", "-q", spec)
    root = tmp_path / "out" / preset
    assert json.loads((root / "meta" / "info.json").read_text())["codebase_version"] == "v2.1"
    norm = json.loads((root / "norm_stats.json").read_text())["norm_stats"]
    assert set(norm) == {"actions", "state"}


def test_groot_from_the_v30_export_is_groot_from_the_source(tmp_path):
    """chunkc reads its own exports back: the G1 (v2.1) -> v3.0 -> a `groot` dataset is the same
    bytes as the `groot` dataset built from the source directly (rows, modality, statistics)."""
    groot = f"""
[profiles.g]
preset = "groot"
relative_actions = ["arms"]
[profiles.g.modality]
"observation.state" = {G1_PARTS}
action = {G1_PARTS}
"""
    v3 = """
[profiles.v3]
preset = "pi0"
format = "parquet"
"""
    split = "val_fraction = 0.0"
    (tmp_path / "a.toml").write_text(spec_text(G1, groot + v3, split=split, cam=False, out="a"))
    run_chunkc("build", "-q", tmp_path / "a.toml")
    (tmp_path / "b.toml").write_text(spec_text(tmp_path / "a" / "v3", groot, split=split, cam=False, out="b"))
    run_chunkc("build", "-q", tmp_path / "b.toml")
    a, b = tmp_path / "a" / "g", tmp_path / "b" / "g"
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file() and p.parts[-2] in ("meta", "chunk-000"))
    assert any(f.name == "relative_stats.json" for f in files) and len(files) > 8
    for f in files:
        if f.name == "info.json":
            continue
        assert (a / f).read_bytes() == (b / f).read_bytes(), f
