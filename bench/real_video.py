"""Real camera sources for bench/frame_storage.py's real-video case (issue 48).

The footage is a public LeRobot v2.1 set recorded on a Unitree G1 with Inspire hands
(github.com/YifanTian07/G1-policy-train, MIT License): one 640x480 camera at 30 fps, encoded as
LeRobot encodes (AV1, libsvtav1, yuv420p, a keyframe every 2 frames), episodes of 340-480 frames.
Give its checkout (`git clone https://github.com/YifanTian07/G1-policy-train`, about 300 MB; or
any LeRobot v2.1 set with one mp4 per episode and camera) as G1_DIR; episodes whose video is
missing from the checkout are skipped.

`sources(g1_dir, work, episodes)` writes three LeRobot v3.0 datasets of the same episodes:
- `av1`: the footage's own AV1 packets;
- `h264`: re-encoded with libx264, crf 30, a keyframe every 2 frames (LeRobot's encoding before
  AV1);
- `mpeg4`: re-encoded with FFmpeg's MPEG-4 part 2 encoder, a keyframe every 12 frames (what a real
  MPEG-4 LeRobot set of 640x480 footage holds).
Each is a v2.1 subset first (the first `episodes` episodes whose video the checkout holds,
renumbered from 0), then exported to v3.0 by `chunkc build` with the source's packets copied
(one mp4 per episode), which LeRobotDataset 0.4.4 and chunkc's builds both read.
"""
import json
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np

# name: (PyAV encoder, its options, keyframe spacing); None keeps the footage's packets.
ENCODINGS = {
    "av1": None,
    "h264": ("libx264", {"crf": "30", "preset": "medium"}, 2),
    "mpeg4": ("mpeg4", {"qscale": "4"}, 12),
}


def _episodes_with_video(root: Path, count: int):
    info = json.loads((root / "meta" / "info.json").read_text())
    cams = [k for k, v in info["features"].items() if v["dtype"] == "video"]
    chosen = []
    for line in (root / "meta" / "episodes.jsonl").read_text().splitlines():
        ep = json.loads(line)
        i = ep["episode_index"]
        chunk = i // info["chunks_size"]
        videos = [root / info["video_path"].format(episode_chunk=chunk, video_key=k, episode_index=i) for k in cams]
        if all(v.is_file() and v.stat().st_size > 1000 for v in videos):
            chosen.append(ep)
        if len(chosen) == count:
            break
    if len(chosen) < count:
        raise SystemExit(f"{root}: only {len(chosen)} episodes have their videos, {count} asked")
    return info, cams, chosen


def _transcode(src: Path, dst: Path, encoding):
    import av

    codec, options, gop = encoding
    with av.open(str(src)) as inp, av.open(str(dst), "w") as out:
        s = inp.streams.video[0]
        o = out.add_stream(codec, rate=s.average_rate, options=options)
        o.width, o.height, o.pix_fmt = s.width, s.height, "yuv420p"
        o.codec_context.gop_size = gop
        o.codec_context.max_b_frames = 0 if codec == "mpeg4" else o.codec_context.max_b_frames
        if codec == "mpeg4":
            o.codec_context.qscale = int(options["qscale"])
        o.time_base = s.time_base
        for frame in inp.decode(s):
            frame.pict_type = av.video.frame.PictureType.NONE
            for p in o.encode(frame):
                out.mux(p)
        for p in o.encode():
            out.mux(p)


def _subset_v21(root: Path, dst: Path, count: int, encoding):
    """The first `count` episodes with video, renumbered from 0, as a LeRobot v2.1 set."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    info, cams, chosen = _episodes_with_video(root, count)
    shutil.rmtree(dst, ignore_errors=True)
    (dst / "meta").mkdir(parents=True)
    stats = {json.loads(l)["episode_index"]: json.loads(l)
             for l in (root / "meta" / "episodes_stats.jsonl").read_text().splitlines()}
    index = 0
    episodes, ep_stats = [], []
    for new, ep in enumerate(chosen):
        old = ep["episode_index"]
        chunk = old // info["chunks_size"]
        t = pq.read_table(root / info["data_path"].format(episode_chunk=chunk, episode_index=old))
        n = t.num_rows
        t = t.set_column(t.schema.get_field_index("episode_index"), "episode_index",
                         pa.array(np.full(n, new, dtype=np.int64)))
        t = t.set_column(t.schema.get_field_index("index"), "index",
                         pa.array(np.arange(index, index + n, dtype=np.int64)))
        data = dst / info["data_path"].format(episode_chunk=0, episode_index=new)
        data.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(t, data)
        for k in cams:
            src = root / info["video_path"].format(episode_chunk=chunk, video_key=k, episode_index=old)
            out = dst / info["video_path"].format(episode_chunk=0, video_key=k, episode_index=new)
            out.parent.mkdir(parents=True, exist_ok=True)
            if encoding is None:
                shutil.copyfile(src, out)
            else:
                _transcode(src, out, encoding)
        episodes.append({**ep, "episode_index": new})
        s = stats[old]
        s["episode_index"] = new
        s["stats"]["episode_index"] = {k: [new] if isinstance(v, list) and len(v) == 1 else v
                                       for k, v in s["stats"].get("episode_index", {}).items()}
        ep_stats.append(s)
        index += n
    (dst / "meta" / "episodes.jsonl").write_text("".join(json.dumps(e) + "\n" for e in episodes))
    (dst / "meta" / "episodes_stats.jsonl").write_text("".join(json.dumps(e) + "\n" for e in ep_stats))
    shutil.copyfile(root / "meta" / "tasks.jsonl", dst / "meta" / "tasks.jsonl")
    info.update(total_episodes=count, total_frames=index, total_videos=count * len(cams), total_chunks=1,
                splits={"train": f"0:{count}"})
    if encoding is not None:
        for k in cams:
            info["features"][k]["info"]["video.codec"] = {"libx264": "h264"}.get(encoding[0], encoding[0])
    (dst / "meta" / "info.json").write_text(json.dumps(info, indent=4))
    return cams, index


def build_lerobot(bin_path: str, root: Path, cams, work: Path, name: str, profiles: str, *args):
    """`chunkc build` of a spec named `name` in `work` over the LeRobot set at `root` (action, state
    and `cams`, no validation split) with `profiles`, into `work/out_<name>`, from a clean slate:
    (output dir, wall seconds)."""
    out = work / f"out_{name}"
    channels = "\n".join(f'"{k}" = "{k}"' for k in ["action", "observation.state", *cams])
    spec = work / f"{name}.toml"
    spec.write_text(f"""version = 1
[source]
format = "lerobot"
path = "{root}"
[source.channels]
{channels}
[split]
val_fraction = 0.0
[output]
dir = "{out}"
{profiles}""")
    shutil.rmtree(out, ignore_errors=True)
    (work / "chunkc.lock").unlink(missing_ok=True)
    t0 = time.perf_counter()
    p = subprocess.run([bin_path, "build", "-q", *args, str(spec)], capture_output=True, text=True, cwd=work)
    if p.returncode:
        raise SystemExit(f"{name}: {p.stderr}")
    return out, time.perf_counter() - t0


def _export_v30(bin_path: str, v21: Path, work: Path, cams, name: str):
    """chunkc's v3.0 export of a v2.1 set, the packets copied (one mp4 per episode)."""
    out, _ = build_lerobot(bin_path, v21, cams, work, f"export_{name}", """[profiles.lerobot]
preset = "pi0"
chunk = 5
format = "parquet"
image_encoding = "video"
video_copy = true
""")
    return out / "lerobot"


def sources(bin_path: str, g1_dir: Path, work: Path, episodes: int):
    """{name: (v3.0 root, camera keys, frames)} for every encoding, made once per work dir."""
    made = {}
    for name, encoding in ENCODINGS.items():
        v21 = work / f"real_{name}_{episodes}ep_v21"
        done = work / f"real_{name}_{episodes}ep.json"
        if not done.exists():
            cams, frames = _subset_v21(g1_dir, v21, episodes, encoding)
            root = _export_v30(bin_path, v21, work, cams, f"{name}_{episodes}ep")
            done.write_text(json.dumps({"root": str(root), "cams": cams, "frames": frames}))
        d = json.loads(done.read_text())
        made[name] = (Path(d["root"]), d["cams"], d["frames"])
    return made


def stream_facts(root: Path, cam: str):
    """Codec, keyframe spacing and bytes of a v3.0 root's first episode file of `cam`, as PyAV reads it."""
    import av

    files = sorted((root / "videos" / cam).rglob("*.mp4"))
    with av.open(str(files[0])) as c:
        s = c.streams.video[0]
        keys = [i for i, p in enumerate(c.demux(s)) if p.pts is not None and p.is_keyframe]
        codec = s.codec_context.name
    return {"codec": codec, "keyframe_spacing": float(np.mean(np.diff(keys))) if len(keys) > 1 else None,
            "bytes": sum(f.stat().st_size for f in files)}
